// raylod run: the whole pipeline (build, probe, simplify, render) for one
// view, with simplified meshes cached across views.
#include <cctype>
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "cli/cli.h"
#include "streaming/octree_store.h"
#include "streaming/source_record.h"
#include "core/cluster.h"
#include "core/memory_budget.h"
#include "core/system.h"
#include "gen/generate.h"
#include "pipeline/image_compare.h"
#include "pipeline/noise_floor.h"
#include "pipeline/pipeline.h"
#include "pipeline/views.h"
#include "render/image_codec.h"
#include "render/renderer.h"
#include "scene/orbit.h"

namespace raylod::cli {
namespace {

// The images --compare writes beside the image (-o): OUT.full.EXT (the full
// mesh) and OUT.diff.EXT (the difference).
std::filesystem::path compare_image_path(const std::filesystem::path& output, const char* what) {
  std::filesystem::path p = output;
  p.replace_extension("." + std::string(what) + output.extension().string());
  return p;
}

// One line per simplified mesh under the summary's simplify line; with more
// than one mesh each line names its mesh.
void print_cache_note(const SimplifiedMesh& m, size_t meshes) {
  if (meshes > 1)
    summary("             %s: %llu triangles, %s\n", m.name.c_str(), (unsigned long long)m.triangles,
                m.cache_note.c_str());
  else
    summary("             %s\n", m.cache_note.c_str());
}

// The terminal summary of a view sequence, and its --stats-json.
Status report_views(const Args& args, const ViewsResult& r, const RunOptions& opts, const std::filesystem::path& output) {
  const bool shared = r.shared_cut;
  for (const std::string& w : r.warnings) std::fprintf(stderr, "raylod run: warning: %s\n", w.c_str());
  summary("raylod run: %s, %zu views (%s)\n", args.positionals().empty() ? "embedded default scene" : args.positionals()[0].c_str(),
              r.views.size(), shared ? "one shared cut" : "a cut per view, cached meshes reused");
  summary("  build      %7.2f s  (%llu triangles)\n", r.build_seconds, (unsigned long long)r.triangles_in);
  if (r.ranks > 1)
    summary("  ranks      %d (views handed out %s; images written by the rank that rendered them)\n", r.ranks,
                r.dynamic_handout ? "one at a time" : "round robin");
  if (shared) {
    uint64_t triangles = 0;
    for (const SimplifiedMesh& m : r.shared_meshes) triangles += m.triangles;
    summary("  shared cut %7.2f s  (select over all views' test rays), simplify %.2f s: %llu triangles\n",
                r.shared_select_seconds, r.shared_simplify_seconds, (unsigned long long)triangles);
    for (const SimplifiedMesh& m : r.shared_meshes) print_cache_note(m, r.shared_meshes.size());
  }
  summary("  view  triangles  mesh    probe s  simplify s  render s  image\n");
  for (size_t i = 0; i < r.views.size(); ++i) {
    const ViewStats& v = r.views[i];
    summary("  %4zu  %9llu  %-6s  %7.2f  %10.2f  %8.2f  %s\n", i, (unsigned long long)v.triangles,
                shared ? "shared" : v.cache_hit ? "hit" : "miss", v.probe, v.simplify, v.render, numbered_image_path(output, i).string().c_str());
  }
  summary("  total      %7.2f s, %.2f s per view; %zu of %zu views reused a simplified mesh (%s); peak memory %s\n",
              r.total_seconds, r.seconds_per_view(), r.cache_reuse(), r.views.size(),
              shared ? "the shared one, or the cache's" : "from the cache", format_bytes(r.peak_rss).c_str());
  if (args.has("--stats-json")) RAYLOD_RETURN_IF_ERROR(write_file_atomic(args.get("--stats-json"), views_stats_json(r, opts)));
  return {};
}


// --views FILE / --orbit N: every view rendered to a numbered image.
Status run_view_sequence(const Args& args, Scene scene, const std::vector<Camera>& cameras, const RunOptions& opts,
                         const std::filesystem::path& output, const LogFn& log) {
  const bool shared = args.has("--shared-cut");
  auto write_view = [&](size_t i, const RenderResult& r) -> Status {
    return write_color(numbered_image_path(output, i), r);
  };
  RAYLOD_ASSIGN_OR_RETURN(ViewsResult r, run_views(std::move(scene), cameras, opts, shared, write_view, log));
  // Rank 0 has every view's statistics; the others wait to learn whether it
  // could write them.
  return cluster::agree(cluster::is_root() ? report_views(args, r, opts, output) : Status::ok());
}

Status run_run(int argc, char** argv, bool& help) {
  // Under mpirun: views handed out to the ranks, or one view's test rays and
  // tiles split across them (README, "Running on a cluster").
  cluster::enlist();
  Args args("run", "[SCENE] -o IMAGE [options]",
            "Builds (or reuses) the octree store of the scene's mesh, traces test rays with ray\n"
            "differentials, collapses the cells no ray can resolve, and renders the simplified\n"
            "mesh. Without SCENE, renders the embedded default scene (its teapot is generated\n"
            "on first use into the cache). Simplified meshes are cached and reused for later\n"
            "views that need no finer detail anywhere their probe looks.",
            with_cut_options({{"--output", "-o", "output image (format by extension; default raylod-run.png)", true, "IMAGE"},
             {"--mesh", "", "mesh to use in place of the scene's first object's mesh", true, "FILE"},
             {"--memory-limit", "", "memory cap (default: a quarter of physical memory); the cut is\n"
                                    "                              coarsened until the simplified mesh fits", true, "SIZE"},
             {"--rays", "", "test rays (default 5000)", true, "N"},
             {"--spp", "", "samples per pixel (default: the scene's)", true, "N"},
             threads_option(),
             {"--cache", "", "cache directory (default $XDG_CACHE_HOME/raylod or ~/.cache/raylod)", true, "DIR"},
             {"--cache-limit", "", "cache size limit, least recently used evicted (default 4G)", true, "SIZE"},
             {"--no-cache", "", "neither reuse nor keep simplified meshes", false, ""},
             {"--compare", "", "also render the full-resolution mesh and report the error, beside the\n"
                               "                              noise floor (the full mesh at seed + 1 against seed)", false, ""},
             {"--stats-json", "", "write triangle counts, stage times, memory and cache use as JSON", true, "FILE"},
             {"--export-mesh", "", "also write the simplified meshes as a Draco-compressed glTF (.glb), one\n"
                                   "                              node per scene object, with the .drc's quantisation", true, "OUT.glb"},
             {"--crease-angle", "", crease_angle_help(), true, "DEG"},
             {"--width", "", "image width (default: the scene camera's; with --views, the views' default)", true, "W"},
             {"--height", "", "image height (default: the scene camera's; likewise)", true, "H"},
             {"--views", "", "render every camera of a JSON list (the scene camera's fields; up, fov_y,\n"
                             "                              width and height default to the scene's) to numbered images:\n"
                             "                              -o out_####.png (without '#', _#### goes before the extension)", true, "FILE"},
             {"--orbit", "", "render N views on a horizontal circle around the scene camera's look_at,\n"
                             "                              through its eye, evenly spaced (numbered images as --views)", true, "N"},
             {"--shared-cut", "", "with --views or --orbit: one cut with the finest need over all views,\n"
                                  "                              simplified once, every view rendered from it", false, ""},
             quiet_option()}));
  RAYLOD_RETURN_IF_ERROR(args.parse(argc, argv));
  if (args.help_requested()) {
    std::fputs(args.help_text().c_str(), stdout);
    help = true;
    return {};
  }
  const std::filesystem::path output = args.get("--output", "raylod-run.png");
  const bool sequence = args.has("--views") || args.has("--orbit");
  if (args.has("--views") && args.has("--orbit")) return Status::error("--views and --orbit exclude each other: give one");
  if (args.has("--shared-cut") && !sequence) return Status::error("--shared-cut needs --views FILE or --orbit N");
  if (sequence && args.has("--compare"))
    return Status::error("--compare measures one view; with --views or --orbit render the full mesh per view "
                         "(build/tools/views_benchmark does)");
  if (sequence && args.has("--export-mesh")) return Status::error("--export-mesh takes one view, not --views or --orbit");
  if (cluster::active() && args.has("--compare"))
    return Status::error("--compare runs in one process: run it without mpirun");
  const std::filesystem::path first_image = sequence ? numbered_image_path(output, 0) : output;
  // OpenImageIO's 0.4 s of loading overlaps the store stage, which then
  // checks that the image has a writer (RunOptions::output_image); an
  // extension no build is sure to write is checked now.
  start_loading_image_codec();
  RAYLOD_RETURN_IF_ERROR(check_output_image_early(first_image));
  RAYLOD_RETURN_IF_ERROR(check_stats_json_path(args));
  if (args.has("--export-mesh")) RAYLOD_RETURN_IF_ERROR(check_output_path(args.get("--export-mesh"), "--export-mesh"));
  if (args.has("--compare")) {
    if (is_pass_through_output(output))
      return Status::error(output.string() + ": --compare writes its images beside the image (-o), which must then "
                           "be a file, not a device or FIFO");
    // Its two images are written after the image (-o): checked now, so that
    // a failure to write them cannot leave the image behind.
    RAYLOD_RETURN_IF_ERROR(check_output_image_path(compare_image_path(output, "full")));
    RAYLOD_RETURN_IF_ERROR(check_output_image_path(compare_image_path(output, "diff")));
  }

  RunOptions opts;
  opts.output_image = first_image;
  RAYLOD_ASSIGN_OR_RETURN(const MemoryBudget budget, memory_budget_from_args(args));
  opts.memory_limit = budget.total;
  RAYLOD_ASSIGN_OR_RETURN(int64_t rays, args.get_int("--rays", 5000, 1, 100000000));
  RAYLOD_ASSIGN_OR_RETURN(CutOptions cut, cut_options_from_args(args));
  opts.footprint_scale = cut.footprint_scale;
  opts.criterion = cut.criterion;
  RAYLOD_ASSIGN_OR_RETURN(int64_t spp, args.get_int("--spp", 0, 1, 4096));
  RAYLOD_ASSIGN_OR_RETURN(opts.cache_limit, args.get_size("--cache-limit", uint64_t(4) << 30));
  opts.rays = uint64_t(rays);
  opts.spp = int(spp);
  // An empty --cache (an unset variable in a cluster script) names no folder:
  // refused, not taken for the default, which would give each node its own.
  if (args.has("--cache") && args.get("--cache").empty())
    return Status::error("--cache: an empty folder name (leave the option out for the default, " +
                         default_cache_dir().string() + ")");
  opts.cache_dir = args.get("--cache", default_cache_dir().string());
  opts.use_cache = !args.has("--no-cache");
  if (args.has("--mesh")) opts.mesh_override = std::filesystem::path(args.get("--mesh"));
  if (args.has("--export-mesh")) {
    opts.export_mesh = args.get("--export-mesh");
    std::string ext = opts.export_mesh.extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".glb")
      return Status::error(opts.export_mesh.string() + ": --export-mesh writes glTF binary; the name must end in .glb");
  }
  const bool quiet = apply_quiet(args);
  opts.progress = !quiet;
  // Only --compare looks at the linear colors; an 8-bit image is encoded
  // tile by tile where rendered (RenderOptions::srgb_color).
  opts.srgb_color = !args.has("--compare") && !is_float_image_format(output);
  LogFn log;
  if (!quiet) log = [](const std::string& m) { std::fprintf(stderr, "raylod run: %s\n", m.c_str()); };

  RAYLOD_ASSIGN_OR_RETURN(Scene scene, scene_from_args(args));
  RAYLOD_ASSIGN_OR_RETURN(int64_t width, args.get_int("--width", scene.camera.width, 1, 32768));
  RAYLOD_ASSIGN_OR_RETURN(int64_t height, args.get_int("--height", scene.camera.height, 1, 32768));
  scene.camera.width = int(width);
  scene.camera.height = int(height);
  const int render_spp = opts.spp > 0 ? opts.spp : scene.spp;
  cut.fit_defaults_to(render_spp);  // the tolerances, once the render's spp is known
  opts.tolerance_px = cut.tolerance_px;
  opts.angle_tolerance_px = cut.angle_tolerance_px;
  opts.outline_tolerance = cut.outline_tolerance;
  opts.unreached_angle_allowance = cut.unreached_angle_allowance;
  opts.balance = cut.balance;
  opts.unseen_cells = cut.unseen_cells;
  opts.shadow_receivers = cut.shadow_receivers;
  {
    std::vector<FileRole> outputs = {{sequence ? numbered_image_path(output, 0) : output, "the image (-o)"}};
    if (args.has("--compare")) {
      outputs.push_back({compare_image_path(output, "full"), "--compare's full-mesh image"});
      outputs.push_back({compare_image_path(output, "diff"), "--compare's difference image"});
    }
    if (args.has("--stats-json")) outputs.push_back({args.get("--stats-json"), "--stats-json"});
    if (!opts.export_mesh.empty()) outputs.push_back({opts.export_mesh, "--export-mesh"});
    std::vector<FileRole> inputs = scene_input_files(args, scene);
    // The stores run builds beside the meshes, and their check records: an
    // output there would be written over a store the same run reads.
    for (const FileRole& mesh : scene_mesh_files(args, scene)) {
      if (mesh.path.empty()) continue;
      const std::filesystem::path store = default_store_path(mesh.path);
      inputs.push_back({store, "the store of " + mesh.role});
      inputs.push_back({source_record_path(store), "the check record of " + mesh.role + "'s store"});
    }
    if (args.has("--views")) inputs.push_back({args.get("--views"), "the --views file"});
    RAYLOD_RETURN_IF_ERROR(check_outputs_apart(outputs, inputs));
  }
  if (sequence) {
    // The cameras are read (and checked) before anything is built or written.
    std::vector<Camera> cameras;
    if (args.has("--views")) {
      RAYLOD_ASSIGN_OR_RETURN(cameras, load_views(args.get("--views"), scene.camera));
    } else {
      RAYLOD_ASSIGN_OR_RETURN(int64_t n, args.get_int("--orbit", 0, 1, kMaxViews));
      RAYLOD_ASSIGN_OR_RETURN(cameras, orbit_cameras(scene.camera, int(n)));
    }
    // Each view's frame against the memory limit, so that a view too large
    // for it fails before the views before it are rendered: against 7/8 of
    // the working memory, what keep_pages_between_views leaves a view before
    // it also takes out the node tables it keeps (the stores are not open
    // yet), so a frame that passes here may still fail there, at its view.
    const MemoryBudget views_budget = MemoryBudget::of(opts.memory_limit);
    const uint64_t per_view = views_budget.working() - views_budget.working() / 8;
    RenderOptions frame;
    frame.srgb_color = opts.srgb_color;
    for (size_t i = 0; i < cameras.size() && views_budget.limited(); ++i) {
      const uint64_t image = estimate_image_memory(cameras[i].width, cameras[i].height, frame);
      if (image >= per_view)
        return Status::error((args.has("--views") ? args.get("--views") + ": [" + std::to_string(i) + "]"
                                                  : std::string("--orbit: view ") + std::to_string(i)) +
                             ": the " + std::to_string(cameras[i].width) + " x " + std::to_string(cameras[i].height) +
                             " image needs about " + format_bytes(image) + ", more than the " +
                             format_bytes(per_view) + " the memory limit of " + format_bytes(budget.total) +
                             " leaves after the program's own " + format_bytes(budget.baseline) +
                             "; render a smaller image or raise --memory-limit");
    }
    // Each view's image, now that their number is known: a path a view
    // could not be written to (a directory there) would fail the run after
    // the views before it were written. And against the statistics file
    // (view 0's was checked with the others above).
    for (size_t i = 1; i < cameras.size(); ++i) {
      RAYLOD_RETURN_IF_ERROR(check_output_image_path(numbered_image_path(output, i)));
      if (args.has("--stats-json"))
        RAYLOD_RETURN_IF_ERROR(check_outputs_apart({{numbered_image_path(output, i), "the image of view " + std::to_string(i)}},
                                                   {{args.get("--stats-json"), "--stats-json"}}));
    }
    return run_view_sequence(args, std::move(scene), cameras, opts, output, log);
  }

  RAYLOD_ASSIGN_OR_RETURN(RunResult r, run_pipeline(scene, opts, log));
  // Rank 0 holds the whole frame and writes it (and the statistics); the
  // others wait to learn whether it could, so that a failed write ends the
  // job like any failure.
  auto write_outputs = [&]() -> Status {
    RAYLOD_RETURN_IF_ERROR(write_color(output, r.render));
    for (const std::string& w : r.warnings) std::fprintf(stderr, "raylod run: warning: %s\n", w.c_str());

    summary("raylod run: %s\n", args.positionals().empty() ? "embedded default scene" : args.positionals()[0].c_str());
    if (r.triangles_out == 0) {
      summary("  triangles  %llu -> 0 (every one collapsed or left out)\n", (unsigned long long)r.triangles_in);
    } else {
      // Two decimals below 10x, so that 9956 -> 9871 does not read as no change.
      const double ratio = double(r.triangles_in) / double(r.triangles_out);
      summary("  triangles  %llu -> %llu (%.*fx fewer)\n", (unsigned long long)r.triangles_in,
                  (unsigned long long)r.triangles_out, ratio < 10 ? 2 : 1, ratio);
    }
    // The counts above are per distinct mesh; a mesh the scene places more
    // than once is rendered once per placement.
    if (scene.objects.size() > r.meshes.size()) {
      const unsigned long long rendered = r.render.stats.triangles;
      if (r.meshes.size() == 1)
        summary("             the scene places this mesh %zu times: %llu triangles rendered\n", scene.objects.size(),
                    rendered);
      else
        summary("             %zu objects place these %zu meshes: %llu triangles rendered\n", scene.objects.size(),
                    r.meshes.size(), rendered);
    }
    summary("  build      %7.2f s\n", r.seconds.build);
    char tolerance[96] = "";
    if (opts.criterion == CutCriterion::Deviation && opts.tolerance_px != kDefaultTolerancePx) {
      if (cut.tolerance_given)
        std::snprintf(tolerance, sizeof tolerance, ", tolerance %.3g px", opts.tolerance_px);
      else
        std::snprintf(tolerance, sizeof tolerance, ", tolerance %.3g px (%g fitted to %d spp)", opts.tolerance_px,
                      kDefaultTolerancePx, render_spp);
    }
    summary("  probe      %7.2f s  (%llu test rays, K = %g%s%s)\n", r.seconds.probe, (unsigned long long)opts.rays,
                r.footprint_scale, tolerance, r.coarsening_steps ? ", coarsened to fit the memory limit" : "");
    summary("  simplify   %7.2f s  (%s)\n", r.seconds.simplify, r.cache_hit ? "from cache" : "simplified");
    for (const SimplifiedMesh& m : r.meshes) print_cache_note(m, r.meshes.size());
    summary("  render     %7.2f s  (load %.2f s, BVH %.2f s, trace %.2f s)\n", r.seconds.render,
                r.render.stats.load_seconds, r.render.stats.bvh_seconds, r.render.stats.render_seconds);
    summary("  total      %7.2f s, peak memory %s\n", r.seconds.total(), format_bytes(r.peak_rss).c_str());

    std::string stats = run_stats_json(r, opts);
    if (args.has("--compare")) {
      // The full-resolution render the method is measured against, and the
      // noise floor that says what difference sampling alone makes: the full
      // mesh at the next seed, same spp, against the reference.
      RAYLOD_RETURN_IF_ERROR(resolve_generated_meshes(scene, opts.cache_dir));
      RenderOptions ro;
      ro.spp = opts.spp;
      // The comparison runs after the run's own render has been freed, so it
      // gets the whole memory limit to itself.
      ro.memory_limit = opts.memory_limit;
      ro.progress = opts.progress;
      ro.over_limit_hint.clear();
      if (opts.mesh_override) ro.mesh_override = {*opts.mesh_override};
      RAYLOD_ASSIGN_OR_RETURN(uint64_t full_triangles, declared_scene_triangles(scene, ro));
      const uint64_t full_need = estimate_render_memory(full_triangles, bvh_for_memory_limit(full_triangles, ro.memory_limit));
      if (ro.memory_limit && full_need > ro.memory_limit) {
        // The run itself succeeded: keep its image and statistics, and say why
        // there is no comparison.
        const std::string why = "the full mesh (" + std::to_string(full_triangles) + " triangles) needs about " +
                                format_bytes(full_need) + " to render, over the memory limit of " +
                                format_bytes(ro.memory_limit) + "; raise --memory-limit to compare";
        std::fprintf(stderr, "raylod run: warning: --compare skipped: %s\n", why.c_str());
        summary("  error      not measured (--compare skipped: %s)\n", why.c_str());
        auto j = nlohmann::json::parse(stats);
        j["comparison_skipped"] = why;
        stats = j.dump(2) + "\n";
      } else {
        RAYLOD_ASSIGN_OR_RETURN(FullRender fr, render_full_with_noise_floor(scene, ro));
        const RenderResult& full = fr.reference;
        const NoiseFloor& floor = fr.noise_floor;
        RAYLOD_ASSIGN_OR_RETURN(ImageError e, compare_images(r.render.color, full.color));
        const RenderStats& fs = full.stats;
        double full_seconds = fs.load_seconds + fs.bvh_seconds + fs.render_seconds;
        summary("  full mesh  %7.2f s  (load %.2f s, BVH %.2f s, trace %.2f s; seed %llu, and %.2f s more at seed %llu "
                    "for the noise floor)\n",
                    full_seconds, fs.load_seconds, fs.bvh_seconds, fs.render_seconds, (unsigned long long)floor.seed,
                    floor.render_seconds, (unsigned long long)noise_floor_seed(floor.seed));
        summary("  error      PSNR %.2f dB, SSIM %.4f (%s), largest pixel difference %.3f\n", e.psnr, e.ssim,
                    describe_against_noise_floor(e, floor).c_str(), e.max_diff);
        summary("  floor      PSNR %.2f dB, SSIM %.4f, largest pixel difference %.3f (full mesh, seed %llu against "
                    "seed %llu, %d spp)\n",
                    floor.psnr(), floor.error.ssim, floor.error.max_diff, (unsigned long long)noise_floor_seed(floor.seed),
                    (unsigned long long)floor.seed, floor.spp);
        const std::filesystem::path ref = compare_image_path(output, "full");
        RAYLOD_RETURN_IF_ERROR(write_image(ref, full.color));
        const std::filesystem::path diff = compare_image_path(output, "diff");
        RAYLOD_RETURN_IF_ERROR(write_image(diff, difference_image(r.render.color, full.color)));
        summary("  wrote      %s (full mesh), %s (difference x4)\n", ref.string().c_str(), diff.string().c_str());
        // run_stats_json() (pipeline.cpp) knows nothing of the comparison: extend its object.
        auto j = nlohmann::json::parse(stats);
        // Identical images have infinite PSNR, which JSON cannot hold: null.
        auto psnr_json = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
        j["full_render_seconds"] = full_seconds;
        j["psnr"] = psnr_json(e.psnr);
        j["ssim"] = e.ssim;
        j["max_diff"] = e.max_diff;
        j["noise_floor"] = {{"seed", floor.seed},
                            {"other_seed", noise_floor_seed(floor.seed)},
                            {"spp", floor.spp},
                            {"psnr", psnr_json(floor.psnr())},
                            {"ssim", floor.error.ssim},
                            {"max_diff", floor.error.max_diff},
                            {"render_seconds", floor.render_seconds}};
        j["within_noise_floor"] = within_noise_floor(e, floor);
        stats = j.dump(2) + "\n";
      }
    }
    summary("  wrote      %s\n", output.string().c_str());
    if (!opts.export_mesh.empty())
      summary("  exported   %s (%s)\n", opts.export_mesh.string().c_str(), format_bytes(r.exported_bytes).c_str());
    if (args.has("--stats-json")) RAYLOD_RETURN_IF_ERROR(write_file_atomic(args.get("--stats-json"), stats));
    return {};
  };
  return cluster::agree(cluster::is_root() ? write_outputs() : Status::ok());
}

int cmd_run(int argc, char** argv) {
  bool help = false;
  Status st = run_run(argc, argv, help);
  return st.is_ok() ? 0 : fail("run", st);
}

}  // namespace

RAYLOD_COMMAND("run", "the whole pipeline: build, probe, simplify and render one view (cached)", cmd_run);

}  // namespace raylod::cli
