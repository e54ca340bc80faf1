// `raylod probe`: test rays with ray differentials against the stores of the
// scene's meshes; writes the cut that `raylod simplify` collapses.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "cli/cli.h"
#include "core/system.h"
#include "gen/generate.h"
#include "probe/probe.h"
#include "scene/scene.h"
#include "streaming/cut_file.h"
#include "streaming/octree_store.h"

namespace raylod {
namespace {

int cmd_probe(int argc, char** argv) {
  cli::Args args("probe", "[SCENE] [options]",
                 "Traces test rays with Igehy ray differentials from random positions inside random pixels against\n"
                 "the full-resolution triangles in the store of each of the scene's meshes (built first if missing\n"
                 "or stale), following reflection and refraction only where the materials call for them, and\n"
                 "marks the octree cells whose diagonal is below K times the footprint ||dP||. Writes the cut\n"
                 "beside the store as MESH.<key>.cut (key: store, camera, options). Without SCENE, the embedded\n"
                 "default scene is used.",
                 {{"--mesh", "", "use FILE in place of the scene's meshes", true, "FILE"},
                  {"--rays", "", "test rays (default 5000)", true, "N"},
                  {"--seed", "", "random seed (default: the scene's seed)", true, "S"},
                  {"--footprint-scale", "", "K: collapse cells with diagonal < K * footprint (default 1)", true, "K"},
                  {"--threads", "", "threads (default: all cores)", true, "T"},
                  {"--memory-limit", "", "memory limit (default: a quarter of physical memory)", true, "SIZE"},
                  {"--output", "-o", "cut file to write (single-mesh scenes)", true, "CUT"}});
  if (Status s = args.parse(argc, argv); !s) return cli::fail("probe", s);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  if (args.positionals().size() > 1) return cli::fail("probe", Status::error("expected at most one SCENE argument"));

  auto scene_or = args.positionals().empty() ? default_scene() : load_scene(args.positionals()[0]);
  if (!scene_or) return cli::fail("probe", scene_or.status());
  Scene scene = std::move(scene_or.value());

#if defined(__GLIBC__)
  // Evicted pages are large, short-lived buffers: a fixed mmap threshold
  // returns them to the OS instead of leaving a fragmented heap behind (glibc
  // otherwise raises the threshold after the first large free), which keeps
  // the resident size within --memory-limit.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
#endif
  ProbeConfig config;
  auto rays = args.get_int("--rays", 5000, 1, 100'000'000);
  auto seed = args.get_int("--seed", int64_t(scene.seed), 0, INT64_MAX);
  auto k = args.get_double("--footprint-scale", 1.0);
  auto threads = args.get_int("--threads", 0, 0, 1024);
  auto limit = args.get_size("--memory-limit", 0);
  for (const Status& s : {rays.status(), seed.status(), k.status(), threads.status(), limit.status()})
    if (!s) return cli::fail("probe", s);
  if (!(*k > 0)) return cli::fail("probe", Status::error("--footprint-scale must be > 0"));
  config.rays = uint64_t(*rays);
  config.seed = uint64_t(*seed);
  config.footprint_scale = *k;
  config.threads = int(*threads);
  config.progress = true;
  const uint64_t memory_limit = *limit ? *limit : physical_memory_bytes() / 4;

  if (args.has("--mesh")) {
    const std::filesystem::path mesh = args.get("--mesh");
    std::error_code ec;
    if (!std::filesystem::is_regular_file(mesh, ec))
      return cli::fail("probe", Status::error(mesh.string() + ": mesh file not found"));
    for (SceneObject& o : scene.objects) {
      o.mesh = mesh;
      o.generate.reset();
    }
  } else if (Status s = resolve_generated_meshes(scene, default_cache_dir()); !s) {
    return cli::fail("probe", s);
  }

  // One store per distinct mesh; build it if missing or stale.
  std::vector<std::filesystem::path> meshes;
  std::vector<ProbeObject> objects;
  for (const SceneObject& o : scene.objects) {
    auto it = std::find(meshes.begin(), meshes.end(), o.mesh);
    size_t index = size_t(it - meshes.begin());
    if (it == meshes.end()) meshes.push_back(o.mesh);
    objects.push_back({index, o.transform, o.material});
  }
  if (args.has("--output") && meshes.size() > 1)
    return cli::fail("probe", Status::error("-o names one cut, but the scene has " + std::to_string(meshes.size()) +
                                            " meshes; omit -o to write one cut beside each store"));
  std::vector<std::unique_ptr<OctreeStore>> opened;
  std::vector<ProbeStore> stores;
  for (const auto& mesh : meshes) {
    const std::filesystem::path store_path = default_store_path(mesh);
    // An existing store is judged by the options it was built with: the probe
    // needs it current for the mesh, not rebuilt for another memory limit.
    StoreOptions options;
    options.memory_limit = memory_limit;
    if (auto existing = OctreeStore::open(store_path); existing) options = (*existing)->header().options;
    std::string reason;
    if (!store_is_current(mesh, store_path, options, &reason)) {
      std::fprintf(stderr, "raylod probe: building the store %s (%s)\n", store_path.string().c_str(), reason.c_str());
      StoreOptions build;
      build.memory_limit = memory_limit;
      build.threads = config.threads;
      auto report = build_store(mesh, store_path, build);
      if (!report) return cli::fail("probe", report.status().with_context("building " + store_path.string()));
      std::fprintf(stderr, "raylod probe: built %s: %llu triangles in %.1f s\n", store_path.string().c_str(),
                   static_cast<unsigned long long>(report->triangles), report->seconds);
    }
    auto store = OctreeStore::open(store_path);
    if (!store) return cli::fail("probe", store.status());
    stores.push_back({store.value().get(), store_path});
    opened.push_back(std::move(store.value()));
  }

  // The page cache gets what the limit leaves after the node tables (already
  // resident) and a reserve for the test rays' hit records.
  const uint64_t rss = current_rss_bytes();
  const uint64_t reserve = config.rays * 64 * uint64_t(std::max(1, scene.max_depth + 1)) + (uint64_t(32) << 20);
  if (memory_limit <= rss + reserve)
    return cli::fail("probe", Status::error("--memory-limit " + format_bytes(memory_limit) +
                                            " is below what the stores' node tables already take (" +
                                            format_bytes(rss) + " resident)"));
  // Half of what is left: malloc fragmentation from evicted pages and the
  // pages in flight (one per thread) must fit in the rest.
  config.cache_bytes = (memory_limit - rss - reserve) / 2;

  auto result = run_probe(scene, stores, objects, config);
  if (!result) return cli::fail("probe", result.status());
  const ProbeResult& r = *result;
  auto c = [&](const char* name) {
    auto it = r.counters.find(name);
    return static_cast<unsigned long long>(it == r.counters.end() ? 0 : it->second);
  };
  std::printf("probe: %llu test rays in %.2f s (+ %.2f s for the cut): %llu primary, %llu reflection, %llu refraction "
              "(%llu total internal reflections)\n",
              static_cast<unsigned long long>(config.rays), r.trace_seconds, r.cut_seconds, c("rays_primary"),
              c("rays_reflection"), c("rays_refraction"), c("total_internal_reflections"));
  std::printf("probe: %llu hits on meshes, %llu on the ground, %llu misses, %llu with dropped differentials\n",
              c("hits"), c("hits_ground"), c("misses"), c("differentials_dropped"));
  std::printf("probe: %llu pages read (%s), cache peak %s of %s, magnification m = %.3f, peak memory %s\n",
              c("pages_read"), format_bytes(c("bytes_read")).c_str(), format_bytes(c("cache_peak_bytes")).c_str(),
              format_bytes(config.cache_bytes).c_str(), r.magnification, format_bytes(peak_rss_bytes()).c_str());
  for (size_t s = 0; s < stores.size(); ++s) {
    const Cut& cut = r.cuts[s];
    std::filesystem::path out = args.has("--output")
                                    ? std::filesystem::path(args.get("--output"))
                                    : std::filesystem::path(meshes[s].string() + "." + cut.key + ".cut");
    if (Status st = write_cut(out, cut); !st) return cli::fail("probe", st);
    std::map<uint32_t, uint64_t> per_level;
    for (const CollapsedCell& cell : cut.cells) ++per_level[cell.key.level];
    std::string levels;
    for (const auto& [level, n] : per_level) levels += " L" + std::to_string(level) + ":" + std::to_string(n);
    std::printf("probe: %s: %zu cells marked (%llu with hits;%s), smallest footprint %g\n", out.string().c_str(),
                cut.cells.size(), static_cast<unsigned long long>(cut.counters.at("cells_marked_with_hits")),
                levels.c_str(), double(cut.min_footprint));
  }
  return 0;
}

}  // namespace
}  // namespace raylod

namespace {
int run_probe_command(int argc, char** argv) { return raylod::cmd_probe(argc, argv); }
}  // namespace
RAYLOD_COMMAND("probe", "trace test rays with ray differentials and mark octree cells for collapse", run_probe_command);


