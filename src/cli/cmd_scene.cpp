// raylod scene MESH [-o SCENE.json] [--up AXIS] [--material NAME] [--width W] [--height H] [--spp N]
#include <cstdio>
#include <filesystem>
#include <optional>
#include <vector>

#include "cli/cli.h"
#include "core/system.h"
#include "scene/mesh_framing.h"
#include "scene/scene.h"
#include "streaming/gltf_io.h"
#include "streaming/mesh_reader.h"

namespace raylod::cli {
namespace {

namespace fs = std::filesystem;

// How the scene file names the mesh: relative to the scene's folder when the
// mesh is in it or below it (the two move together), else absolute.
std::string mesh_path_in_scene(const fs::path& mesh, const fs::path& scene) {
  const fs::path m = fs::absolute(mesh).lexically_normal();
  const fs::path dir = fs::absolute(scene).lexically_normal().parent_path();
  // A scene written through a symlink lives in the folder of the file the
  // link names, and is read through either: a path relative to one of the
  // two folders is wrong from the other, so it is absolute.
  std::error_code ec;
  if (fs::is_symlink(scene, ec)) return m.generic_string();
  const fs::path rel = m.lexically_relative(dir);
  if (!rel.empty() && *rel.begin() != "..") return rel.generic_string();
  return m.generic_string();
}

struct PlacedMesh {
  Bbox bounds;              // as the scene will place it, before --up
  uint64_t triangles = 0;   // placed: a glTF mesh counts once per node using it
};

// The mesh's bounds as a scene object naming it places it: a mesh file's own
// bounds, or, for a whole glTF file, the union over the nodes of its default
// scene of each node's mesh bounds under the node's transform (the scene
// format makes one object per node instance, scene.h).
StatusOr<PlacedMesh> placed_mesh(const fs::path& mesh) {
  PlacedMesh out;
  const MeshRef ref = parse_mesh_ref(mesh);
  auto format = mesh_format_from_extension(ref.file);
  if (format.is_ok() && *format == MeshFormat::Gltf && ref.gltf_mesh < 0) {
    RAYLOD_ASSIGN_OR_RETURN(GltfSummary gltf, describe_gltf(mesh));
    std::vector<std::optional<MeshSummary>> summaries(gltf.meshes.size());
    for (const GltfInstance& inst : gltf.instances) {
      if (gltf.meshes[size_t(inst.mesh)].triangle_primitives == 0) continue;
      std::optional<MeshSummary>& m = summaries[size_t(inst.mesh)];
      if (!m) {
        RAYLOD_ASSIGN_OR_RETURN(MeshSummary read, summarize_mesh(gltf_mesh_path(mesh, inst.mesh)));
        m = read;
      }
      out.triangles += m->triangle_count;
      out.bounds.expand(world_bounds(inst.transform, m->bounds));
    }
    return out;
  }
  RAYLOD_ASSIGN_OR_RETURN(MeshSummary summary, summarize_mesh(mesh));
  out.bounds = summary.bounds;
  out.triangles = summary.triangle_count;
  return out;
}

Status write_scene_for_mesh(const Args& args) {
  if (args.positionals().size() != 1) return Status::error("expected one MESH (see raylod scene --help)");
  const fs::path mesh = args.positionals()[0];
  const fs::path out = args.get("--output", mesh.stem().string() + ".json");
  FramingOptions options;
  RAYLOD_ASSIGN_OR_RETURN(options.up, parse_up_axis(args.get("--up", "y")));
  RAYLOD_ASSIGN_OR_RETURN(MaterialPreset material, parse_material_preset(args.get("--material", "glossy")));
  RAYLOD_ASSIGN_OR_RETURN(int64_t width, args.get_int("--width", options.width, 1, 32768));
  RAYLOD_ASSIGN_OR_RETURN(int64_t height, args.get_int("--height", options.height, 1, 32768));
  RAYLOD_ASSIGN_OR_RETURN(int64_t spp, args.get_int("--spp", 4, 1, 4096));
  options.width = int(width);
  options.height = int(height);
  RAYLOD_RETURN_IF_ERROR(check_output_path(out, "the scene (-o)"));
  RAYLOD_RETURN_IF_ERROR(check_outputs_apart({{out, "the scene (-o)"}}, {{mesh, "the mesh"}}));
  RAYLOD_RETURN_IF_ERROR(check_regular_file(parse_mesh_ref(mesh).file));

  // The whole mesh is read once for its bounds.
  RAYLOD_ASSIGN_OR_RETURN(PlacedMesh summary, placed_mesh(mesh));
  if (summary.triangles == 0) return Status::error(mesh.string() + ": has no triangles: nothing to frame");
  StatusOr<MeshFraming> framing = frame_mesh(summary.bounds, options);
  if (!framing) return Status::error(mesh.string() + ": " + framing.status().message());
  const MeshFraming& f = *framing;

  char comment[512];
  std::snprintf(comment, sizeof comment,
                "Made by raylod scene from %s (%llu triangles, up %s): the camera frames its bounds, the ground is "
                "%.6g below its lowest point (y = %.9g).",
                mesh.filename().string().c_str(), (unsigned long long)summary.triangles, to_string(options.up),
                f.bounds.lo.y - f.ground_height, f.bounds.lo.y);
  const std::string text = scene_json_for_mesh(mesh_path_in_scene(mesh, out), f, material, int(spp), comment);
  // What is written must load as a scene (a mesh path the format cannot take
  // would otherwise show only when the scene is run).
  {
    AtomicOutput file(out);
    RAYLOD_RETURN_IF_ERROR(write_temporary(file, text));
    StatusOr<Scene> check = load_scene(file.temp_path());
    if (!check) return Status::error("internal: the scene written for " + mesh.string() + " does not load: " +
                                     check.status().message());
    RAYLOD_RETURN_IF_ERROR(file.commit());
  }
  cli::summary("wrote %s\n", out.string().c_str());
  cli::summary("  mesh       %s (%llu triangles, up %s)\n", mesh.string().c_str(),
              (unsigned long long)summary.triangles, to_string(options.up));
  const Vec3d e = f.bounds.extent();
  cli::summary("  bounds     %.6g x %.6g x %.6g (rotated to y up), centre (%.6g, %.6g, %.6g)\n", e.x, e.y, e.z,
              f.camera.look_at.x, f.camera.look_at.y, f.camera.look_at.z);
  cli::summary("  camera     eye (%.6g, %.6g, %.6g), fov_y %g, %d x %d, %d spp\n", f.camera.eye.x, f.camera.eye.y,
              f.camera.eye.z, f.camera.fov_y_deg, f.camera.width, f.camera.height, int(spp));
  cli::summary("  ground     y = %.9g\n", f.ground_height);
  cli::summary("next: raylod run %s --compare\n", out.string().c_str());
  return Status::ok();
}

int run_scene(int argc, char** argv) {
  Args args("scene", "MESH [-o SCENE.json] [--up AXIS] [--material NAME] [--width W] [--height H] [--spp N]",
            "Writes a scene file around MESH (.ply, .stl, .obj, .gltf/.glb) to run, render or edit:\n"
            "the camera looks at the centre of the mesh's bounds from above and to the front\n"
            "right, as the default scene looks at its teapot, close enough that the bounds\n"
            "fill 85% of the frame; a diffuse ground lies a thousandth of the bounds'\n"
            "diagonal below the lowest point; the lights are the default scene's, placed and\n"
            "scaled with the camera's distance. The mesh keeps its units and position; --up\n"
            "rotates it so that its up axis becomes +Y (CAD exports are often Z-up). The\n"
            "mesh is read once for its bounds. The scene is written atomically.",
            {{"--output", "-o", "scene file to write (default: MESH's name with .json, in the current folder)",
              true, "SCENE"},
             {"--up", "", "the mesh's up axis: x, y, z, -x, -y or -z (default y)", true, "AXIS"},
             {"--material", "", "glossy (steel; default), diffuse, mirror or glass", true, "NAME"},
             {"--width", "", "image width (default 1280)", true, "W"},
             {"--height", "", "image height (default 960)", true, "H"},
             {"--spp", "", "samples per pixel (default 4)", true, "N"},
             quiet_option()});
  if (Status st = args.parse(argc, argv); !st) return fail("scene", st);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  apply_quiet(args);
  if (Status st = write_scene_for_mesh(args); !st) return fail("scene", st);
  return 0;
}

}  // namespace

RAYLOD_COMMAND("scene", "write a scene file that frames a mesh (camera, ground, lights) to run or edit", run_scene);

}  // namespace raylod::cli
