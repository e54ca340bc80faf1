// raylod info FILE: what a file holds. Meshes (.ply, .stl, .obj, .drc, .gltf,
// .glb) are read in full (format, encoding, counts, bounds, normals, bytes);
// for glTF also the meshes with their triangle counts.
#include <cinttypes>
#include <cstdio>
#include <filesystem>

#include "cli/cli.h"
#include "core/system.h"
#include "streaming/cut_file.h"
#include "streaming/gltf_io.h"
#include "streaming/mesh_reader.h"
#include "streaming/octree_store.h"

namespace raylod::cli {
namespace {

int print_mesh_info(const std::filesystem::path& path) {
  auto summary = summarize_mesh(path);
  if (!summary) return fail("info", summary.status());
  const MeshSummary& s = summary.value();
  const MeshHeader& h = s.header;
  std::printf("file:       %s\n", path.string().c_str());
  std::printf("format:     %s (%s)\n", to_string(h.format), h.encoding.c_str());
  std::printf("triangles:  %" PRIu64 "\n", s.triangle_count);
  if (h.format == MeshFormat::Stl)
    std::printf("vertices:   %" PRIu64 " (3 per triangle; STL has no shared vertices)\n", h.vertex_count);
  else
    std::printf("vertices:   %" PRIu64 "\n", h.vertex_count);
  if (h.face_count != s.triangle_count)
    std::printf("faces:      %" PRIu64 " (polygons, triangulated as fans)\n", h.face_count);
  // 12 digits: a mesh far from zero (e.g. at 1e7) shows its detail.
  std::printf("bounds:     min (%.12g, %.12g, %.12g)\n", s.bounds.lo.x, s.bounds.lo.y, s.bounds.lo.z);
  std::printf("            max (%.12g, %.12g, %.12g)\n", s.bounds.hi.x, s.bounds.hi.y, s.bounds.hi.z);
  if (h.origin != Vec3d(0))
    std::printf("origin:     (%.12g, %.12g, %.12g): positions are read relative to it (far from zero)\n", h.origin.x,
                h.origin.y, h.origin.z);
  const Vec3d e = s.bounds.extent();
  std::printf("size:       %.9g x %.9g x %.9g (diagonal %.9g)\n", e.x, e.y, e.z, s.bounds.diagonal());
  std::printf("normals:    %s\n", h.has_normals ? "yes (per vertex)" : "no");
  std::printf("bytes:      %" PRIu64 " (%s)\n", h.file_bytes, format_bytes(h.file_bytes).c_str());
  return 0;
}

// glTF: the meshes with their triangle counts, node instances and materials,
// then the whole default scene as one mesh (print_mesh_info).
int print_gltf_info(const std::filesystem::path& path) {
  auto described = describe_gltf(path);
  if (!described) return fail("info", described.status());
  const GltfSummary& g = *described;
  std::printf("glTF:       %s, %zu mesh%s, %zu node instance%s, %zu material%s\n", g.binary ? "binary (.glb)" : "JSON",
              g.meshes.size(), g.meshes.size() == 1 ? "" : "es", g.instances.size(), g.instances.size() == 1 ? "" : "s",
              g.materials.size(), g.materials.size() == 1 ? "" : "s");
  for (size_t i = 0; i < g.meshes.size(); ++i) {
    const GltfMeshInfo& m = g.meshes[i];
    std::printf("  meshes[%zu] %-20s %12" PRIu64 " triangles, %" PRIu64 " vertices, %u triangle primitive%s%s, "
                "%s, %u instance%s",
                i, ("'" + m.name + "'").c_str(), m.triangles, m.vertices, m.triangle_primitives,
                m.triangle_primitives == 1 ? "" : "s",
                m.skipped_primitives ? (" (+" + std::to_string(m.skipped_primitives) + " points/lines skipped)").c_str() : "",
                m.has_normals ? "normals" : "no normals", m.instances, m.instances == 1 ? "" : "s");
    if (m.material >= 0) {
      const GltfMaterialInfo& mat = g.materials[size_t(m.material)];
      std::printf(", material '%s'", mat.name.c_str());
      if (mat.mirror) std::printf(" (mirror)");
      else if (mat.has_base_color)
        std::printf(" (base colour %.3g %.3g %.3g)", double(mat.base_color.x), double(mat.base_color.y), double(mat.base_color.z));
    }
    std::printf("\n");
  }
  std::printf("(in a scene, each instance is an object; below, the default scene as one mesh in world space)\n");
  return print_mesh_info(path);
}

int run_info(int argc, char** argv) {
  Args args("info", "FILE",
            "Describes a file. For a mesh (.ply, .stl, .obj, .drc, .gltf, .glb): format and encoding, triangle\n"
            "and vertex counts, bounds, whether it has per-vertex normals, and its size in bytes.\n"
            "The whole mesh is read, so a malformed file is reported (exit status 1).\n"
            "Octree stores (raylod build) and cut files (raylod probe) are recognised by content.",
            {});
  if (Status st = args.parse(argc, argv); !st) return fail("info", st);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  if (args.positionals().size() != 1) return fail("info", Status::error("expected one FILE (see raylod info --help)"));
  const std::filesystem::path path = args.positionals()[0];
  // Before anything opens it: the magic checks below would block on a FIFO.
  if (Status st = check_regular_file(parse_mesh_ref(path).file); !st) return fail("info", st);

  // Dispatch by content (store and cut magic) first, then meshes by
  // extension; a new file kind gets its branch here, before the mesh fallback.
  // A damaged store or cut keeps its extension: its reader says what is wrong.
  if (is_store_file(path) || path.extension() == ".raylod") {
    if (Status st = print_store_info(path, stdout); !st) return fail("info", st);
    return 0;
  }
  if (is_cut_file(path) || path.extension() == ".cut") {
    if (Status st = print_cut_info(path, stdout); !st) return fail("info", st);
    return 0;
  }
  if (auto format = mesh_format_from_extension(path); format && *format == MeshFormat::Gltf) return print_gltf_info(path);
  return print_mesh_info(path);
}

}  // namespace

RAYLOD_COMMAND("info", "describe a mesh (format, counts, bounds, normals, bytes), store or cut file", run_info);

}  // namespace raylod::cli
