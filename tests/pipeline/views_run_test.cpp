// raylod run --views / --orbit / --shared-cut end to end through the
// executable on a small generated teapot: numbered images, per-view
// statistics, cache reuse across views, errors before anything is written,
// and the shared cut's one mesh rendering every view as `raylod render` does.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "pipeline/simplified_cache.h"
#include "pipeline/views.h"
#include "render/renderer.h"
#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// A scratch folder of its own per test, removed at the end even on failure.
struct Folder {
  fs::path dir;
  explicit Folder(const std::string& name) : dir(test::scratch_dir("views-" + name)) {}
  ~Folder() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A 6k-triangle teapot at 64 x 48, one sample per pixel.
fs::path write_scene(const fs::path& dir, const std::string& camera = R"({"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0], "fov_y": 34, "width": 64, "height": 48})") {
  const fs::path p = dir / "scene.json";
  std::ofstream(p) << R"({"camera": )" << camera << R"(,
    "materials": {"red": {"type": "diffuse", "color": [0.7, 0.2, 0.1]}, "floor": {"type": "diffuse", "color": [0.6, 0.6, 0.6]}},
    "objects": [{"mesh": {"generate": "teapot", "triangles": 6000}, "material": "red"}],
    "ground": {"height": 0, "size": 30, "material": "floor"},
    "lights": [{"type": "point", "position": [5, 9, 5], "intensity": 120}],
    "spp": 1, "max_depth": 2, "seed": 5})";
  return p;
}

test::CommandResult raylod(const Folder& f, const std::string& args, int threads = 2) {
  return test::run_command("RAYLOD_CACHE_DIR='" + (f.dir / "cache").string() + "' '" RAYLOD_EXE "' " + args +
                           " --threads " + std::to_string(threads));
}

TEST(NumberedImagePath, ReplacesTheLastRunOfHashesOrInsertsOne) {
  EXPECT_EQ(numbered_image_path("out_####.png", 7), fs::path("out_0007.png"));
  EXPECT_EQ(numbered_image_path("dir/v#.exr", 12), fs::path("dir/v12.exr"));
  EXPECT_EQ(numbered_image_path("a#b/out_##.png", 3), fs::path("a#b/out_03.png"));
  EXPECT_EQ(numbered_image_path("out.png", 3), fs::path("out_0003.png"));
  EXPECT_EQ(numbered_image_path("renders/out.png", 12345), fs::path("renders/out_12345.png"));
}

TEST(ViewsRun, ThreeViewsWriteNumberedImagesAndPerViewStatsAndReuseTheCache) {
  Folder f("three");
  const fs::path scene = write_scene(f.dir);
  std::ofstream(f.dir / "v.json") << R"([
    {"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0]},
    {"eye": [-8.5, 4.8, 6.5], "look_at": [0.2, 1.3, 0], "width": 48, "height": 32},
    {"eye": [3.0, 2.5, 4.0], "look_at": [0.2, 1.3, 0], "fov_y": 40}])";
  const std::string args = "run '" + scene.string() + "' --views '" + (f.dir / "v.json").string() + "' -o '" +
                           (f.dir / "out_##.png").string() + "' --rays 500 --stats-json '" + (f.dir / "s.json").string() + "'";
  auto r = raylod(f, args);
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* name : {"out_00.png", "out_01.png", "out_02.png"}) EXPECT_TRUE(fs::is_regular_file(f.dir / name)) << name;
  EXPECT_FALSE(fs::exists(f.dir / "out_03.png"));
  auto j = nlohmann::json::parse(slurp(f.dir / "s.json"));
  EXPECT_EQ(j["mode"], "per_view");
  ASSERT_EQ(j["views"].size(), 3u);
  for (const auto& v : j["views"]) {
    EXPECT_GT(v["triangles"].get<uint64_t>(), 0u);
    EXPECT_LT(v["triangles"].get<uint64_t>(), j["triangles_in"].get<uint64_t>());
    for (const char* stage : {"probe", "simplify", "render", "total"}) EXPECT_TRUE(v["seconds"].contains(stage)) << stage;
    EXPECT_TRUE(v.contains("cache_hit"));
    EXPECT_TRUE(v.contains("render"));
  }
  EXPECT_EQ(j["views"][1]["camera"]["width"], 48);
  EXPECT_EQ(j["views"][2]["camera"]["fov_y"], 40.0);
  EXPECT_EQ(j["summary"]["views"], 3);
  EXPECT_TRUE(j["summary"].contains("total_seconds"));
  EXPECT_TRUE(j["summary"].contains("seconds_per_view"));
  EXPECT_TRUE(j["summary"].contains("triangles_per_view"));
  EXPECT_FALSE(j["views"][0]["cache_hit"].get<bool>());  // a fresh cache
  EXPECT_NE(r.out.find("views reused a simplified mesh"), std::string::npos) << r.out;

  // Again: every view reuses a cached mesh and the images do not change.
  const std::string first = slurp(f.dir / "out_01.png");
  auto again = raylod(f, args);
  ASSERT_EQ(again.status, 0) << again.out;
  auto k = nlohmann::json::parse(slurp(f.dir / "s.json"));
  EXPECT_EQ(k["summary"]["cache_reuse"], 3);
  for (const auto& v : k["views"]) EXPECT_TRUE(v["cache_hit"].get<bool>());
  EXPECT_EQ(slurp(f.dir / "out_01.png"), first);

  // An 8-bit image is encoded tile by tile where it is rendered
  // (RunOptions::srgb_color); a float one keeps the linear colors. Written
  // to PNG, the linear colors give the same file, for the views and for a
  // single view.
  const std::string exr_args = "run '" + scene.string() + "' --views '" + (f.dir / "v.json").string() + "' -o '" +
                               (f.dir / "lin_##.exr").string() + "' --rays 500 -q";
  auto linear = raylod(f, exr_args);
  ASSERT_EQ(linear.status, 0) << linear.out;
  auto single = raylod(f, "run '" + scene.string() + "' -o '" + (f.dir / "one.png").string() + "' --rays 500 -q");
  ASSERT_EQ(single.status, 0) << single.out;
  auto single_linear = raylod(f, "run '" + scene.string() + "' -o '" + (f.dir / "one.exr").string() + "' --rays 500 -q");
  ASSERT_EQ(single_linear.status, 0) << single_linear.out;
  for (const auto& [exr, png] : {std::pair{"lin_00.exr", "out_00.png"}, std::pair{"lin_01.exr", "out_01.png"},
                                 std::pair{"lin_02.exr", "out_02.png"}, std::pair{"one.exr", "one.png"}}) {
    auto colors = read_image(f.dir / exr);
    ASSERT_TRUE(colors.is_ok()) << colors.status().message();
    ASSERT_TRUE(write_image(f.dir / "from_linear.png", *colors).is_ok());
    EXPECT_EQ(slurp(f.dir / "from_linear.png"), slurp(f.dir / png)) << png;
  }
}

TEST(ViewsRun, BadViewsFileFailsNamingTheElementAndWritesNothing) {
  Folder f("bad");
  const fs::path scene = write_scene(f.dir);
  const fs::path views = f.dir / "views.json";
  std::ofstream(views) << R"([{"eye": [6.5, 4.8, 8.5], "look_at": [0, 1, 0]}, {"eye": [1, 2], "look_at": [0, 1, 0]}])";
  auto r = raylod(f, "run '" + scene.string() + "' --views '" + views.string() + "' -o '" + (f.dir / "o.png").string() +
                         "' --stats-json '" + (f.dir / "s.json").string() + "'");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.out.find(views.string() + ": [1].eye: expected an array of 3 numbers"), std::string::npos) << r.out;
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(f.dir)) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"scene.json", "views.json"}));

  auto both = raylod(f, "run '" + scene.string() + "' --views '" + views.string() + "' --orbit 3");
  EXPECT_NE(both.status, 0);
  auto lone = raylod(f, "run '" + scene.string() + "' --shared-cut");
  EXPECT_NE(lone.status, 0);
  EXPECT_NE(lone.out.find("--shared-cut needs --views FILE or --orbit N"), std::string::npos) << lone.out;
}

// --shared-cut holds every view's hits until the cut is selected: past the
// memory limit it stops and says so (it grew without bound before), and
// writes no image. (Not under AddressSanitizer: its shadow memory alone
// passes the limit at start.)
#if !defined(__SANITIZE_ADDRESS__)
TEST(ViewsRun, SharedCutStopsAtTheMemoryLimit) {
  Folder f("shared-limit");
  const fs::path scene = write_scene(f.dir);
  auto r = raylod(f, "run '" + scene.string() + "' --orbit 2000 --shared-cut --rays 20000 --memory-limit 220M -o '" +
                         (f.dir / "o.png").string() + "'");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("--shared-cut holds every view's test-ray hits"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("more than the memory limit of 220.00 MiB"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(f.dir / "o_0000.png"));
}
#endif

// --shared-cut simplifies once: one mesh in the (fresh) cache, and every view's
// image is what `raylod render` makes of that mesh from the view's camera.
TEST(ViewsRun, SharedCutRendersEveryViewFromOneMesh) {
  Folder f("shared");
  const fs::path scene = write_scene(f.dir);
  auto r = raylod(f, "run '" + scene.string() + "' --orbit 3 --shared-cut --rays 500 -o '" + (f.dir / "o.png").string() +
                         "' --stats-json '" + (f.dir / "s.json").string() + "'");
  ASSERT_EQ(r.status, 0) << r.out;
  auto j = nlohmann::json::parse(slurp(f.dir / "s.json"));
  EXPECT_EQ(j["mode"], "shared_cut");
  ASSERT_EQ(j["shared"]["meshes"].size(), 1u);
  ASSERT_EQ(j["views"].size(), 3u);
  for (const auto& v : j["views"]) EXPECT_EQ(v["triangles"], j["shared"]["triangles"]);
  auto cache = SimplifiedCache::open(f.dir / "cache", uint64_t(1) << 30);
  ASSERT_TRUE(cache.is_ok()) << cache.status().message();
  const auto entries = cache->entries();
  ASSERT_EQ(entries.size(), 1u);
  const fs::path mesh = entries[0].mesh;
  for (size_t i = 0; i < 3; ++i) {
    const auto& c = j["views"][i]["camera"];
    const fs::path view_dir = f.dir / ("view" + std::to_string(i));
    fs::create_directories(view_dir);
    const fs::path view_scene = write_scene(view_dir, c.dump());
    const fs::path alone = view_dir / "alone.png";
    auto rendered = raylod(f, "render '" + view_scene.string() + "' --mesh '" + mesh.string() + "' -o '" + alone.string() + "'");
    ASSERT_EQ(rendered.status, 0) << rendered.out;
    const fs::path in_run = f.dir / ("o_000" + std::to_string(i) + ".png");
    ASSERT_TRUE(fs::is_regular_file(in_run));
    EXPECT_EQ(slurp(alone), slurp(in_run)) << "view " << i;
  }
}

// The same images and the same shared mesh on 1 and 2 threads.
TEST(ViewsRun, SharedCutIsTheSameOnOneAndTwoThreads) {
  Folder f("threads");
  const fs::path scene = write_scene(f.dir);
  std::string stats[2];
  for (int threads : {1, 2}) {
    const std::string n = std::to_string(threads);
    auto r = raylod(f, "run '" + scene.string() + "' --orbit 3 --shared-cut --no-cache --rays 500 -o '" +
                           (f.dir / ("t" + n + "_#.png")).string() + "' --stats-json '" + (f.dir / ("s" + n + ".json")).string() + "'",
                    threads);
    ASSERT_EQ(r.status, 0) << r.out;
    auto j = nlohmann::json::parse(slurp(f.dir / ("s" + n + ".json")));
    stats[threads - 1] = j["shared"]["triangles"].dump() + " " + j["shared"]["cells_marked"].dump() + " " +
                         j["shared"]["meshes"][0]["drc_bytes"].dump();
  }
  EXPECT_EQ(stats[0], stats[1]);
  for (int i = 0; i < 3; ++i) {
    const std::string one = slurp(f.dir / ("t1_" + std::to_string(i) + ".png"));
    EXPECT_FALSE(one.empty());
    EXPECT_EQ(one, slurp(f.dir / ("t2_" + std::to_string(i) + ".png"))) << "view " << i;
  }
}

}  // namespace
}  // namespace raylod
