// views_benchmark: the two strategies of `raylod run --orbit N` compared on
// one scene (issue 11): a cut per view with cached meshes reused, against
// --shared-cut. Timings are benchmarks, never test verdicts.
//
//   views_benchmark [SCENE] [--orbit 16] [--rays 5000] [--cache DIR] [--out DIR] [--no-full] [--json FILE]
//
// Without SCENE, the embedded default scene (its 10M-triangle teapot is
// generated into --cache DIR/meshes on first use; default: raylod's cache).
// Steps, every one on the same N orbit cameras:
//   1. build (or reuse) the octree stores once (not counted in either strategy);
//   2. per view: run_views with a fresh simplified-mesh cache (DIR/views-bench-per-view);
//   3. the same again on that cache: every view a cache hit (the time of a
//      cache-hit view, the yardstick for --shared-cut);
//   4. --shared-cut with a fresh cache (DIR/views-bench-shared);
//   5. unless --no-full, the full mesh rendered from every camera, and the PSNR
//      of both strategies' images against it (image_compare.h).
// Prints a table and writes the figures as JSON (--json). Images of the first
// and last views go to --out DIR if given.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/progress.h"
#include "core/system.h"
#include "gen/generate.h"
#include "pipeline/image_compare.h"
#include "pipeline/views.h"
#include "scene/orbit.h"

using namespace raylod;
namespace fs = std::filesystem;

namespace {

struct Strategy {
  std::string name;
  ViewsResult result;
  std::vector<Image> images;
  std::vector<double> psnr;
};

StatusOr<Strategy> run_strategy(const std::string& name, const Scene& scene, const std::vector<Camera>& cameras,
                                RunOptions options, const fs::path& cache, bool fresh, bool shared) {
  if (fresh) {
    std::error_code ec;
    fs::remove_all(cache, ec);
  }
  options.cache_dir = cache;
  Strategy s;
  s.name = name;
  s.images.resize(cameras.size());
  auto keep = [&](size_t i, const RenderResult& r) -> Status {
    s.images[i] = r.color;
    return {};
  };
  std::fprintf(stderr, "views_benchmark: %s\n", name.c_str());
  RAYLOD_ASSIGN_OR_RETURN(s.result, run_views(scene, cameras, options, shared, keep, nullptr));
  return s;
}

Status run(int argc, char** argv) {
  std::string scene_path, json_path;
  fs::path cache = default_cache_dir(), out;
  int orbit = 16;
  uint64_t rays = 5000;
  bool full = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) return {};
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::printf("views_benchmark [SCENE] [--orbit 16] [--rays 5000] [--cache DIR] [--out DIR] [--no-full] [--json FILE]\n"
                  "Compares raylod run --orbit N per view (fresh cache, then all cache hits) with --shared-cut:\n"
                  "time per stage and per view, triangles, and PSNR per view against the full mesh.\n");
      std::exit(0);
    }
    if (a == "--orbit") orbit = std::atoi(value().c_str());
    else if (a == "--rays") rays = std::strtoull(value().c_str(), nullptr, 10);
    else if (a == "--cache") cache = value();
    else if (a == "--out") out = value();
    else if (a == "--json") json_path = value();
    else if (a == "--no-full") full = false;
    else if (!a.empty() && a[0] != '-') scene_path = a;
    else return Status::error("unknown option " + a + " (see the comment at the top of tools/views_benchmark.cpp)");
  }
  RAYLOD_ASSIGN_OR_RETURN(Scene scene, scene_path.empty() ? default_scene() : load_scene(scene_path));
  // Generated meshes once, into --cache: the strategies' own caches then hold
  // simplified meshes only.
  RAYLOD_RETURN_IF_ERROR(resolve_generated_meshes(scene, cache));
  for (SceneObject& o : scene.objects) o.generate.reset();
  RAYLOD_ASSIGN_OR_RETURN(std::vector<Camera> cameras, orbit_cameras(scene.camera, orbit));
  Progress::set_enabled(false);

  RunOptions options;
  options.rays = rays;
  options.progress = false;
  options.cache_limit = uint64_t(16) << 30;
  // 1. The stores, once, outside both strategies.
  {
    RunOptions build = options;
    build.use_cache = false;
    auto t = std::chrono::steady_clock::now();
    Scene copy = scene;
    RAYLOD_ASSIGN_OR_RETURN(RunSession session, open_run_session(copy, build, nullptr));
    std::fprintf(stderr, "views_benchmark: stores ready (%llu triangles, %.2f s)\n",
                 (unsigned long long)session.stores.triangles,
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count());
  }
  RAYLOD_ASSIGN_OR_RETURN(Strategy per_view, run_strategy("per view, fresh cache", scene, cameras, options,
                                                          cache / "views-bench-per-view", true, false));
  RAYLOD_ASSIGN_OR_RETURN(Strategy hits, run_strategy("per view, every view a cache hit", scene, cameras, options,
                                                      cache / "views-bench-per-view", false, false));
  RAYLOD_ASSIGN_OR_RETURN(Strategy shared, run_strategy("--shared-cut, fresh cache", scene, cameras, options,
                                                        cache / "views-bench-shared", true, true));
  std::vector<Strategy*> strategies{&per_view, &hits, &shared};

  std::vector<double> full_seconds;
  if (full) {
    for (size_t i = 0; i < cameras.size(); ++i) {
      std::fprintf(stderr, "views_benchmark: full mesh, view %zu/%zu\n", i + 1, cameras.size());
      Scene view = scene;
      view.camera = cameras[i];
      RenderOptions ro;
      ro.progress = false;
      auto t = std::chrono::steady_clock::now();
      RAYLOD_ASSIGN_OR_RETURN(RenderResult reference, render(view, ro));
      full_seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count());
      for (Strategy* s : strategies) {
        RAYLOD_ASSIGN_OR_RETURN(ImageError e, compare_images(s->images[i], reference.color));
        s->psnr.push_back(e.psnr);
      }
      if (!out.empty() && (i == 0 || i + 1 == cameras.size())) {
        fs::create_directories(out);
        const std::string n = std::to_string(i);
        RAYLOD_RETURN_IF_ERROR(write_image(out / ("full_" + n + ".png"), reference.color));
        RAYLOD_RETURN_IF_ERROR(write_image(out / ("per_view_" + n + ".png"), per_view.images[i]));
        RAYLOD_RETURN_IF_ERROR(write_image(out / ("shared_" + n + ".png"), shared.images[i]));
      }
    }
  }

  // The table.
  nlohmann::json j;
  j["views"] = cameras.size();
  j["rays"] = rays;
  j["triangles_in"] = per_view.result.triangles_in;
  std::printf("%zu-view orbit, %llu triangles, %llu test rays per view\n\n", cameras.size(),
              (unsigned long long)per_view.result.triangles_in, (unsigned long long)rays);
  std::printf("| strategy | total s | s per view | probe s | select s | simplify s | render s | triangles per view (min-max) | views reusing a mesh | PSNR dB (min / mean / max) |\n");
  std::printf("|---|---:|---:|---:|---:|---:|---:|---|---:|---|\n");
  for (const Strategy* s : strategies) {
    const ViewsResult& r = s->result;
    double probe = 0, simplify = r.shared_simplify_seconds, render = 0;
    uint64_t tmin = UINT64_MAX, tmax = 0;
    for (const ViewStats& v : r.views) {
      probe += v.probe;
      simplify += v.simplify;
      render += v.render;
      tmin = std::min(tmin, v.triangles);
      tmax = std::max(tmax, v.triangles);
    }
    double pmin = INFINITY, pmax = -INFINITY, psum = 0;
    for (double p : s->psnr) {
      pmin = std::min(pmin, p);
      pmax = std::max(pmax, p);
      psum += p;
    }
    char psnr[96] = "not measured";
    if (!s->psnr.empty()) std::snprintf(psnr, sizeof psnr, "%.2f / %.2f / %.2f", pmin, psum / double(s->psnr.size()), pmax);
    std::printf("| %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %llu-%llu | %zu | %s |\n", s->name.c_str(),
                r.total_seconds, r.seconds_per_view(), probe, r.shared_select_seconds, simplify, render,
                (unsigned long long)tmin, (unsigned long long)tmax, r.cache_reuse(), psnr);
    nlohmann::json js = nlohmann::json::parse(views_stats_json(r, options));
    nlohmann::json per = nlohmann::json::array();
    for (double p : s->psnr) per.push_back(std::isfinite(p) ? nlohmann::json(p) : nlohmann::json(nullptr));
    js["psnr_per_view"] = per;
    j[s->name] = js;
  }
  if (!full_seconds.empty()) {
    double sum = 0;
    for (double t : full_seconds) sum += t;
    std::printf("\nfull mesh: %.2f s per view (load, BVH and trace, each view on its own)\n", sum / double(full_seconds.size()));
    j["full_seconds_per_view"] = full_seconds;
  }
  std::printf("\nper view, --shared-cut %.2f s against a cache-hit view %.2f s: %.2fx\n", shared.result.seconds_per_view(),
              hits.result.seconds_per_view(), shared.result.seconds_per_view() / hits.result.seconds_per_view());
  if (!json_path.empty()) RAYLOD_RETURN_IF_ERROR(write_file_atomic(json_path, j.dump(2) + "\n"));
  return {};
}

}  // namespace

int main(int argc, char** argv) {
  Status st = run(argc, argv);
  if (!st.is_ok()) {
    std::fprintf(stderr, "views_benchmark: %s\n", st.message().c_str());
    return 1;
  }
  return 0;
}
