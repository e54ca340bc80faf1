// `raylod probe`: test rays with ray differentials against the stores of the
// scene's meshes; writes the cut that `raylod simplify` collapses.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <optional>

#include "cli/cli.h"
#include "core/cluster.h"
#include "core/system.h"
#include "pipeline/pipeline.h"
#include "geometry/optics.h"
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
                 "marks the octree cells whose collapse no ray can resolve (--criterion). Writes the cut\n"
                 "beside the store as MESH.<key>.cut (key: store, camera, options). Without SCENE, the embedded\n"
                 "default scene is used.",
                 cli::with_cut_options({{"--mesh", "", "use FILE in place of the scene's first object's mesh", true, "FILE"},
                  {"--rays", "", "test rays (default 5000)", true, "N"},
                  {"--seed", "", "random seed (default: the scene's seed)", true, "S"},
                  cli::threads_option(),
                  {"--memory-limit", "", "memory limit (default: a quarter of physical memory)", true, "SIZE"},
                  {"--output", "-o", "cut file to write (single-mesh scenes)", true, "CUT"},
                  cli::quiet_option()}));
  // Under mpirun the test rays are split across the ranks; rank 0 writes the cut.
  cluster::enlist();
  if (Status s = args.parse(argc, argv); !s) return cli::fail("probe", s);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  auto cut_opts = cli::cut_options_from_args(args);
  if (!cut_opts) return cli::fail("probe", cut_opts.status());
  auto scene_or = cli::scene_from_args(args);
  if (!scene_or) return cli::fail("probe", scene_or.status());
  Scene scene = std::move(scene_or.value());
  cut_opts->fit_defaults_to(scene.spp);  // the cut `raylod run` makes for the scene's spp

  auto rays = args.get_int("--rays", 5000, 1, 100'000'000);
  auto seed = args.get_int("--seed", int64_t(scene.seed), 0, INT64_MAX);
  auto limit = memory_budget_from_args(args);
  for (const Status& s : {rays.status(), seed.status(), limit.status()})
    if (!s) return cli::fail("probe", s);

  const bool quiet = cli::apply_quiet(args);
  // The cut's name is checked before the stores are built.
  if (args.has("--output"))
    if (Status s = cluster::agree(check_output_path(args.get("--output"), "the cut (-o)")); !s)
      return cli::fail("probe", s);
  // One store per distinct mesh, built first if missing or stale (saying so).
  const MemoryBudget budget = *limit;
  StoreOptions store_options;
  store_options.memory_limit = budget.total;
  std::optional<std::filesystem::path> mesh_override;
  if (args.has("--mesh")) mesh_override = std::filesystem::path(args.get("--mesh"));
  StatusOr<SceneStores> prepared = Status::error("the stores were not prepared");
  const Status built = cluster::rank0_first([&] {
    prepared = prepare_scene_stores(scene, mesh_override, store_options, default_cache_dir(),
                                    [&](const std::string& m) {
                                      if (!quiet) std::fprintf(stderr, "raylod probe: %s\n", m.c_str());
                                    });
    return prepared.status();
  });
  if (!built) return cli::fail("probe", built);
  const SceneStores& ss = *prepared;
  const std::vector<std::filesystem::path>& meshes = ss.meshes;
  const std::vector<ProbeStore>& stores = ss.probe_stores;
  const std::vector<ProbeObject>& objects = ss.objects;
  // Objects beyond the float range are refused, odd sizes warned about, as
  // run and render do.
  std::vector<std::string> warnings;
  if (Status s = cluster::agree(check_object_placements(scene, ss, warnings)); !s) return cli::fail("probe", s);
  if (cluster::is_root())
    for (const std::string& w : warnings) std::fprintf(stderr, "raylod probe: warning: %s\n", w.c_str());
  if (args.has("--output") && meshes.size() > 1)
    return cli::fail("probe", cluster::agree(Status::error("-o names one cut, but the scene has " +
                                                           std::to_string(meshes.size()) +
                                                           " meshes; omit -o to write one cut beside each store")));

  if (args.has("--output")) {
    std::vector<FileRole> inputs = cli::scene_input_files(args, scene);
    for (const auto& store : ss.store_paths) inputs.push_back({store, "the store " + store.string()});
    if (Status s = cluster::agree(check_outputs_apart({{args.get("--output"), "the cut (-o)"}}, inputs)); !s)
      return cli::fail("probe", s);
  }
  // Without -o each cut goes beside its store, named after the mesh; where
  // that folder takes no files (a store reused in a read-only folder), into
  // the cache's store folder: decided before any ray is traced.
  std::vector<std::filesystem::path> cut_dirs;
  if (!args.has("--output")) {
    Status where = Status::ok();
    if (cluster::is_root())
      for (const std::filesystem::path& store : ss.store_paths) {
        std::filesystem::path dir = std::filesystem::absolute(store).parent_path();
        if (!folder_is_writable(dir)) {
          const std::filesystem::path in_cache = default_cache_dir() / "stores";
          if (!cache_store_folder_is_writable(default_cache_dir())) {
            where = Status::error("neither " + dir.string() + " (beside the store) nor " + in_cache.string() +
                                  " takes files: give the cut's name with -o CUT");
            break;
          }
          if (!quiet)
            std::fprintf(stderr, "raylod probe: %s is not writable: the cut goes to %s\n", dir.c_str(), in_cache.c_str());
          dir = in_cache;
        }
        cut_dirs.push_back(dir);
      }
    if (Status s = cluster::agree(where); !s) return cli::fail("probe", s);
  }
  auto config_or = make_probe_config(scene, uint64_t(*rays), cut_opts->footprint_scale, budget, !quiet);
  if (Status s = cluster::agree(config_or.status()); !s) return cli::fail("probe", s);
  ProbeConfig config = *config_or;
  config.seed = uint64_t(*seed);
  config.criterion = cut_opts->criterion;
  config.tolerance_px = cut_opts->tolerance_px;
  config.angle_tolerance_px = cut_opts->angle_tolerance_px;
  config.outline_tolerance = cut_opts->outline_tolerance;
  config.unreached_angle_allowance = cut_opts->unreached_angle_allowance;
  config.balance = cut_opts->balance;
  config.unseen_cells = cut_opts->unseen_cells;
  config.shadow_receivers = cut_opts->shadow_receivers;

  auto traced = trace_probe_across_ranks(scene, stores, objects, config);
  if (!traced) return cli::fail("probe", traced.status());
  auto result = select_cuts(*traced, scene, stores, objects, config);
  if (Status s = cluster::agree(result.status()); !s) return cli::fail("probe", s);
  // Every rank has the same cuts; rank 0 writes them, the others wait to
  // learn whether it could.
  auto write_cuts = [&]() -> Status {
    const ProbeResult& r = *result;
    auto c = [&](const char* name) {
      auto it = r.counters.find(name);
      return static_cast<unsigned long long>(it == r.counters.end() ? 0 : it->second);
    };
    cli::summary("probe: %llu test rays in %.2f s (+ %.2f s for the cut): %llu primary, %llu reflection, %llu refraction "
        "(%llu total internal reflections; %llu not followed, as the renderer traces no ray of throughput "
        "below %g)\n",
        static_cast<unsigned long long>(config.rays), r.trace_seconds, r.cut_seconds, c("rays_primary"),
        c("rays_reflection"), c("rays_refraction"), c("total_internal_reflections"), c("rays_pruned"),
        double(kMinThroughput));
    cli::summary("probe: %llu hits on meshes, %llu on the ground, %llu misses, %llu with dropped differentials\n",
        c("hits"), c("hits_ground"), c("misses"), c("differentials_dropped"));
    cli::summary("probe: %llu pages read (%s), cache peak %s of %s, magnification m = %.3f, peak memory %s\n",
        c("pages_read"), format_bytes(c("bytes_read")).c_str(), format_bytes(c("cache_peak_bytes")).c_str(),
        format_bytes(config.cache_bytes).c_str(), r.magnification, format_bytes(peak_rss_bytes()).c_str());
    for (size_t s = 0; s < stores.size(); ++s) {
      // With what `raylod run` would simplify it, for `raylod simplify` by hand.
      Cut cut = r.cuts[s];
      record_simplify_settings(cut, scene, objects, s);
      std::filesystem::path out = args.has("--output")
                                      ? std::filesystem::path(args.get("--output"))
                                      : cut_dirs[s] / (temporary_stem(meshes[s].filename().string()) + "." +
                                                       cut.key + ".cut");
      RAYLOD_RETURN_IF_ERROR(write_cut(out, cut));
      std::map<uint32_t, uint64_t> per_level;
      for (const CollapsedCell& cell : cut.cells) ++per_level[cell.key.level];
      std::string levels;
      for (const auto& [level, n] : per_level) levels += " L" + std::to_string(level) + ":" + std::to_string(n);
      auto count = [&](const char* name) {
        auto it = cut.counters.find(name);
        return static_cast<unsigned long long>(it == cut.counters.end() ? 0 : it->second);
      };
      const std::string graded = cut.counters.count("cells_split_to_balance")
                                     ? "; graded, " + std::to_string(count("cells_split_to_balance")) + " cells split"
                                     : "";
      cli::summary("probe: %s: %zu cells marked (%llu with hits;%s)%s, smallest footprint %g\n", out.string().c_str(),
          cut.cells.size(), static_cast<unsigned long long>(cut.counters.at("cells_marked_with_hits")),
          levels.c_str(), graded.c_str(), double(cut.min_footprint));
      // Why finest cells stay whole: their input triangles are kept as they are.
      if (count("finest_cells_kept") > 0)
        cli::summary("probe: %llu finest cells kept whole (for K %llu, deviation %llu, normals %llu, open boundary %llu, "
            "fold %llu, crease %llu, far-end normal %llu)\n",
            count("finest_cells_kept"), count("finest_cells_kept_for_k"), count("finest_cells_kept_for_deviation"),
            count("finest_cells_kept_for_normals"), count("finest_cells_kept_for_boundary"),
            count("finest_cells_kept_for_fold"), count("finest_cells_kept_for_crease"),
            count("finest_cells_kept_for_far_normal"));
      if (cut.counters.count("curvature_factor_ppm"))
        cli::summary("probe: unreached curved cells take a tilt of c kappa f, c = %g (the least over the views; 0: the flat "
            "mirror's bound alone)\n",
            1e-6 * double(count("curvature_factor_ppm")));
    }
    return {};
  };
  if (Status s = cluster::agree(cluster::is_root() ? write_cuts() : Status::ok()); !s) return cli::fail("probe", s);
  return 0;
}

}  // namespace
}  // namespace raylod

namespace {
int run_probe_command(int argc, char** argv) { return raylod::cmd_probe(argc, argv); }
}  // namespace
RAYLOD_COMMAND("probe", "trace test rays with ray differentials and mark octree cells for collapse", run_probe_command);


