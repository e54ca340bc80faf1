// raylod report: what accuracy costs in time (sweeps of K and test rays,
// uniform baselines, REPORT.md with tables, plots and difference images).
#include <cstdio>
#include <algorithm>
#include <sstream>

#include "cli/cli.h"
#include "core/system.h"
#include "pipeline/report.h"

namespace raylod::cli {
namespace {

template <class T>
Status parse_list(const std::string& text, const char* what, std::vector<T>& out) {
  out.clear();
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t pos = 0;
      double v = std::stod(item, &pos);
      if (pos != item.size() || !(v > 0)) throw std::invalid_argument(item);
      // A value given twice would give the same row twice.
      if (std::find(out.begin(), out.end(), T(v)) != out.end())
        return Status::error(std::string(what) + ": '" + item + "' is given twice");
      out.push_back(T(v));
    } catch (...) {
      return Status::error(std::string(what) + ": '" + item + "' is not a positive number");
    }
  }
  if (out.empty()) return Status::error(std::string(what) + ": empty list");
  return {};
}

// "4,8,16" from a list, as the help text shows defaults.
template <typename T>
std::string join_list(const std::vector<T>& values) {
  std::ostringstream out;
  for (size_t i = 0; i < values.size(); ++i) out << (i ? "," : "") << values[i];
  return out.str();
}

Status run_report_cmd(int argc, char** argv) {
  const ReportConfig defaults;
  Args args("report", "[SCENE] [-o DIR] [options]",
            "Shows what accuracy costs in time: renders the full-resolution mesh as the reference,\n"
            "then raylod at a sweep of footprint scales K and test-ray counts, and the uniform\n"
            "baselines (meshoptimizer's vertex clustering and quadric edge collapse) at the same\n"
            "triangle counts, on the scene's view and a close-up of it. Writes DIR/REPORT.md with\n"
            "the table, accuracy-versus-time plots, difference images and pictures of the cut.\n"
            "DIR is written whole or not at all: the report is built in a temporary folder beside it\n"
            "that replaces DIR once complete. DIR must be missing, empty or an earlier report\n"
            "(replaced with all its files); a folder of other files is refused.",
            {{"--output", "-o", "report directory (default raylod-report)", true, "DIR"},
             {"--mesh", "", "mesh to use in place of the scene's first object's mesh", true, "FILE"},
             {"--scales", "",
              "footprint scales K to sweep with the deviation criterion (default " +
                  join_list(defaults.footprint_scales) + "; the diagonal criterion at " +
                  join_list(defaults.diagonal_scales) + " beside them)",
              true, "LIST"},
             {"--rays", "", "test-ray counts to sweep (default " + join_list(defaults.ray_counts) + ")", true, "LIST"},
             {"--default-scale", "",
              "K of the ray sweep and the headline figures (default " + join_list(std::vector{defaults.default_scale}) + ")",
              true, "K"},
             {"--default-rays", "",
              "test rays of the K sweep (default " + std::to_string(defaults.default_rays) + ")", true, "N"},
             {"--no-closeup", "", "skip the close-up view", false, ""},
             {"--no-baselines", "", "skip the meshoptimizer baselines", false, ""},
             {"--spp", "", "samples per pixel (default: the scene's)", true, "N"},
             {"--width", "", "image width (default: the scene's)", true, "W"},
             {"--height", "", "image height (default: the scene's)", true, "H"},
             threads_option(),
             {"--memory-limit", "", "memory cap (default: a quarter of physical memory)", true, "SIZE"},
             {"--quick", "", "a small, fast report (160x120, 1 spp, two K, two ray counts; a generated mesh at 50k triangles)", false, ""},
             {"--crease-angle", "", crease_angle_help(), true, "DEG"},
             quiet_option()});
  RAYLOD_RETURN_IF_ERROR(args.parse(argc, argv));
  if (args.help_requested()) {
    std::fputs(args.help_text().c_str(), stdout);
    return {};
  }
  RAYLOD_ASSIGN_OR_RETURN(Scene scene, scene_from_args(args));

  ReportConfig cfg;
  if (args.has("--quick")) {
    // Small enough for a test: a 50k-triangle teapot (when the scene generates
    // its mesh), a thumbnail, one sample per pixel, two points per sweep.
    for (auto& obj : scene.objects)
      if (obj.generate) obj.generate->triangles = 50000;
    cfg.footprint_scales = {2, 8};
    cfg.ray_counts = {300, 1000};
    cfg.default_rays = 1000;
    cfg.default_scale = 8;
    cfg.width = 160;
    cfg.height = 120;
    cfg.spp = 1;
  }
  if (args.has("--scales")) RAYLOD_RETURN_IF_ERROR(parse_list(args.get("--scales"), "--scales", cfg.footprint_scales));
  if (args.has("--rays")) RAYLOD_RETURN_IF_ERROR(parse_list(args.get("--rays"), "--rays", cfg.ray_counts));
  RAYLOD_ASSIGN_OR_RETURN(cfg.default_scale, args.get_double("--default-scale", cfg.default_scale));
  if (!(cfg.default_scale > 0)) return Status::error("--default-scale must be positive");
  RAYLOD_ASSIGN_OR_RETURN(int64_t default_rays, args.get_int("--default-rays", int64_t(cfg.default_rays), 1, 100000000));
  cfg.default_rays = uint64_t(default_rays);
  RAYLOD_ASSIGN_OR_RETURN(int64_t spp, args.get_int("--spp", cfg.spp, 1, 4096));
  RAYLOD_ASSIGN_OR_RETURN(int64_t width, args.get_int("--width", cfg.width, 1, 32768));
  RAYLOD_ASSIGN_OR_RETURN(int64_t height, args.get_int("--height", cfg.height, 1, 32768));
  RAYLOD_ASSIGN_OR_RETURN(const MemoryBudget budget, memory_budget_from_args(args));
  cfg.memory_limit = budget.total;
  cfg.spp = int(spp);
  cfg.width = int(width);
  cfg.height = int(height);
  cfg.closeup = !args.has("--no-closeup");
  cfg.baselines = !args.has("--no-baselines");
  cfg.out_dir = args.get("--output", "raylod-report");
  if (std::find(cfg.footprint_scales.begin(), cfg.footprint_scales.end(), cfg.default_scale) == cfg.footprint_scales.end())
    cfg.footprint_scales.push_back(cfg.default_scale);
  std::optional<std::filesystem::path> mesh;
  if (args.has("--mesh")) mesh = std::filesystem::path(args.get("--mesh"));
  const bool quiet = apply_quiet(args);
  LogFn log;
  if (!quiet) log = [](const std::string& m) { std::fprintf(stderr, "raylod report: %s\n", m.c_str()); };

  RAYLOD_ASSIGN_OR_RETURN(ReportResult r, run_report(scene, mesh, cfg, log));
  for (const std::string& w : r.warnings) std::fprintf(stderr, "raylod report: warning: %s\n", w.c_str());
  summary("raylod report: wrote %s (%zu rows) and %s\n", r.markdown.string().c_str(), r.rows.size(),
              r.plot.string().c_str());
  return {};
}

int cmd_report(int argc, char** argv) {
  Status st = run_report_cmd(argc, argv);
  return st.is_ok() ? 0 : fail("report", st);
}

}  // namespace

RAYLOD_COMMAND("report", "what accuracy costs in time: K and test-ray sweeps against uniform baselines", cmd_report);

}  // namespace raylod::cli
