// Stores found corrupt are repaired by the run itself, and concurrent runs of
// a scene with a generated mesh share one mesh and one store.
#include <atomic>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "file_damage.h"

#include "core/progress.h"
#include "pipeline/pipeline.h"
#include "pipeline/simplified_cache.h"
#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// This test's scratch directory, emptied first and removed when the test ends.
struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name) : dir(test::scratch_dir("store-repair-" + name)) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

const char* kScene = R"({
  "camera": {"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0.0], "fov_y": 34, "width": 48, "height": 36},
  "materials": {"m": {"type": "diffuse", "color": [0.7, 0.2, 0.1]}},
  "objects": [{"mesh": {"generate": "teapot", "triangles": 20000}, "material": "m"}],
  "lights": [{"type": "point", "position": [6, 10, 6], "intensity": 160}],
  "background": [0.6, 0.7, 0.85], "spp": 1, "seed": 1})";

Scene small_scene(const fs::path& dir) {
  auto scene = parse_scene(kScene, dir, "scene.json");
  EXPECT_TRUE(scene.is_ok()) << scene.status().message();
  return scene.is_ok() ? *scene : Scene{};
}

StoreOptions small_store_options() {
  StoreOptions o;
  o.memory_limit = uint64_t(1) << 30;
  return o;
}

struct Log {
  std::mutex mutex;
  std::string text;
  LogFn fn() {
    return [this](const std::string& line) {
      std::lock_guard lock(mutex);
      text += line + "\n";
    };
  }
};

using test::flip_byte;

// Builds the scene's store in `cache`, returns its path.
fs::path prepare(const fs::path& cache) {
  Scene scene = small_scene(cache);
  auto stores = prepare_scene_stores(scene, std::nullopt, small_store_options(), cache, nullptr);
  EXPECT_TRUE(stores.is_ok()) << stores.status().message();
  return stores.is_ok() ? stores->store_paths.at(0) : fs::path();
}

TEST(StoreRepair, RunRebuildsAStoreRecordedCorrupt) {
  Progress::set_enabled(false);
  Scratch s("recorded");
  const fs::path store = prepare(s.dir);
  ASSERT_FALSE(store.empty());
  ASSERT_TRUE(record_store_corruption(store, "page 0 (cell 0) checksum mismatch").is_ok());
  Scene scene = small_scene(s.dir);
  Log log;
  auto stores = prepare_scene_stores(scene, std::nullopt, small_store_options(), s.dir, log.fn());
  ASSERT_TRUE(stores.is_ok()) << stores.status().message();
  EXPECT_FALSE(stores->builds.at(0).reused);
  EXPECT_NE(log.text.find("corrupt"), std::string::npos) << log.text;
  EXPECT_FALSE(store_corruption(store).has_value());
}

TEST(StoreRepair, ChecksumFailureDuringARunIsRecordedTheStoreRebuiltAndTheRunRetried) {
  Progress::set_enabled(false);
  Scratch s("during-run");
  const fs::path store = prepare(s.dir);
  ASSERT_FALSE(store.empty());
  {  // Damage every page, so that whichever the run reads first fails its checksum.
    auto opened = OctreeStore::open(store);
    ASSERT_TRUE(opened.is_ok());
    std::vector<uint64_t> offsets;
    for (const PageInfo& p : (*opened)->pages()) offsets.push_back(p.offset + 3);
    opened.value().reset();
    for (uint64_t o : offsets) flip_byte(store, o);
  }
  RunOptions options;
  options.memory_limit = uint64_t(1) << 30;
  options.rays = 200;
  options.cache_dir = s.dir;
  options.progress = false;
  Log log;
  auto result = run_pipeline(small_scene(s.dir), options, log.fn());
  ASSERT_TRUE(result.is_ok()) << result.status().message() << "\n" << log.text;
  EXPECT_NE(log.text.find("corrupt"), std::string::npos) << log.text;
  EXPECT_NE(log.text.find("rebuilding it and retrying"), std::string::npos) << log.text;
  EXPECT_GT(result->triangles_out, 0u);
  auto verified = verify_store_pages(store);
  EXPECT_TRUE(verified.is_ok()) << verified.status().message();
  EXPECT_FALSE(store_corruption(store).has_value());
}

TEST(StoreRepair, ConcurrentPreparationsShareOneGeneratedMeshAndStore) {
  Progress::set_enabled(false);
  Scratch s("concurrent");
  constexpr int kRuns = 3;
  std::vector<Status> results(kRuns);
  std::vector<fs::path> paths(kRuns);
  std::vector<std::thread> threads;
  for (int i = 0; i < kRuns; ++i)
    threads.emplace_back([&, i] {
      Scene scene = small_scene(s.dir);
      auto stores = prepare_scene_stores(scene, std::nullopt, small_store_options(), s.dir, nullptr);
      results[size_t(i)] = stores.status();
      if (stores.is_ok()) paths[size_t(i)] = stores->store_paths.at(0);
    });
  for (auto& t : threads) t.join();
  for (const Status& r : results) EXPECT_TRUE(r.is_ok()) << r.message();
  ASSERT_FALSE(paths[0].empty());
  for (const auto& p : paths) EXPECT_EQ(p, paths[0]);
  auto verified = verify_store_pages(paths[0]);
  EXPECT_TRUE(verified.is_ok()) << verified.status().message();
  // The store is current for the mesh as it is now (not rewritten under it).
  Scene scene = small_scene(s.dir);
  auto again = prepare_scene_stores(scene, std::nullopt, small_store_options(), s.dir, nullptr);
  ASSERT_TRUE(again.is_ok()) << again.status().message();
  EXPECT_TRUE(again->builds.at(0).reused) << again->builds.at(0).reason;
}

TEST(StoreRepair, FindReusableRemovesACorruptCutFile) {
  Scratch s("cut");
  auto cache = SimplifiedCache::open(s.dir, uint64_t(1) << 30);
  ASSERT_TRUE(cache.is_ok()) << cache.status().message();
  Cut cut;
  cut.store_hash = 0x1234;
  cut.key = "test";
  const fs::path drc = s.dir / "mesh.drc";
  std::ofstream(drc) << "not really draco, but hashed and copied as it is";
  auto entry = cache->insert(cut, drc, 10, 0.001, kDefaultCreaseAngleDeg);
  ASSERT_TRUE(entry.is_ok()) << entry.status().message();
  ASSERT_TRUE(fs::exists(entry->cut));
  std::ofstream(entry->cut, std::ios::trunc) << "garbage";
  std::string why;
  EXPECT_FALSE(cache->find_reusable(cut, 1.0, &why, kDefaultCreaseAngleDeg).has_value());
  EXPECT_FALSE(fs::exists(entry->cut));
  EXPECT_FALSE(fs::exists(entry->mesh));
}

}  // namespace
}  // namespace raylod
