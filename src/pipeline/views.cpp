#include "pipeline/views.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <optional>
#include <set>

#include <nlohmann/json.hpp>

#include "core/cluster.h"
#include "core/progress.h"
#include "core/system.h"

namespace raylod {
namespace fs = std::filesystem;

namespace {

Scene with_camera(const Scene& scene, const Camera& camera) {
  Scene s = scene;
  s.camera = camera;
  return s;
}

// The angle of one pixel (what shading_normal_tolerance uses on mirrors and glass).
double pixel_angle(const Camera& c) { return 2.0 * std::tan(glm::radians(c.fov_y_deg) / 2) / c.height; }

// Renders view i from `meshes`, hands the image over, fills its statistics.
Status render_view(RunSession& session, const Scene& scene, const Camera& camera, std::span<const SimplifiedMesh> meshes,
                   const RunOptions& options, size_t i, const ViewImageFn& on_image, const LogFn& log, ViewStats& stats) {
  auto t = std::chrono::steady_clock::now();
  RAYLOD_ASSIGN_OR_RETURN(RenderResult r, render_simplified(with_camera(scene, camera), session.stores.objects, meshes,
                                                            options, session.memory_limit, log));
  stats.render = seconds_since(t);
  stats.render_stats = r.stats;
  if (on_image) RAYLOD_RETURN_IF_ERROR(on_image(i, r));
  return {};
}

void free_probe_memory(RunSession& session) {
  session.pages.reset();
  session.stores.probe_stores.clear();
  session.stores.stores.clear();
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

// The order in which views are handed out to ranks: the costliest expected
// first (most pixels; ties in view order), so that the last views handed out
// are short and the ranks finish together. One process renders in view order.
std::vector<size_t> handout_order(std::span<const ViewStats> views) {
  std::vector<size_t> order(views.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  if (!cluster::active()) return order;
  auto pixels = [&](size_t i) { return uint64_t(views[i].camera.width) * uint64_t(views[i].camera.height); };
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return pixels(a) > pixels(b); });
  return order;
}

// Renders the views the work queue hands this rank (every view, in order, on
// one process), stopping at the first failure; then the ranks agree.
Status for_each_view(const std::function<Status(size_t)>& view, std::optional<Progress>& progress,
                     std::vector<size_t>& done, ViewsResult& out) {
  Status failed;
  const std::vector<size_t> order = handout_order(out.views);
  {
    cluster::WorkQueue queue(order.size());
    out.ranks = cluster::size();
    out.dynamic_handout = queue.dynamic() || !cluster::active();
    while (const std::optional<uint64_t> next = queue.next()) {
      const size_t i = order[size_t(*next)];
      out.views[i].rank = cluster::rank();
      failed = view(i);
      if (!failed) {
        queue.stop();
        break;
      }
      done.push_back(i);
      if (progress) progress->advance(1);
    }
  }
  return cluster::agree(failed);
}

// Under mpirun: the statistics of the views the other ranks rendered, their
// warnings and peak memory, onto rank 0 (as JSON).
void gather_view_stats(ViewsResult& out, const std::vector<size_t>& mine) {
  if (!cluster::active()) return;
  using nlohmann::json;
  json j = {{"views", json::array()}, {"warnings", out.warnings}, {"peak_rss", out.peak_rss}};
  for (size_t i : mine) {
    const ViewStats& v = out.views[i];
    j["views"].push_back({{"index", i}, {"rank", v.rank}, {"triangles", v.triangles}, {"cache_hit", v.cache_hit},
                          {"cache_notes", v.cache_notes}, {"footprint_scale", v.footprint_scale},
                          {"coarsening_steps", v.coarsening_steps}, {"probe", v.probe}, {"simplify", v.simplify},
                          {"render", v.render}, {"render_stats", render_stats_json(v.render_stats)}});
  }
  const std::vector<std::string> parts = cluster::gather(j.dump());
  for (size_t r = 1; r < parts.size(); ++r) {
    const json p = json::parse(parts[r]);
    for (const json& e : p["views"]) {
      ViewStats& v = out.views.at(e["index"].get<size_t>());
      e["rank"].get_to(v.rank);
      e["triangles"].get_to(v.triangles);
      e["cache_hit"].get_to(v.cache_hit);
      e["cache_notes"].get_to(v.cache_notes);
      e["footprint_scale"].get_to(v.footprint_scale);
      e["coarsening_steps"].get_to(v.coarsening_steps);
      e["probe"].get_to(v.probe);
      e["simplify"].get_to(v.simplify);
      e["render"].get_to(v.render);
      v.render_json = e["render_stats"].get<std::string>();
    }
    for (const json& w : p["warnings"])
      if (std::find(out.warnings.begin(), out.warnings.end(), w.get<std::string>()) == out.warnings.end())
        out.warnings.push_back(w.get<std::string>());
    out.peak_rss = std::max(out.peak_rss, p["peak_rss"].get<uint64_t>());
  }
}

}  // namespace

size_t ViewsResult::cache_reuse() const {
  if (shared_cut) {
    bool hit = !shared_meshes.empty() && std::all_of(shared_meshes.begin(), shared_meshes.end(),
                                                     [](const SimplifiedMesh& m) { return m.cache_hit || m.triangles == 0; });
    return views.empty() ? 0 : views.size() - 1 + (hit ? 1 : 0);
  }
  return size_t(std::count_if(views.begin(), views.end(), [](const ViewStats& v) { return v.cache_hit; }));
}

StatusOr<ViewsResult> run_views(Scene scene, std::span<const Camera> cameras, const RunOptions& options,
                                bool shared_cut, const ViewImageFn& on_image, const LogFn& log) {
  if (cameras.empty()) return Status::error("no views to render");
  const auto t_start = std::chrono::steady_clock::now();
  ViewsResult out;
  out.shared_cut = shared_cut;
  out.views.resize(cameras.size());
  for (size_t i = 0; i < cameras.size(); ++i) out.views[i].camera = cameras[i];
  // One progress display, for the views; the stages stay silent.
  RunOptions inner = options;
  inner.progress = false;
  RAYLOD_ASSIGN_OR_RETURN(RunSession session, open_run_session(scene, inner, log));
  keep_pages_between_views(session);
  out.build_seconds = session.stores.seconds;
  out.triangles_in = session.stores.triangles;
  std::optional<Progress> progress;
  if (options.progress) progress.emplace("views", cameras.size(), "views");
  const std::string of = "/" + std::to_string(cameras.size());
  std::vector<size_t> mine;  // the views this rank rendered

  if (!shared_cut) {
    // A view reuses only what the cache held before the run (or the mesh of
    // its own cut): its image does not depend on the views before it, nor on
    // how the views are spread over ranks.
    session.reusable = std::set<std::string>();
    std::string keys;
    if (cluster::is_root() && session.cache)
      for (const CacheEntry& e : session.cache->entries()) keys += e.key + "\n";
    cluster::broadcast(keys);
    for (size_t at = 0, nl; (nl = keys.find('\n', at)) != std::string::npos; at = nl + 1)
      session.reusable->insert(keys.substr(at, nl - at));
    auto one_view = [&](size_t i) -> Status {
      ViewStats& v = out.views[i];
      const Scene view_scene = with_camera(scene, cameras[i]);
      say(log, "view " + std::to_string(i + 1) + of + ": probe, " + std::to_string(options.rays) + " test rays");
      auto t = std::chrono::steady_clock::now();
      RAYLOD_ASSIGN_OR_RETURN(ProbeConfig probe, run_probe_config(session, view_scene, inner));
      RAYLOD_ASSIGN_OR_RETURN(ProbeTrace trace, trace_view(session, view_scene, probe, log));
      const ProbeView view{&trace, cameras[i]};
      RAYLOD_ASSIGN_OR_RETURN(FittedCuts fitted, select_fitting_cuts(session, std::span<const ProbeView>(&view, 1),
                                                                     view_scene, probe, inner, log));
      v.probe = seconds_since(t);
      v.footprint_scale = fitted.footprint_scale;
      v.coarsening_steps = fitted.coarsening_steps;
      t = std::chrono::steady_clock::now();
      RAYLOD_ASSIGN_OR_RETURN(StagedMeshes staged, simplify_or_reuse(session, view_scene, fitted.probe.cuts, inner, log));
      v.simplify = seconds_since(t);
      v.triangles = staged.triangles;
      v.cache_hit = staged.cache_hit;
      for (const SimplifiedMesh& m : staged.meshes) v.cache_notes.push_back(m.cache_note);
      return render_view(session, scene, cameras[i], staged.meshes, inner, i, on_image, log, v);
    };
    RAYLOD_RETURN_IF_ERROR(for_each_view(one_view, progress, mine, out));
  } else {
    // Every view's test rays (the views dealt to the ranks), then one cut
    // over all of them, the same on every rank.
    auto probe_config = run_probe_config(session, scene, inner);
    RAYLOD_RETURN_IF_ERROR(cluster::agree(probe_config.status()));
    const ProbeConfig probe = probe_config.value();
    RAYLOD_ASSIGN_OR_RETURN(std::vector<ProbeTrace> traces, trace_views_across_ranks(session, scene, cameras, probe, log));
    shrink_kept_pages(session);
    for (size_t i = 0; i < cameras.size(); ++i) out.views[i].probe = traces[i].trace_seconds;
    std::vector<ProbeView> views;
    for (size_t i = 0; i < cameras.size(); ++i) views.push_back(ProbeView{&traces[i], cameras[i]});
    say(log, "shared cut: the finest need over " + std::to_string(cameras.size()) + " views");
    auto t = std::chrono::steady_clock::now();
    auto selected = select_fitting_cuts(session, views, scene, probe, inner, log);
    RAYLOD_RETURN_IF_ERROR(cluster::agree(selected.status()));
    const FittedCuts fitted = std::move(selected.value());
    out.shared_select_seconds = seconds_since(t);
    out.shared_cuts = fitted.probe.cuts;
    // The shading normals' tolerance follows the finest pixel of all views.
    const Camera* finest = &cameras[0];
    for (const Camera& c : cameras)
      if (pixel_angle(c) < pixel_angle(*finest)) finest = &c;
    t = std::chrono::steady_clock::now();
    RAYLOD_ASSIGN_OR_RETURN(StagedMeshes staged, simplify_or_reuse_on_ranks(session, with_camera(scene, *finest),
                                                                          fitted.probe.cuts, inner, log));
    out.shared_simplify_seconds = seconds_since(t);
    out.shared_meshes = staged.meshes;
    // The render gets the memory of the stores' node tables and the traces.
    views.clear();
    traces.clear();
    free_probe_memory(session);
    auto one_view = [&](size_t i) -> Status {
      ViewStats& v = out.views[i];
      v.footprint_scale = fitted.footprint_scale;
      v.coarsening_steps = fitted.coarsening_steps;
      v.triangles = staged.triangles;
      v.cache_hit = staged.cache_hit;
      for (const SimplifiedMesh& m : staged.meshes) v.cache_notes.push_back(m.cache_note);
      say(log, "view " + std::to_string(i + 1) + of + ": render");
      return render_view(session, scene, cameras[i], staged.meshes, inner, i, on_image, log, v);
    };
    RAYLOD_RETURN_IF_ERROR(for_each_view(one_view, progress, mine, out));
  }
  if (progress) progress->finish();
  out.peak_rss = peak_rss_bytes();
  out.warnings = session.warnings;
  gather_view_stats(out, mine);
  out.total_seconds = seconds_since(t_start);
  return out;
}

std::string views_stats_json(const ViewsResult& r, const RunOptions& options) {
  using nlohmann::json;
  auto vec = [](const Vec3d& v) { return json::array({v.x, v.y, v.z}); };
  json views = json::array();
  double probe = 0, simplify = 0, render = 0;
  uint64_t tri_min = UINT64_MAX, tri_max = 0, tri_sum = 0;
  for (size_t i = 0; i < r.views.size(); ++i) {
    const ViewStats& v = r.views[i];
    const Camera& c = v.camera;
    probe += v.probe;
    simplify += v.simplify;
    render += v.render;
    tri_min = std::min(tri_min, v.triangles);
    tri_max = std::max(tri_max, v.triangles);
    tri_sum += v.triangles;
    views.push_back({{"index", i},
                     {"rank", v.rank},
                     {"camera", {{"eye", vec(c.eye)}, {"look_at", vec(c.look_at)}, {"up", vec(c.up)},
                                 {"fov_y", c.fov_y_deg}, {"width", c.width}, {"height", c.height}}},
                     {"triangles", v.triangles},
                     {"reduction", v.triangles ? double(r.triangles_in) / double(v.triangles) : 0.0},
                     {"cache_hit", v.cache_hit},
                     {"cache_notes", v.cache_notes},
                     {"footprint_scale", v.footprint_scale},
                     {"coarsening_steps", v.coarsening_steps},
                     {"seconds", {{"probe", v.probe}, {"simplify", v.simplify}, {"render", v.render}, {"total", v.total()}}},
                     {"render", json::parse(v.render_json.empty() ? render_stats_json(v.render_stats)
                                                                        : v.render_json)}});
  }
  const size_t n = r.views.size();
  json j;
  j["mode"] = r.shared_cut ? "shared_cut" : "per_view";
  j["ranks"] = r.ranks;
  j["view_handout"] = r.ranks == 1 ? "in order" : r.dynamic_handout ? "dynamic" : "round robin";
  j["triangles_in"] = r.triangles_in;
  j["rays"] = options.rays;
  j["footprint_scale_requested"] = options.footprint_scale;
  j["views"] = views;
  if (r.shared_cut) {
    json meshes = json::array();
    uint64_t triangles = 0;
    for (const SimplifiedMesh& m : r.shared_meshes) {
      triangles += m.triangles;
      meshes.push_back({{"triangles", m.triangles}, {"drc_bytes", m.drc_bytes}, {"cache_hit", m.cache_hit},
                        {"cache_note", m.cache_note}});
    }
    uint64_t cells = 0;
    for (const Cut& c : r.shared_cuts) cells += c.cells.size();
    j["shared"] = {{"triangles", triangles}, {"cells_marked", cells}, {"meshes", meshes},
                   {"seconds", {{"select", r.shared_select_seconds}, {"simplify", r.shared_simplify_seconds}}}};
  }
  j["summary"] = {{"views", n},
                  {"total_seconds", r.total_seconds},
                  {"seconds_per_view", r.seconds_per_view()},
                  {"build_seconds", r.build_seconds},
                  {"seconds", {{"probe", probe},
                               {"select", r.shared_select_seconds},
                               {"simplify", simplify + r.shared_simplify_seconds},
                               {"render", render}}},
                  {"cache_reuse", r.cache_reuse()},
                  {"triangles_per_view", {{"min", n ? tri_min : 0}, {"max", tri_max},
                                          {"mean", n ? double(tri_sum) / double(n) : 0.0}}}};
  j["peak_rss_bytes"] = r.peak_rss;
  j["warnings"] = r.warnings;
  return j.dump(2) + "\n";
}

fs::path numbered_image_path(const fs::path& pattern, size_t index) {
  std::string name = pattern.filename().string();
  const size_t last = name.find_last_of('#');
  if (last == std::string::npos) {
    const std::string stem = pattern.stem().string(), ext = pattern.extension().string();
    name = stem + "_####" + ext;
    return numbered_image_path(pattern.parent_path() / name, index);
  }
  size_t first = last;
  while (first > 0 && name[first - 1] == '#') --first;
  std::string digits = std::to_string(index);
  const size_t width = last - first + 1;
  if (digits.size() < width) digits.insert(0, width - digits.size(), '0');
  name.replace(first, width, digits);
  return pattern.parent_path() / name;
}

}  // namespace raylod
