// Library calls with a memory limit of 0 run without a limit (memory_budget.h):
// the pipeline neither coarsens the cut nor bounds the page cache, and the
// store it builds records no limit.
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/progress.h"
#include "pipeline/pipeline.h"
#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

const char* kScene = R"({
  "camera": {"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0.0], "fov_y": 34, "width": 48, "height": 36},
  "materials": {"m": {"type": "diffuse", "color": [0.7, 0.2, 0.1]}},
  "objects": [{"mesh": {"generate": "teapot", "triangles": 20000}, "material": "m"}],
  "lights": [{"type": "point", "position": [6, 10, 6], "intensity": 160}],
  "background": [0.6, 0.7, 0.85], "spp": 1, "seed": 1})";

TEST(NoMemoryLimit, ProbeConfigHasAnUnboundedPageCache) {
  auto scene = parse_scene(kScene, ".", "scene.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  auto probe = make_probe_config(*scene, 1000, 32, MemoryBudget::of(0), false);
  ASSERT_TRUE(probe.is_ok()) << probe.status().message();
  EXPECT_EQ(probe->cache_bytes, UINT64_MAX);
  // Under a limit below what is resident, nothing is left: an error, not "no limit".
  EXPECT_FALSE(make_probe_config(*scene, 1000, 32, MemoryBudget::of(1), false).is_ok());
}

TEST(NoMemoryLimit, RunPipelineWithZeroRunsUnlimited) {
  Progress::set_enabled(false);
  const fs::path dir = test::scratch_dir("no-memory-limit");
  auto scene = parse_scene(kScene, dir, "scene.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  RunOptions options;
  options.memory_limit = 0;
  options.rays = 200;
  options.cache_dir = dir;
  options.use_cache = false;
  options.progress = false;
  auto result = run_pipeline(*scene, options, nullptr);
  ASSERT_TRUE(result.is_ok()) << result.status().message();
  EXPECT_EQ(result->coarsening_steps, 0);
  EXPECT_GT(result->triangles_out, 0u);
  ASSERT_EQ(result->probe.cuts.size(), 1u);
  auto store = OctreeStore::open(result->probe.cuts[0].store_path);
  ASSERT_TRUE(store.is_ok()) << store.status().message();
  EXPECT_EQ((*store)->header().options.memory_limit, 0u);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace raylod
