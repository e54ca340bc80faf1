// `raylod run --views FILE | --orbit N`: the pipeline for a sequence of
// cameras. The stores are built once. Per view (the default), each view is
// probed, its cut simplified or a cached mesh reused under the cache's rule
// (simplified_cache.h), and rendered. With shared_cut, every view's test rays
// are traced, one cut is selected with the finest need over all views
// (select_shared_cuts), simplified once, and every view is rendered from that
// one set of meshes.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "pipeline/pipeline.h"

namespace raylod {

struct ViewStats {
  Camera camera;
  uint64_t triangles = 0;     // rendered (the shared mesh's with shared_cut)
  bool cache_hit = false;     // every mesh of this view came from the cache (shared_cut: the shared meshes did)
  std::vector<std::string> cache_notes;  // one per store
  double footprint_scale = 1;
  int coarsening_steps = 0;
  // Seconds: probe = this view's trace (and, per view, its cut); simplify =
  // this view's simplify or cache look-up (0 with shared_cut: see ViewsResult).
  double probe = 0, simplify = 0, render = 0;
  double total() const { return probe + simplify + render; }
  RenderStats render_stats;
  std::string render_json;  // a view rendered on another rank: its render_stats as JSON (render_stats unset)
  int rank = 0;               // the MPI rank that rendered it (0 in one process)
};

struct ViewsResult {
  std::vector<ViewStats> views;
  bool shared_cut = false;
  uint64_t triangles_in = 0;
  double build_seconds = 0;
  // shared_cut: selecting the one cut over all traces, and simplifying it (or
  // reusing a cached mesh); the meshes every view was rendered from.
  double shared_select_seconds = 0, shared_simplify_seconds = 0;
  std::vector<SimplifiedMesh> shared_meshes;
  std::vector<Cut> shared_cuts;
  int ranks = 1;              // MPI ranks the views were spread over (core/cluster.h)
  bool dynamic_handout = true;  // views handed out one at a time (else round robin)
  double total_seconds = 0;   // wall clock, build included
  uint64_t peak_rss = 0;
  std::vector<std::string> warnings;

  // Views rendered from cached meshes (per view: cache hits; shared_cut: the
  // views after the first, which reuse the shared meshes, plus the first if
  // those came from the cache).
  size_t cache_reuse() const;
  double seconds_per_view() const { return views.empty() ? 0 : total_seconds / double(views.size()); }
};

// Called once per view as soon as it is rendered (the image is not kept):
// its color, linear, or 8-bit sRGB with RunOptions::srgb_color.
using ViewImageFn = std::function<Status(size_t view, const RenderResult& render)>;

StatusOr<ViewsResult> run_views(Scene scene, std::span<const Camera> cameras, const RunOptions& options,
                                bool shared_cut, const ViewImageFn& on_image, const LogFn& log);

// JSON for --stats-json: a "views" array (per view: camera, triangles, cache
// hit, seconds per stage, render statistics) and a "summary".
std::string views_stats_json(const ViewsResult& result, const RunOptions& options);

// The image of view `index` for an output pattern: the last run of '#' in the
// file name is replaced by the index, zero-padded to the run's length
// ("out_####.png", 7 -> "out_0007.png"); a name without '#' gets "_####"
// before its extension ("out.png" -> "out_0007.png").
std::filesystem::path numbered_image_path(const std::filesystem::path& pattern, size_t index);

}  // namespace raylod
