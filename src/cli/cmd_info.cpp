// raylod info FILE: what a file holds. Meshes (.ply, .stl, .obj, .drc) are
// read in full (format, encoding, counts, bounds, normals, bytes).
#include <cinttypes>
#include <cstdio>
#include <filesystem>

#include "cli/cli.h"
#include "core/system.h"
#include "streaming/cut_file.h"
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
  std::printf("bounds:     min (%.9g, %.9g, %.9g)\n", s.bounds.lo.x, s.bounds.lo.y, s.bounds.lo.z);
  std::printf("            max (%.9g, %.9g, %.9g)\n", s.bounds.hi.x, s.bounds.hi.y, s.bounds.hi.z);
  const Vec3d e = s.bounds.extent();
  std::printf("size:       %.9g x %.9g x %.9g (diagonal %.9g)\n", e.x, e.y, e.z, s.bounds.diagonal());
  std::printf("normals:    %s\n", h.has_normals ? "yes (per vertex)" : "no");
  std::printf("bytes:      %" PRIu64 " (%s)\n", h.file_bytes, format_bytes(h.file_bytes).c_str());
  return 0;
}

int run_info(int argc, char** argv) {
  Args args("info", "FILE",
            "Describes a file. For a mesh (.ply, .stl, .obj, .drc): format and encoding, triangle\n"
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
  if (Status st = check_regular_file(path); !st) return fail("info", st);

  // Dispatch by content (store and cut magic) first, then meshes by
  // extension; a new file kind gets its branch here, before the mesh fallback.
  if (is_store_file(path)) {
    if (Status st = print_store_info(path, stdout); !st) return fail("info", st);
    return 0;
  }
  if (is_cut_file(path)) {
    if (Status st = print_cut_info(path, stdout); !st) return fail("info", st);
    return 0;
  }
  return print_mesh_info(path);
}

}  // namespace

RAYLOD_COMMAND("info", "describe a mesh (format, counts, bounds, normals, bytes), store or cut file", run_info);

}  // namespace raylod::cli
