// `raylod report`: what accuracy costs in time (in the spirit of the paper's
// Table 1 and Figure 4). For each scene: a reference render of the full
// mesh; raylod at a sweep of footprint scales K and test-ray counts; and the
// two uniform baselines (baselines.h) at the same triangle counts, all
// rendered the same way and compared with the reference. Each view also gets
// its noise floor (noise_floor.h): the errors are read against it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/status.h"
#include "pipeline/image_compare.h"
#include "pipeline/noise_floor.h"
#include "pipeline/pipeline.h"
#include "scene/scene.h"

namespace raylod {

struct ReportConfig {
  std::vector<double> footprint_scales{4, 8, 16, 32, 64};  // deviation criterion, swept at default_rays
  std::vector<double> diagonal_scales{4, 10};              // the paper's diagonal criterion, for comparison
  std::vector<uint64_t> ray_counts{500, 5000, 50000};      // swept at default_scale
  uint64_t default_rays = 5000;
  double default_scale = kDefaultFootprintScale;
  bool baselines = true;
  bool closeup = true;         // add a close-up view of the same mesh
  int spp = 0;                 // 0 = the scene's
  int width = 0, height = 0;   // 0 = the scene's
  uint64_t memory_limit = 0;   // bytes for the whole report (memory_budget.h); 0 = no limit
  std::filesystem::path out_dir = "raylod-report";
  std::filesystem::path cache_dir;  // for generated meshes and stores of generated meshes
  bool progress = false;
};

struct ReportRow {
  std::string scene;           // "default", "close-up"
  std::string method;          // "raylod", "raylod (diagonal)", "vertex clustering", "edge collapse", "full mesh"
  double footprint_scale = 0;  // raylod only
  uint64_t rays = 0;           // raylod only
  uint64_t triangles = 0;
  double probe_s = 0, simplify_s = 0, render_s = 0;  // render includes load and BVH
  double total_s = 0;          // probe + simplify + render (baselines: load + simplify + render)
  uint64_t drc_bytes = 0;      // raylod only
  uint64_t memory_bytes = 0;   // baselines: loaded mesh + simplifier peak; raylod: process peak
  ImageError error;
  std::string image;           // file name in out_dir (rendered image), if kept
  std::string diff_image;
};

// A view of the report ("default", "close-up") and its noise floor.
struct ReportView {
  std::string scene;
  NoiseFloor noise_floor;
};

struct ReportResult {
  std::vector<ReportRow> rows;
  std::vector<ReportView> views;
  std::filesystem::path markdown, plot;
  std::vector<std::string> warnings;  // printed whatever the log level
};

// Runs the sweep on scene (with mesh_override in place of its first
// object's mesh) and, if config.closeup, on a close-up view of it; writes
// images, REPORT.md, report.json and the accuracy-versus-time plot to out_dir.
// The folder is written whole or not at all: the files go to a temporary
// folder beside it (AtomicDirectory), which replaces it once complete. An
// existing out_dir must be empty or an earlier report (which is replaced,
// none of its files kept); one that holds other files is refused before any
// work. Its parent folder must exist. In report.json an image identical to
// the reference has "psnr": null and "identical": true.
StatusOr<ReportResult> run_report(const Scene& scene, const std::optional<std::filesystem::path>& mesh_override,
                                  const ReportConfig& config, const LogFn& log);

// The close-up view used by the report: the eye moved to a quarter of its
// distance from the look-at point and the field of view narrowed, so that
// most of the model is off-screen.
Scene closeup_scene(const Scene& scene);

}  // namespace raylod
