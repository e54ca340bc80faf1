// raylod render: ray trace a scene (or the embedded default scene) to an image.
#include <cstdio>
#include <sstream>

#include "cli/cli.h"
#include "core/cluster.h"
#include "core/system.h"
#include "gen/generate.h"
#include "render/image_codec.h"
#include "render/renderer.h"
#include "scene/scene.h"

namespace raylod::cli {
namespace {

Status run_render(int argc, char** argv, bool& help) {
  // Under mpirun the frame's tiles are split across the ranks (renderer.h).
  cluster::enlist();
  Args args("render", "[SCENE] -o IMAGE [options]",
            "Ray traces SCENE (a JSON scene file; the embedded default scene if omitted) with the\n"
            "scene's meshes, or with --mesh in place of the first object's mesh, and writes IMAGE\n"
            "in the format its extension names (.png, .exr, .jpg, .tif, ... via OpenImageIO).\n"
            "Only the effects the scene's materials and lights call for are simulated.",
            {{"--output", "-o", "output image (format by extension)", true, "IMAGE"},
             {"--mesh", "", "mesh to render in place of the first object's (.ply, .stl, .obj, .drc, .gltf, .glb)", true, "FILE"},
             {"--spp", "", "samples per pixel (default: the scene's)", true, "N"},
             threads_option(),
             {"--memory-limit", "", "refuse scenes whose mesh + BVH would exceed SIZE, e.g. 4G (default: no limit)", true, "SIZE"},
             {"--aov", "", "extra EXR images next to IMAGE: depth,normal,triangle-id", true, "LIST"},
             {"--wireframe", "", "darken pixels near triangle edges (shows triangle density)", false, ""},
             {"--width", "", "image width (default: the scene camera's)", true, "W"},
             {"--height", "", "image height (default: the scene camera's)", true, "H"},
             {"--stats-json", "", "write ray counters, timings and memory as JSON", true, "FILE"},
             {"--crease-angle", "", crease_angle_help(), true, "DEG"},
             quiet_option()});
  RAYLOD_RETURN_IF_ERROR(args.parse(argc, argv));
  if (args.help_requested()) {
    std::fputs(args.help_text().c_str(), stdout);
    help = true;
    return {};
  }
  if (!args.has("--output")) return Status::error("missing -o IMAGE (see raylod render --help)");
  const std::filesystem::path output = args.get("--output");
  // Only rank 0 writes images, so only it loads the image codec (0.4 s of
  // OpenImageIO's libraries, render/image_codec.h): on a thread of its own
  // while the scene loads and its BVH is built, after which the images'
  // writers are checked, before any ray (RenderOptions::before_trace).
  std::vector<std::filesystem::path> images;
  if (cluster::is_root()) start_loading_image_codec();
  auto check_image = [&images](const std::filesystem::path& p) {
    images.push_back(p);
    return cluster::is_root() ? check_output_image_early(p) : check_output_image_path(p);
  };
  RAYLOD_RETURN_IF_ERROR(cluster::agree(check_image(output)));  // the codec checks on rank 0 alone
  RAYLOD_RETURN_IF_ERROR(check_stats_json_path(args));

  RenderOptions opts;
  RAYLOD_ASSIGN_OR_RETURN(int64_t spp, args.get_int("--spp", 0, 1, 4096));
  RAYLOD_ASSIGN_OR_RETURN(uint64_t limit, args.get_size("--memory-limit", 0));
  opts.spp = int(spp);
  opts.memory_limit = limit;
  opts.wireframe = args.has("--wireframe");
  const bool quiet = apply_quiet(args);
  opts.progress = !quiet;
  // -q keeps errors and warnings (the option's rule): only the warnings of the log.
  opts.log = [quiet](const std::string& m) {
    if (!quiet || m.rfind("warning:", 0) == 0) std::fprintf(stderr, "raylod render: %s\n", m.c_str());
  };
  if (args.has("--aov")) {
    std::stringstream list(args.get("--aov"));
    std::string aov;
    while (std::getline(list, aov, ',')) {
      if (aov == "depth") opts.aov_depth = true;
      else if (aov == "normal") opts.aov_normal = true;
      else if (aov == "triangle-id") opts.aov_triangle_id = true;
      else return Status::error("--aov: '" + aov + "' is not one of depth, normal, triangle-id");
    }
    if (!opts.aov_depth && !opts.aov_normal && !opts.aov_triangle_id)
      return Status::error("--aov: no AOV named; give one or more of depth, normal, triangle-id");
  }

  RAYLOD_ASSIGN_OR_RETURN(Scene scene, scene_from_args(args));
  {
    std::vector<FileRole> outputs = {{output, "the image (-o)"}};
    if (args.has("--stats-json")) outputs.push_back({args.get("--stats-json"), "--stats-json"});
    for (const auto& [on, aov] : {std::pair{opts.aov_depth, "depth"}, std::pair{opts.aov_normal, "normal"},
                                  std::pair{opts.aov_triangle_id, "triangle-id"}}) {
      if (!on) continue;
      // Written beside the image: not beside a device or FIFO (/dev/null.depth.exr).
      if (is_pass_through_output(output))
        return Status::error(output.string() + ": --aov writes its images beside the image (-o), which must then be "
                             "a file, not a device or FIFO");
      // Checked like the image: a path that cannot be written fails before rendering, not after.
      RAYLOD_RETURN_IF_ERROR(cluster::agree(check_image(aov_path(output, aov))));
      outputs.push_back({aov_path(output, aov), std::string("the ") + aov + " AOV"});
    }
    RAYLOD_RETURN_IF_ERROR(check_outputs_apart(outputs, scene_input_files(args, scene)));
  }
  RAYLOD_ASSIGN_OR_RETURN(int64_t width, args.get_int("--width", scene.camera.width, 1, 32768));
  RAYLOD_ASSIGN_OR_RETURN(int64_t height, args.get_int("--height", scene.camera.height, 1, 32768));
  scene.camera.width = int(width);
  scene.camera.height = int(height);
  if (args.has("--mesh")) RAYLOD_RETURN_IF_ERROR(replace_first_mesh(scene, args.get("--mesh")));
  RAYLOD_RETURN_IF_ERROR(cluster::rank0_first([&] { return resolve_generated_meshes(scene, default_cache_dir()); }));

  opts.before_trace = [&images]() -> Status {
    if (cluster::is_root())
      for (const auto& p : images) RAYLOD_RETURN_IF_ERROR(check_output_image(p));
    return {};
  };
  opts.split_across_ranks = true;
  // An 8-bit output needs only the 8-bit frame: encoded tile by tile where
  // it is rendered (RenderOptions::srgb_color).
  opts.srgb_color = !is_float_image_format(output);
  RAYLOD_ASSIGN_OR_RETURN(RenderResult result, render(scene, opts));
  // Rank 0 holds the whole frame and writes it; the others wait to learn
  // whether it could, so that a failed write ends the job like any failure.
  auto write_outputs = [&]() -> Status {
    // The image and its AOVs all or none: each written under a temporary
    // name, then all renamed into place (an earlier image of the same names
    // stays if any write fails).
    ImageBatch batch;
    RAYLOD_RETURN_IF_ERROR(write_color(output, result, &batch));
    RAYLOD_ASSIGN_OR_RETURN(const std::vector<std::filesystem::path> aovs, write_aovs(output, result, &batch));
    RAYLOD_RETURN_IF_ERROR(batch.commit());
    const RenderStats& s = result.stats;
    if (!quiet)
      std::fprintf(stderr,
                 "raylod render: wrote %s (%dx%d, %d spp, %d threads%s)\n"
                 "raylod render: rays: camera %llu, shadow %llu, reflection %llu, refraction %llu; "
                 "total %llu in %.2f s (%.2f Mrays/s)\n"
                 "raylod render: load %.2f s, BVH %.2f s (%s), peak memory %s\n",
                 output.string().c_str(), s.width, s.height, s.spp, s.threads,
                 cluster::active() ? (" per rank, " + std::to_string(cluster::size()) + " ranks").c_str() : "",
                 (unsigned long long)s.rays.camera,
                 (unsigned long long)s.rays.shadow, (unsigned long long)s.rays.reflection,
                 (unsigned long long)s.rays.refraction, (unsigned long long)s.rays.total(), s.render_seconds,
                 s.rays_per_second() * 1e-6, s.load_seconds, s.bvh_seconds, format_bytes(s.bvh_bytes).c_str(),
                 format_bytes(s.peak_rss).c_str());
    if (!quiet)
      for (const auto& p : aovs) std::fprintf(stderr, "raylod render: wrote %s\n", p.string().c_str());
    if (args.has("--stats-json")) RAYLOD_RETURN_IF_ERROR(write_file_atomic(args.get("--stats-json"), render_stats_json(s) + "\n"));
    return {};
  };
  return cluster::agree(cluster::is_root() ? write_outputs() : Status::ok());
}

int cmd_render(int argc, char** argv) {
  bool help = false;
  Status st = run_render(argc, argv, help);
  return st.is_ok() ? 0 : fail("render", st);
}

}  // namespace

RAYLOD_COMMAND("render", "ray trace a scene to an image (simulating only the effects it calls for)", cmd_render);

}  // namespace raylod::cli
