// End to end through the raylod executable: run, the cache across views,
// memory-limited runs, and report --quick.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_tmp.h"

namespace {

namespace fs = std::filesystem;

// This process's scratch directory, removed when the tests end.
fs::path work_dir() {
  static fs::path d = [] {
    fs::path p = raylod::test::scratch_dir("run-report");
    fs::remove_all(p);
    fs::create_directories(p);
    return p;
  }();
  return d;
}

class RemoveWorkDir : public ::testing::Environment {
 public:
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(work_dir(), ec);
  }
};
[[maybe_unused]] const auto* const kRemoveWorkDir = ::testing::AddGlobalTestEnvironment(new RemoveWorkDir);

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Runs raylod with arguments; returns the exit code, output in *out.
// `env`: more VAR=value settings for it, e.g. RAYLOD_FAULT_POINT=NAME.
int raylod(const std::string& args, std::string* out = nullptr, const std::string& env = "") {
  fs::path log = work_dir() / "last.log";
  std::string cmd = "RAYLOD_CACHE_DIR='" + (work_dir() / "cache").string() + "' " + env + " '" RAYLOD_EXE "' " + args +
                    " > '" + log.string() + "' 2>&1";
  int rc = std::system(cmd.c_str());
  if (out) *out = read(log);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

// The same, run from the folder `dir`.
int raylod_in(const fs::path& dir, const std::string& args, std::string* out) {
  return raylod(args, out, "sh -c 'cd \"$0\" && exec \"$@\"' '" + dir.string() + "'");
}

// A small version of the default scene: a generated 20k-triangle teapot,
// a thumbnail, one sample per pixel. eye_scale moves the eye along the view.
fs::path write_scene(const std::string& name, double eye_scale, int width = 128, int height = 96,
                     int triangles = 20000) {
  fs::path p = work_dir() / name;
  double ex = 6.5 * eye_scale, ey = 1.3 + 3.5 * eye_scale, ez = 8.5 * eye_scale;
  std::ofstream(p) << R"({"camera": {"eye": [)" << ex << ", " << ey << ", " << ez
                   << R"(], "look_at": [0.2, 1.3, 0], "fov_y": 34, "width": )" << width << R"(, "height": )" << height
                   << R"(},
    "materials": {"p": {"type": "glossy", "color": [0.7, 0.1, 0.1], "specular": [0.4, 0.4, 0.4]},
                  "floor": {"type": "diffuse", "color": [0.7, 0.7, 0.7]}},
    "objects": [{"mesh": {"generate": "teapot", "triangles": )" << triangles << R"(}, "material": "p"}],
    "ground": {"height": 0, "size": 40, "material": "floor"},
    "lights": [{"type": "point", "position": [6, 10, 6], "intensity": 150}],
    "spp": 1, "max_depth": 3, "seed": 3})";
  return p;
}

nlohmann::json stats(const fs::path& p) { return nlohmann::json::parse(read(p)); }

// `raylod run SCENE --no-cache EXTRA` writing TAG.png and TAG.json in the
// work folder: the simplified triangle count (its output appended to out).
uint64_t run_triangles(const fs::path& scene, const std::string& extra, const std::string& tag, std::string& out) {
  const fs::path st = work_dir() / (tag + ".json");
  EXPECT_EQ(raylod("run '" + scene.string() + "' --no-cache " + extra + " -o '" + (work_dir() / (tag + ".png")).string() +
                       "' --stats-json '" + st.string() + "'",
                   &out),
            0)
      << out;
  return stats(st)["triangles_out"];
}

// A command prefix that runs raylod as a user who cannot write where the
// test forbids it: root writes anywhere, so as root the command drops to
// user nobody (setpriv), with HOME in `home` (made writable to all); for
// anyone else, empty (the test makes folders read-only instead). nullopt,
// and why, when root cannot drop here.
std::optional<std::string> as_unprivileged(const fs::path& home, std::string* why) {
  if (::geteuid() != 0) return std::string();
  if (std::system("command -v setpriv > /dev/null 2>&1") != 0) {
    *why = "running as root without setpriv";
    return std::nullopt;
  }
  // nobody must reach the executable, the scene and the writable folder.
  for (fs::path p = work_dir(); p.has_relative_path() && p != p.root_path(); p = p.parent_path())
    if (((fs::status(p).permissions() & fs::perms::others_exec) == fs::perms::none)) {
      *why = p.string() + " is not searchable by other users";
      return std::nullopt;
    }
  fs::permissions(home, fs::perms::all);
  return "setpriv --reuid=65534 --regid=65534 --clear-groups env HOME='" + home.string() + "' ";
}

TEST(Run, SecondRunOfTheSameViewHitsTheCache) {
  fs::path scene = write_scene("view.json", 1.0);
  fs::path cache = work_dir() / "cache-same";
  std::string out;
  const std::string common = "run '" + scene.string() + "' --rays 800 --footprint-scale 4 --cache '" + cache.string() + "' ";
  ASSERT_EQ(raylod(common + "-o '" + (work_dir() / "a.png").string() + "' --stats-json '" +
                   (work_dir() / "a.json").string() + "'", &out), 0) << out;
  auto a = stats(work_dir() / "a.json");
  EXPECT_FALSE(a["cache_hit"].get<bool>());
  EXPECT_GT(a["triangles_in"].get<uint64_t>(), a["triangles_out"].get<uint64_t>());
  for (const char* stage : {"build", "probe", "simplify", "render"}) EXPECT_GE(a["seconds"][stage].get<double>(), 0.0);
  EXPECT_GT(a["peak_rss_bytes"].get<uint64_t>(), 0u);
  EXPECT_TRUE(fs::exists(work_dir() / "a.png"));
  // Each simplified mesh's statistics name the mesh they are about.
  ASSERT_EQ(a["meshes"].size(), 1u);
  EXPECT_EQ(a["meshes"][0]["mesh"].get<std::string>(), "teapot-20000.ply") << a["meshes"].dump();

  ASSERT_EQ(raylod(common + "-o '" + (work_dir() / "b.png").string() + "' --stats-json '" +
                   (work_dir() / "b.json").string() + "'", &out), 0) << out;
  auto b = stats(work_dir() / "b.json");
  EXPECT_TRUE(b["cache_hit"].get<bool>()) << out;
  EXPECT_EQ(a["triangles_out"], b["triangles_out"]);
  // Same inputs and seed: the same image.
  EXPECT_EQ(read(work_dir() / "a.png"), read(work_dir() / "b.png"));
}

TEST(Run, OtherViewsReuseOrRebuildByTheRule) {
  fs::path cache = work_dir() / "cache-views";
  auto run = [&](const std::string& scene, const std::string& tag) {
    std::string out;
    EXPECT_EQ(raylod("run '" + write_scene(scene, tag == "near" ? 0.5 : tag == "far" ? 3.0 : 1.0).string() +
                     "' --rays 800 --footprint-scale 4 --cache '" + cache.string() + "' -o '" +
                     (work_dir() / (tag + ".png")).string() + "' --stats-json '" +
                     (work_dir() / (tag + ".stats.json")).string() + "'", &out), 0) << out;
    return stats(work_dir() / (tag + ".stats.json"));
  };
  auto mid = run("mid.json", "mid");
  EXPECT_FALSE(mid["cache_hit"].get<bool>());
  // Farther away the view resolves less: either the cached mesh collapses
  // no cell the new cut keeps and is reused, or the new cut is coarser. (Not
  // always the first: a rim the near view saw at a grazing angle, where the
  // measured footprint is long, can be a cell no test ray reaches from
  // farther, where the pinhole bound is shorter.)
  auto far = run("far.json", "far");
  if (far["cache_hit"].get<bool>()) {
    EXPECT_NE(far["meshes"][0]["cache_note"].get<std::string>().find("reusing"), std::string::npos);
    EXPECT_EQ(far["triangles_out"], mid["triangles_out"]);
  } else {
    EXPECT_LT(far["triangles_out"].get<uint64_t>(), mid["triangles_out"].get<uint64_t>()) << far.dump(2);
  }
  // Closer, the view needs finer cells than the cached mesh has: rebuilt.
  auto near = run("near.json", "near");
  EXPECT_FALSE(near["cache_hit"].get<bool>()) << near.dump(2);
  EXPECT_GT(near["triangles_out"].get<uint64_t>(), mid["triangles_out"].get<uint64_t>());
}

TEST(Run, CorruptCacheEntryIsRebuiltNotRendered) {
  fs::path scene = write_scene("corrupt.json", 1.0);
  fs::path cache = work_dir() / "cache-corrupt";
  const std::string common = "run '" + scene.string() + "' --rays 500 --footprint-scale 4 --cache '" + cache.string() +
                             "' -o '" + (work_dir() / "c.png").string() + "' --stats-json '" +
                             (work_dir() / "c.json").string() + "'";
  std::string out;
  ASSERT_EQ(raylod(common, &out), 0) << out;
  std::string first = read(work_dir() / "c.png");
  int corrupted = 0;
  for (const auto& f : fs::directory_iterator(cache / "simplified"))
    if (f.path().extension() == ".drc") {
      std::fstream io(f.path(), std::ios::in | std::ios::out | std::ios::binary);
      io.seekp(40);
      io.put('\x5a');
      ++corrupted;
    }
  ASSERT_EQ(corrupted, 1);
  ASSERT_EQ(raylod(common, &out), 0) << out;
  EXPECT_NE(out.find("corrupt"), std::string::npos) << out;
  EXPECT_FALSE(stats(work_dir() / "c.json")["cache_hit"].get<bool>());
  EXPECT_EQ(read(work_dir() / "c.png"), first);
}

TEST(Run, MemoryLimitBelowTheFullMeshCoarsensTheCut) {
  // A 3.6M-triangle teapot at 640 x 480: the renderer's estimate for the full
  // mesh (16 MiB + about 90 bytes per triangle even with the compact BVH
  // layout) is over 300 MiB, and at K = 1 the cut keeps most triangles (they
  // are about pixel-sized).
  fs::path scene = write_scene("tight.json", 1.0, 640, 480, 3600000);
  std::string out;
  ASSERT_NE(raylod("render '" + scene.string() + "' -o '" + (work_dir() / "t-full.png").string() +
                   "' --memory-limit 300M", &out), 0);
  EXPECT_NE(out.find("raylod run"), std::string::npos) << out;
  EXPECT_NE(out.find("compact layout"), std::string::npos) << out;
  // ...and run still produces an image by coarsening the cut. The comparison
  // cannot fit the full mesh either: it is skipped with a warning, and the
  // run succeeds with its statistics written.
  ASSERT_EQ(raylod("run '" + scene.string() + "' --no-cache --memory-limit 300M --footprint-scale 1 --rays 500 -o '" +
                   (work_dir() / "t.png").string() + "' --compare --stats-json '" + (work_dir() / "t.json").string() + "'",
                   &out), 0)
      << out;
  EXPECT_NE(out.find("warning: --compare skipped: the full mesh (3"), std::string::npos) << out;
  EXPECT_EQ(out.find("Use `raylod run`"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(work_dir() / "t.full.png"));
  auto t = stats(work_dir() / "t.json");
  EXPECT_TRUE(t.contains("comparison_skipped")) << t.dump(2);
  EXPECT_FALSE(t.contains("psnr")) << t.dump(2);
  EXPECT_GT(t["coarsening_steps"].get<int>(), 0) << out;
  EXPECT_GT(t["footprint_scale"].get<double>(), 1.0) << out;
  EXPECT_NE(out.find("coarsening the cut"), std::string::npos) << out;
  EXPECT_LE(t["render"]["bytes"]["estimated"].get<uint64_t>(), uint64_t(300) << 20) << out;
  // One budget (memory_budget.h): the program's own memory counts against
  // the limit, and the stores and the trace are freed before rendering (the
  // run used to peak at 513 MiB here). Sanitizers add shadow memory.
#if !defined(__SANITIZE_ADDRESS__)
  EXPECT_LE(t["peak_rss_bytes"].get<uint64_t>(), uint64_t(300) << 20) << out;
#endif
  EXPECT_TRUE(fs::exists(work_dir() / "t.png"));
}

TEST(Run, SameImageAndMeshOnOneOrTwoThreads) {
  fs::path scene = write_scene("threads.json", 1.0);
  std::string out;
  for (int t : {1, 2}) {
    const std::string tag = "threads" + std::to_string(t);
    ASSERT_EQ(raylod("run '" + scene.string() + "' --no-cache --rays 700 --footprint-scale 4 --threads " +
                     std::to_string(t) + " -o '" + (work_dir() / (tag + ".png")).string() + "' --stats-json '" +
                     (work_dir() / (tag + ".json")).string() + "'", &out), 0) << out;
  }
  EXPECT_EQ(stats(work_dir() / "threads1.json")["triangles_out"], stats(work_dir() / "threads2.json")["triangles_out"]);
  EXPECT_EQ(read(work_dir() / "threads1.png"), read(work_dir() / "threads2.png"));
}

TEST(Run, CompareReportsTheNoiseFloor) {
  fs::path scene = write_scene("compare.json", 1.0);
  std::string out;
  ASSERT_EQ(raylod("run '" + scene.string() + "' --no-cache --rays 500 --footprint-scale 4 --compare -o '" +
                   (work_dir() / "cmp.png").string() + "' --stats-json '" + (work_dir() / "cmp.json").string() + "'",
                   &out), 0) << out;
  auto j = stats(work_dir() / "cmp.json");
  ASSERT_TRUE(j.contains("noise_floor")) << j.dump(2);
  const auto& floor = j["noise_floor"];
  // The scene's seed is 3 and its spp 1: the floor is seed 4 against seed 3.
  EXPECT_EQ(floor["seed"].get<uint64_t>(), 3u);
  EXPECT_EQ(floor["other_seed"].get<uint64_t>(), 4u);
  EXPECT_EQ(floor["spp"].get<int>(), 1);
  ASSERT_TRUE(floor["psnr"].is_number()) << floor.dump();  // one jittered sample per pixel: seeds differ
  ASSERT_TRUE(j["psnr"].is_number()) << j.dump(2);
  const bool within = j["psnr"].get<double>() >= floor["psnr"].get<double>();
  EXPECT_EQ(j["within_noise_floor"].get<bool>(), within) << j.dump(2);
  EXPECT_NE(out.find("noise floor"), std::string::npos) << out;
  EXPECT_NE(out.find(within ? ": indistinguishable" : "below the noise floor of"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(work_dir() / "cmp.full.png"));
  EXPECT_TRUE(fs::exists(work_dir() / "cmp.diff.png"));
}

// Writes a binary STL of the given triangles (9 floats each).
void write_stl(const fs::path& p, const std::vector<std::array<float, 9>>& tris) {
  std::ofstream out(p, std::ios::binary);
  const std::string header(80, ' ');
  out.write(header.data(), 80);
  const uint32_t n = uint32_t(tris.size());
  out.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& t : tris) {
    const float normal[3] = {0, 0, 1};
    out.write(reinterpret_cast<const char*>(normal), 12);
    out.write(reinterpret_cast<const char*>(t.data()), 36);
    const uint16_t attr = 0;
    out.write(reinterpret_cast<const char*>(&attr), 2);
  }
}

// Two triangles, NAME.stl, in a scene of their own, NAME.json (32 x 24).
fs::path write_pair_scene(const std::string& name) {
  write_stl(work_dir() / (name + ".stl"), {{0, 0, 0, 1, 0, 0, 0, 1, 0}, {1, 0, 0, 1, 1, 0.5f, 0, 1, 0}});
  const fs::path scene = work_dir() / (name + ".json");
  std::ofstream(scene) << R"({"camera": {"eye": [0.5, 0.5, 4], "look_at": [0.5, 0.5, 0], "fov_y": 30, "width": 32, "height": 24},
    "materials": {"m": {"type": "diffuse", "color": [0.7, 0.7, 0.7]}},
    "objects": [{"mesh": ")" << name << R"(.stl", "material": "m"}],
    "lights": [{"type": "point", "position": [2, 5, 3], "intensity": 40}], "spp": 1})";
  return scene;
}

TEST(Run, MeshThatCollapsesToNothingIsLeftOutWithTheReason) {
  // Every triangle degenerate, and a mesh far below a pixel (one cell): each
  // simplifies to nothing. The run renders the rest of the scene, names the
  // input and the reason (never a cache temporary), and caches nothing.
  write_stl(work_dir() / "flat.stl", {{0, 0, 0, 1, 1, 1, 2, 2, 2}, {0, 0, 0, 0, 0, 0, 1, 0, 0}});
  write_stl(work_dir() / "speck.stl", {{0, 1, 0, 1e-6f, 1, 0, 0, 1 + 1e-6f, 0}, {1e-6f, 1, 0, 1e-6f, 1 + 1e-6f, 0, 0, 1 + 1e-6f, 0}});
  const std::map<std::string, std::string> reasons = {{"flat", "triangles are degenerate"}, {"speck", "triangles collapsed"}};
  for (const auto& [name, reason] : reasons) {
    fs::path scene = work_dir() / (name + ".json");
    std::ofstream(scene) << R"({"camera": {"eye": [0, 1, 5], "look_at": [0, 1, 0], "fov_y": 30, "width": 48, "height": 32},
      "materials": {"m": {"type": "diffuse", "color": [0.7, 0.7, 0.7]}},
      "objects": [{"mesh": ")" << name << R"(.stl", "material": "m"}],
      "ground": {"height": -0.5, "size": 20, "material": "m"},
      "lights": [{"type": "point", "position": [2, 5, 3], "intensity": 40}], "spp": 1})";
    const fs::path cache = work_dir() / ("cache-" + name);
    std::string out;
    ASSERT_EQ(raylod("run '" + scene.string() + "' -q --cache '" + cache.string() + "' -o '" +
                     (work_dir() / (name + ".png")).string() + "' --stats-json '" +
                     (work_dir() / (name + ".stats.json")).string() + "'", &out), 0)
        << out;
    EXPECT_NE(out.find("warning: " + (work_dir() / (name + ".stl")).string() + ": all 2 " + reason), std::string::npos) << out;
    EXPECT_NE(out.find("left out of the image"), std::string::npos) << out;
    EXPECT_EQ(out.find(".tmp-"), std::string::npos) << out;
    auto j = stats(work_dir() / (name + ".stats.json"));
    EXPECT_EQ(j["triangles_out"].get<uint64_t>(), 0u);
    ASSERT_EQ(j["warnings"].size(), 1u) << j.dump(2);
    EXPECT_TRUE(fs::exists(work_dir() / (name + ".png")));
    size_t cached = 0;
    std::error_code ec;
    for (auto it = fs::recursive_directory_iterator(cache, ec); it != fs::recursive_directory_iterator(); ++it)
      cached += it->path().extension() == ".drc";
    EXPECT_EQ(cached, 0u);
  }
}

// The cut's bounds assume the default crease rule: another crease angle on
// a mesh without normals is run as asked, with a warning naming the mesh;
// at the default, no warning.
TEST(Run, ACreaseAngleOtherThanTheDefaultIsRunWithAWarning) {
  const fs::path scene = write_pair_scene("pair");
  for (const char* angle : {"0", "25"}) {
    std::string out;
    ASSERT_EQ(raylod("run '" + scene.string() + "' --no-cache --crease-angle " + angle + " -o '" +
                         (work_dir() / "pair.png").string() + "'",
                     &out),
              0)
        << out;
    const bool warned = out.find("warning: crease angle " + std::string(angle) + " degrees") != std::string::npos;
    EXPECT_EQ(warned, std::string(angle) == "0") << out;
    if (warned) {
      EXPECT_NE(out.find((work_dir() / "pair.stl").string() + " (no normals of its own)"), std::string::npos) << out;
    }
  }
}

// A limit too small for the program and the test rays fails before the
// store check, so a good store is not rebuilt for it first.
TEST(Run, AHopelessMemoryLimitLeavesTheStoreAlone) {
  const fs::path scene = write_pair_scene("keep");
  const std::string image = (work_dir() / "keep.png").string();
  std::string out;
  ASSERT_EQ(raylod("run '" + scene.string() + "' --no-cache -q -o '" + image + "'", &out), 0) << out;
  const fs::path store = work_dir() / "keep.stl.raylod";
  ASSERT_TRUE(fs::exists(store));
  const auto built = fs::last_write_time(store);
  EXPECT_EQ(raylod("run '" + scene.string() + "' --no-cache -q --memory-limit 150M -o '" + image + "'", &out), 1) << out;
  EXPECT_NE(out.find("leaves nothing for the probe"), std::string::npos) << out;
  EXPECT_EQ(out.find("building store"), std::string::npos) << out;
  EXPECT_EQ(fs::last_write_time(store), built);
}

TEST(Run, UnusableCacheRendersWithoutCaching) {
  // The cache folder cannot be used (its "simplified" folder is a file, as a
  // full or read-only cache disk would refuse it): the run still renders,
  // warns, and leaves the cache alone.
  fs::path scene = write_scene("nocache.json", 1.0, 48, 36, 5000);
  const fs::path cache = work_dir() / "cache-unusable";
  fs::create_directories(cache);
  std::ofstream(cache / "simplified") << "not a folder";
  std::string out;
  // The generated teapot is made (once) in the test's own cache.
  ASSERT_EQ(raylod("run '" + scene.string() + "' -q --rays 300 --cache '" + cache.string() + "' -o '" +
                   (work_dir() / "nocache.png").string() + "'", &out), 0)
      << out;
  EXPECT_NE(out.find("warning: cannot use the cache"), std::string::npos) << out;
  EXPECT_NE(out.find("rendering without caching"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(work_dir() / "nocache.png"));
  EXPECT_TRUE(fs::is_regular_file(cache / "simplified"));
}

TEST(Run, OutputDoesNotDependOnTheLimitAnEarlierBuildUsed) {
  // A store built under a small limit is shallower; a later run under a
  // larger limit must not reuse it (it used to, and gave a coarser cut than
  // the same command on a fresh mesh), and a store that a fresh build would
  // make identically is reused.
  const fs::path a = work_dir() / "history-a.ply", b = work_dir() / "history-b.ply";
  std::string out;
  ASSERT_EQ(raylod("gen teapot --triangles 200000 -q -o '" + a.string() + "'", &out), 0) << out;
  fs::copy_file(a, b);
  ASSERT_EQ(raylod("build '" + a.string() + "' -q --memory-limit 100M", &out), 0) << out;
  const fs::path scene = write_scene("history.json", 1.0, 96, 72);
  auto run = [&](const fs::path& mesh, const std::string& tag) {
    const int rc = raylod("run '" + scene.string() + "' --mesh '" + mesh.string() +
                              "' --no-cache --rays 800 --memory-limit 1G -o '" + (work_dir() / (tag + ".png")).string() +
                              "' --stats-json '" + (work_dir() / (tag + ".json")).string() + "'",
                          &out);
    EXPECT_EQ(rc, 0) << out;
    return out;
  };
  const std::string first = run(a, "history-a");
  EXPECT_NE(first.find("building store"), std::string::npos) << first;
  EXPECT_NE(first.find("a build under 1.00 GiB makes a finer one"), std::string::npos) << first;
  run(b, "history-b");
  EXPECT_EQ(stats(work_dir() / "history-a.json")["triangles_out"], stats(work_dir() / "history-b.json")["triangles_out"]);
  EXPECT_EQ(read(work_dir() / "history-a.png"), read(work_dir() / "history-b.png"));
  // 2G builds the same store as 1G here: reused.
  ASSERT_EQ(raylod("build '" + a.string() + "' --memory-limit 2G", &out), 0) << out;
  EXPECT_NE(out.find("up to date"), std::string::npos) << out;
}

// The names in a folder, sorted.
std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

// A folder of meshes, to be made read-only, and a folder beside it that
// stays writable; `mesh` generates a teapot in the first.
struct MeshFolders {
  fs::path base, meshes, writable;
  explicit MeshFolders(const std::string& name)
      : base(work_dir() / name), meshes(base / "meshes"), writable(base / "writable") {
    fs::create_directories(meshes);
    fs::create_directories(writable);
  }
  void mesh(const std::string& name, int triangles) const {
    std::string out;
    ASSERT_EQ(raylod("gen teapot --triangles " + std::to_string(triangles) + " -q -o '" + (meshes / name).string() + "'",
                     &out),
              0)
        << out;
  }
};

TEST(Run, MeshInAReadOnlyFolderGetsItsStoreInTheCache) {
  // The store normally sits beside the mesh; a mesh in a folder this user
  // cannot write to gets it under the cache folder instead. Root writes
  // anywhere, so as root the run drops to user nobody (setpriv); otherwise
  // the folder is made read-only.
  const MeshFolders folders("read-only");
  const fs::path &base = folders.base, &meshes = folders.meshes, &writable = folders.writable;
  std::string out;
  folders.mesh("t.ply", 4000);
  const fs::path scene = write_scene("read-only.json", 1.0, 48, 36);
  std::string why;
  const std::optional<std::string> unprivileged = as_unprivileged(writable, &why);
  if (!unprivileged) GTEST_SKIP() << why;
  const std::string prefix = *unprivileged;
  const bool root = ::geteuid() == 0;
  if (!root) fs::permissions(meshes, fs::perms::owner_read | fs::perms::owner_exec);
  const fs::path cache = writable / "cache";
  const std::string cmd = prefix + "'" RAYLOD_EXE "' run '" + scene.string() + "' --mesh '" + (meshes / "t.ply").string() +
                          "' --rays 300 --cache '" + cache.string() + "' -o '" + (writable / "x.png").string() + "'";
  const int rc = std::system((cmd + " > '" + (base / "log").string() + "' 2>&1").c_str());
  out = read(base / "log");
  if (!root) fs::permissions(meshes, fs::perms::owner_all);
  ASSERT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << out;
  EXPECT_NE(out.find("is not writable: the store goes to " + (cache / "stores").string()), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(meshes / "t.ply.raylod"));
  size_t stores = 0;
  for (const auto& e : fs::directory_iterator(cache / "stores")) stores += e.path().extension() == ".raylod";
  EXPECT_EQ(stores, 1u);
  EXPECT_TRUE(fs::exists(writable / "x.png"));
}

TEST(Run, AMeshWithAVeryLongNameGetsItsStoreInTheCache) {
  // 241 bytes: the store's check record beside it (MESH.raylod.checked)
  // would pass a file name's 255 bytes, and the build failed with "File
  // name too long". Its store goes to the cache under a shortened name, and
  // probe's cut beside it.
  const MeshFolders folders("long-name");
  const std::string name = std::string(237, 'n') + ".ply";
  folders.mesh(name, 2000);
  const fs::path scene = write_scene("long-name.json", 1.0, 48, 36);
  const std::string mesh = "--mesh '" + (folders.meshes / name).string() + "' --rays 300";
  std::string out;
  ASSERT_EQ(raylod("run '" + scene.string() + "' " + mesh + " -o '" + (folders.writable / "x.png").string() + "'", &out),
            0)
      << out;
  EXPECT_NE(out.find("the name is too long for a store beside it: the store goes to " + (work_dir() / "cache" / "stores").string()),
            std::string::npos)
      << out;
  EXPECT_TRUE(fs::exists(folders.writable / "x.png"));
  ASSERT_EQ(raylod("probe '" + scene.string() + "' " + mesh, &out), 0) << out;
  EXPECT_EQ(names_in(folders.meshes), std::vector<std::string>{name});
  size_t stores = 0, cuts = 0;
  for (const auto& e : fs::directory_iterator(work_dir() / "cache" / "stores")) {
    const std::string f = e.path().filename().string();
    EXPECT_LE(f.size(), 255u) << f;
    if (f.find(std::string(100, 'n')) == std::string::npos) continue;
    stores += e.path().extension() == ".raylod";
    cuts += e.path().extension() == ".cut";
  }
  EXPECT_EQ(stores, 1u);
  EXPECT_EQ(cuts, 1u);
}

TEST(Probe, ACutGoesBesideItsStoreOrIntoTheCacheWhereThatFolderIsReadOnly) {
  // `raylod probe` without -o: the cut beside the store. A mesh in a
  // read-only folder has its store in the cache, and its cut with it (the
  // cut used to go beside the mesh, failing after every ray was traced); a
  // store already beside it (built before the folder became read-only) is
  // used there, and the cut goes to the cache, said so.
  const MeshFolders folders("read-only-probe");
  const fs::path &base = folders.base, &meshes = folders.meshes, &writable = folders.writable;
  std::string out;
  folders.mesh("t.ply", 4000);
  folders.mesh("built.ply", 3000);
  ASSERT_EQ(raylod("build '" + (meshes / "built.ply").string() + "' -q", &out), 0) << out;
  const fs::path scene = write_scene("read-only-probe.json", 1.0, 48, 36);
  std::string why;
  const std::optional<std::string> unprivileged = as_unprivileged(writable, &why);
  if (!unprivileged) GTEST_SKIP() << why;
  const bool root = ::geteuid() == 0;
  if (!root) fs::permissions(meshes, fs::perms::owner_read | fs::perms::owner_exec);
  const fs::path cache = writable / "cache";
  auto probe = [&](const std::string& mesh) {
    const std::string cmd = *unprivileged + "env RAYLOD_CACHE_DIR='" + cache.string() + "' '" RAYLOD_EXE "' probe '" +
                            scene.string() + "' --mesh '" + (meshes / mesh).string() + "' --rays 300";
    const int rc = std::system((cmd + " > '" + (base / "log").string() + "' 2>&1").c_str());
    out = read(base / "log");
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  };
  auto cuts_in = [](const fs::path& dir, const std::string& mesh) {
    size_t n = 0;
    if (fs::is_directory(dir))
      for (const auto& e : fs::directory_iterator(dir))
        n += e.path().extension() == ".cut" && e.path().filename().string().rfind(mesh + ".", 0) == 0;
    return n;
  };
  const int fresh = probe("t.ply");
  const std::string fresh_out = out;
  const int built = probe("built.ply");
  if (!root) fs::permissions(meshes, fs::perms::owner_all);
  ASSERT_EQ(fresh, 0) << fresh_out;
  EXPECT_NE(fresh_out.find("is not writable: the store goes to " + (cache / "stores").string()), std::string::npos)
      << fresh_out;
  EXPECT_EQ(fresh_out.find("the cut goes to"), std::string::npos) << fresh_out;  // beside its store, in the cache
  ASSERT_EQ(built, 0) << out;
  EXPECT_NE(out.find(meshes.string() + " is not writable: the cut goes to " + (cache / "stores").string()),
            std::string::npos)
      << out;
  EXPECT_EQ(cuts_in(meshes, "t.ply") + cuts_in(meshes, "built.ply"), 0u);
  EXPECT_EQ(cuts_in(cache / "stores", "built.ply"), 1u);
  EXPECT_EQ(cuts_in(cache / "stores", "t.ply"), 1u);
}

TEST(Run, AReadOnlyCacheIsUsedAsItIs) {
  // A cache and a mesh folder this user may read but not write (shared by
  // others): a view the cache holds renders from it (its entry copied to
  // the temporary folder), and a store that is missing is built there too.
  // Found by a bug hunt: the cache hit failed with "Permission denied" and
  // the store build with "cannot create temporary file".
  const fs::path base = work_dir() / "read-only-cache";
  const fs::path meshes = base / "meshes", cache = base / "cache", writable = base / "writable";
  fs::create_directories(meshes);
  fs::create_directories(writable / "tmp");
  std::string out;
  ASSERT_EQ(raylod("gen teapot --triangles 4000 -q -o '" + (meshes / "t.ply").string() + "'", &out), 0) << out;
  const fs::path scene = write_scene("read-only-cache.json", 1.0, 48, 36);
  const std::string args = "run '" + scene.string() + "' --mesh '" + (meshes / "t.ply").string() +
                           "' --rays 300 --cache '" + cache.string() + "' -o ";
  ASSERT_EQ(raylod(args + "'" + (writable / "first.png").string() + "'", &out), 0) << out;
  for (const auto& e : fs::directory_iterator(meshes))
    if (e.path().filename() != "t.ply") fs::remove(e.path());  // the store: built again below
  std::string why;
  const std::optional<std::string> unprivileged = as_unprivileged(writable, &why);
  if (!unprivileged) GTEST_SKIP() << why;
  if (::geteuid() == 0) fs::permissions(writable / "tmp", fs::perms::all);
  const std::string prefix = *unprivileged + "env TMPDIR='" + (writable / "tmp").string() + "' ";
  const auto read_only = fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                         fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec;
  for (const fs::path& d : {meshes, cache, cache / "simplified"}) fs::permissions(d, read_only);
  const std::string cmd = prefix + "'" RAYLOD_EXE "' " + args + "'" + (writable / "second.png").string() + "'";
  const int rc = std::system((cmd + " > '" + (base / "log").string() + "' 2>&1").c_str());
  out = read(base / "log");
  for (const fs::path& d : {meshes, cache, cache / "simplified"}) fs::permissions(d, fs::perms::owner_all);
  ASSERT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << out;
  EXPECT_NE(out.find("cache hit"), std::string::npos) << out;
  EXPECT_NE(out.find("using its entries from the system's temporary folder"), std::string::npos) << out;
  EXPECT_NE(out.find("are not writable: the store goes to " + (writable / "tmp").string() + "/raylod-stores-"),
            std::string::npos)
      << out;
  EXPECT_EQ(read(writable / "second.png"), read(writable / "first.png"));
  EXPECT_FALSE(fs::exists(meshes / "t.ply.raylod"));
}

TEST(Run, MeshOptionStandsInForAMeshThatIsNotHere) {
  // A scene written elsewhere names a mesh this machine does not have; the
  // commands' --mesh replaces it, so nothing needs the missing file.
  std::string out;
  const fs::path mesh = work_dir() / "stand-in.ply";
  ASSERT_EQ(raylod("gen teapot --triangles 2000 -q -o '" + mesh.string() + "'", &out), 0) << out;
  const fs::path scene = work_dir() / "elsewhere.json";
  std::string text = read(write_scene("elsewhere.json", 1.0, 48, 36));
  const std::string generated = R"({"generate": "teapot", "triangles": 20000})";
  text.replace(text.find(generated), generated.size(), R"("/nowhere/on/this/machine.ply")");
  std::ofstream(scene) << text;
  EXPECT_EQ(raylod("render '" + scene.string() + "' -o '" + (work_dir() / "x.png").string() + "'", &out), 1);
  EXPECT_NE(out.find("objects[0].mesh: file not found: /nowhere/on/this/machine.ply"), std::string::npos) << out;
  EXPECT_EQ(raylod("render '" + scene.string() + "' --mesh '" + mesh.string() + "' -o '" +
                       (work_dir() / "stand-in-render.png").string() + "'",
                   &out),
            0)
      << out;
  EXPECT_EQ(raylod("run '" + scene.string() + "' --mesh '" + mesh.string() + "' --rays 200 --no-cache -q -o '" +
                       (work_dir() / "stand-in-run.png").string() + "'",
                   &out),
            0)
      << out;
  EXPECT_EQ(raylod("probe '" + scene.string() + "' --mesh '" + mesh.string() + "' --rays 200 -q -o '" +
                       (work_dir() / "stand-in.cut").string() + "'",
                   &out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(work_dir() / "stand-in-render.png"));
  EXPECT_TRUE(fs::exists(work_dir() / "stand-in-run.png"));
  EXPECT_TRUE(fs::exists(work_dir() / "stand-in.cut"));
}

TEST(Run, AMeshPlacedTwiceIsCountedOnceAndRenderedTwice) {
  // The summary's counts are the mesh's; the scene renders it at each
  // placement, and the summary says how many triangles that makes.
  std::string out;
  const fs::path mesh = work_dir() / "placed.ply";
  ASSERT_EQ(raylod("gen teapot --triangles 2000 -q -o '" + mesh.string() + "'", &out), 0) << out;
  const fs::path scene = work_dir() / "twice.json";
  std::ofstream(scene) << R"({"camera": {"eye": [6, 4, 8], "look_at": [0, 1, 0], "width": 64, "height": 48},
    "materials": {"m": {"type": "diffuse"}},
    "objects": [{"mesh": "placed.ply", "material": "m"},
                {"mesh": "placed.ply", "material": "m", "transform": {"translate": [0, 0, -5]}}],
    "lights": [{"type": "point", "position": [5, 9, 7], "intensity": 150}]})";
  ASSERT_EQ(raylod("run '" + scene.string() + "' --no-cache --rays 300 -o '" + (work_dir() / "twice.png").string() +
                       "' --stats-json '" + (work_dir() / "twice-stats.json").string() + "'",
                   &out),
            0)
      << out;
  const auto st = stats(work_dir() / "twice-stats.json");
  const uint64_t simplified = st["triangles_out"];
  EXPECT_NE(out.find("the scene places this mesh 2 times: " + std::to_string(2 * simplified) + " triangles rendered"),
            std::string::npos)
      << out;
}

TEST(Run, AViewFinerThanTheStoreGridIsWarnedAbout) {
  // A 0.001-degree view of the teapot's knob resolves 2.9e-6, finer than
  // the store's grid keeps positions (6.6e-6 for this mesh): said, with
  // what to do; an ordinary view says nothing of it.
  auto scene_at = [&](const std::string& name, double fov) {
    const fs::path p = work_dir() / name;
    std::ofstream(p) << R"({"camera": {"eye": [0, 3.15, 20], "look_at": [0, 3.15, 0], "fov_y": )" << fov
                     << R"(, "width": 160, "height": 120},
      "materials": {"m": {"type": "diffuse"}},
      "objects": [{"mesh": {"generate": "teapot", "triangles": 20000}, "material": "m"}],
      "lights": [{"type": "point", "position": [5, 9, 7], "intensity": 150}]})";
    return p;
  };
  std::string out;
  ASSERT_EQ(raylod("run '" + scene_at("zoom.json", 0.001).string() + "' --no-cache --rays 500 -o '" +
                       (work_dir() / "zoom.png").string() + "'",
                   &out),
            0)
      << out;
  EXPECT_NE(out.find("warning:"), std::string::npos) << out;
  EXPECT_NE(out.find("its store keeps positions to within"), std::string::npos) << out;
  EXPECT_NE(out.find("`raylod render` draws the mesh itself"), std::string::npos) << out;
  ASSERT_EQ(raylod("run '" + scene_at("whole.json", 30).string() + "' --no-cache --rays 500 -o '" +
                       (work_dir() / "whole.png").string() + "'",
                   &out),
            0)
      << out;
  EXPECT_EQ(out.find("its store keeps positions"), std::string::npos) << out;
}

TEST(Run, TheDefaultToleranceFollowsTheSamplesPerPixel) {
  // Above 4 spp the renderer's noise floor rises past what 0.5 px keeps
  // (a bug hunt's glossy teapot at 64 spp: 7.9 dB below it); the default
  // tolerance tightens with the spp the run renders at, and says so. An
  // explicit --tolerance is taken as given.
  const fs::path scene = write_scene("spp.json", 1.0, 64, 48);
  std::string out;
  auto triangles = [&](const std::string& extra, const std::string& tag) {
    return run_triangles(scene, "--rays 1000 " + extra, tag, out);
  };
  const uint64_t at4 = triangles("--spp 4", "spp4");
  EXPECT_EQ(out.find("tolerance"), std::string::npos) << out;
  const uint64_t at64 = triangles("--spp 64", "spp64");
  EXPECT_NE(out.find("tolerance 0.0625 px (0.5 fitted to 64 spp)"), std::string::npos) << out;
  EXPECT_GT(at64, at4);
  EXPECT_EQ(triangles("--spp 64 --tolerance 0.5", "spp64-given"), at4);
  EXPECT_NE(out.find("K = 64)"), std::string::npos) << out;  // 0.5 given: the default, not reported
}

TEST(Run, TheUnreachedAngleLoosensOnlyMirrorsAndGlass) {
  // --unreached-angle scales the turn that mirror and glass cells no test
  // ray reached may cause (probe.h): larger, a mirror teapot keeps fewer
  // triangles; on a glossy one, which bounds no turn, it changes nothing.
  const fs::path glossy = write_scene("unreached-glossy.json", 1.0, 96, 72);
  std::string text = read(glossy);
  const std::string from = R"("material": "p")";
  text.replace(text.find(from), from.size(), R"("material": "m")");
  const std::string mats = R"("materials": {)";
  text.replace(text.find(mats), mats.size(), mats + R"("m": {"type": "mirror", "reflectance": 0.9}, )");
  const fs::path mirror = work_dir() / "unreached-mirror.json";
  std::ofstream(mirror) << text;
  std::string out;
  auto triangles = [&](const fs::path& scene, const std::string& angle) {
    return run_triangles(scene, "--rays 500 --unreached-angle " + angle, scene.stem().string() + "-" + angle, out);
  };
  EXPECT_LT(triangles(mirror, "64"), triangles(mirror, "2"));
  EXPECT_EQ(triangles(glossy, "64"), triangles(glossy, "2"));
}

TEST(Run, BadSceneIsAClearError) {
  fs::path bad = work_dir() / "bad.json";
  std::ofstream(bad) << "{\"camera\": 3}";
  std::string out;
  EXPECT_EQ(raylod("run '" + bad.string() + "' -o '" + (work_dir() / "x.png").string() + "'", &out), 1);
  EXPECT_NE(out.find("bad.json"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(work_dir() / "x.png"));
}

TEST(Report, QuickWritesMarkdownPlotAndPictures) {
  fs::path dir = work_dir() / "report";
  std::string out;
  ASSERT_EQ(raylod("report --quick -q -o '" + dir.string() + "'", &out), 0) << out;
  std::string md = read(dir / "REPORT.md");
  EXPECT_NE(md.find("| raylod |"), std::string::npos);
  EXPECT_NE(md.find("| vertex clustering |"), std::string::npos);
  EXPECT_NE(md.find("| edge collapse |"), std::string::npos);
  EXPECT_NE(md.find("close-up view"), std::string::npos);
  // Each view in the layout of the paper's Table 1 (the paper's own columns
  // only for its bottle scene, not this teapot).
  EXPECT_NE(md.find("In the layout of the paper's Table 1"), std::string::npos) << md;
  EXPECT_NE(md.find("| preprocessing s (probe + simplify) | none |"), std::string::npos) << md;
  EXPECT_EQ(md.find("paper: method"), std::string::npos) << md;
  for (const char* f : {"default-accuracy-vs-time.png", "close-up-accuracy-vs-time.png", "default-cut.png",
                        "default-reference.png", "report.json"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  auto j = nlohmann::json::parse(read(dir / "report.json"));
  // A noise floor per view, printed before each table and judged per row.
  EXPECT_NE(md.find("Noise floor: PSNR"), std::string::npos) << md;
  EXPECT_NE(md.find("| vs noise floor |"), std::string::npos) << md;
  ASSERT_EQ(j["noise_floors"].size(), 2u) << j.dump(2);
  std::map<std::string, double> floors;
  for (const auto& f : j["noise_floors"]) {
    EXPECT_EQ(f["other_seed"].get<uint64_t>(), f["seed"].get<uint64_t>() + 1);
    // An identical floor (no noise at all) has a null PSNR: infinite.
    EXPECT_EQ(f["identical"].get<bool>(), f["psnr"].is_null()) << f.dump();
    floors[f["scene"].get<std::string>()] = f["psnr"].is_null() ? INFINITY : f["psnr"].get<double>();
  }
  EXPECT_EQ(floors.count("default"), 1u);
  EXPECT_EQ(floors.count("close-up"), 1u);
  // Every simplified row has a measured error and is judged against its
  // view's floor: a finite PSNR, or (in the almost noise-free close-up, where
  // a baseline can render the very same pixels) a null one with "identical":
  // true. A real simplification of the default view is not identical.
  for (const auto& row : j["rows"]) {
    if (row["method"] == "full mesh") continue;
    EXPECT_GT(row["triangles"].get<uint64_t>(), 0u) << row.dump();
    EXPECT_LT(row["triangles"].get<uint64_t>(), j["triangles"].get<uint64_t>()) << row.dump();
    ASSERT_TRUE(row["identical"].is_boolean()) << row.dump();
    if (row["identical"].get<bool>()) {
      EXPECT_TRUE(row["psnr"].is_null()) << row.dump();
      EXPECT_NE(row["scene"], "default") << row.dump();
      EXPECT_TRUE(row["within_noise_floor"].get<bool>()) << row.dump();
      continue;
    }
    ASSERT_TRUE(row["psnr"].is_number()) << row.dump();
    EXPECT_GT(row["psnr"].get<double>(), 10.0) << row.dump();
    EXPECT_EQ(row["within_noise_floor"].get<bool>(),
              row["psnr"].get<double>() >= floors[row["scene"].get<std::string>()])
        << row.dump();
  }
}

// The report's folder is written whole or not at all (AtomicDirectory): the
// tests below give it a folder of its own, REP in a scratch folder BASE, so
// that a temporary folder beside it (REP.tmp-...) shows in BASE.

// Every file under dir (relative path -> bytes).
std::map<std::string, std::string> files_in(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) {
      std::ifstream f(e.path(), std::ios::binary);
      std::stringstream ss;
      ss << f.rdbuf();
      out[fs::relative(e.path(), dir).string()] = ss.str();
    }
  return out;
}

// `report` of the two-triangle scene (a report of a fraction of a second):
// --quick's settings with one K and one ray count.
std::string pair_report(const fs::path& scene, const fs::path& dir, const std::string& extra = "") {
  return "report '" + scene.string() + "' --quick --scales 8 --rays 1000 -q " + extra + " -o '" + dir.string() + "'";
}

// The two-triangle scene `name` and a scratch folder holding its report
// folder (`dir`, not yet made): the setting of the tests of a report that
// replaces an earlier one.
struct ReportFolder {
  fs::path scene;
  raylod::test::ScratchDir base;
  fs::path dir;
  explicit ReportFolder(const std::string& name)
      : scene(write_pair_scene(name)), base("report-" + name), dir(base.path / "rep") {}
};

TEST(Report, ARerunWithFewerSectionsLeavesNoneOfTheFirstRunsFiles) {
  // Close-up and baselines, then neither: the second report's folder holds
  // its own files only (the close-up's and the baselines' pictures and the
  // close-up's .drc files used to stay beside it). The first run goes into
  // an empty folder that is already there.
  const ReportFolder folder("rerun");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  const raylod::test::ScratchDir& base = folder.base;
  fs::create_directories(dir);
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, dir), &out), 0) << out;
  const auto first = files_in(dir);
  auto has = [](const std::map<std::string, std::string>& files, const std::string& part) {
    for (const auto& [name, bytes] : files)
      if (name.find(part) != std::string::npos) return true;
    return false;
  };
  ASSERT_TRUE(has(first, "close-up-reference.png"));
  ASSERT_TRUE(has(first, "meshes/close-up-"));
  ASSERT_TRUE(has(first, "edge-collapse"));
  ASSERT_TRUE(has(first, "vertex-clustering"));

  ASSERT_EQ(raylod(pair_report(scene, dir, "--no-closeup --no-baselines"), &out), 0) << out;
  const auto second = files_in(dir);
  for (const char* part : {"close-up", "edge-collapse", "vertex-clustering"}) EXPECT_FALSE(has(second, part)) << part;
  // Every file is one the second report names: a picture in REPORT.md or
  // report.json, a mesh of the default view.
  const std::string md = read(dir / "REPORT.md"), json = read(dir / "report.json");
  for (const auto& [name, bytes] : second) {
    if (name == "REPORT.md" || name == "report.json" || name == "report-files.txt") continue;
    if (name.rfind("meshes/", 0) == 0) {
      EXPECT_EQ(name.rfind("meshes/default-raylod-", 0), 0u) << name;
      continue;
    }
    EXPECT_TRUE(md.find("(" + name + ")") != std::string::npos || json.find('"' + name + '"') != std::string::npos)
        << name << " is in the folder but not in the report";
  }
  EXPECT_EQ(names_in(base.path), std::vector<std::string>{"rep"}) << "a temporary folder was left beside it";
}

TEST(Report, AFileOfTheUsersInAnEarlierReportKeepsItFromBeingReplaced) {
  // An earlier report is replaced whole, so a file put into it afterwards
  // (a note, the scene the new report reads: both were deleted by the swap)
  // makes it a folder of other files, refused before any work; without
  // them it is replaced again.
  const ReportFolder folder("manifest");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  const raylod::test::ScratchDir& base = folder.base;
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, dir), &out), 0) << out;
  ASSERT_TRUE(fs::exists(dir / "report-files.txt"));
  std::ofstream(dir / "notes.txt") << "mine";
  fs::copy_file(scene, dir / "scene.json");
  fs::create_directories(dir / "meshes" / "extra");
  for (const char* mine : {"notes.txt", "scene.json", "meshes/extra/"}) {
    const auto before = files_in(dir);
    EXPECT_EQ(raylod(pair_report(scene, dir), &out), 1) << out;
    EXPECT_NE(out.find("holds files that are not a raylod report's"), std::string::npos) << out;
    EXPECT_TRUE(files_in(dir) == before) << mine;
    fs::remove_all(dir / mine);
  }
  ASSERT_EQ(raylod(pair_report(scene, dir), &out), 0) << out;
  EXPECT_EQ(names_in(base.path), std::vector<std::string>{"rep"});
}

TEST(Report, ASymlinkToAFolderNotYetMadeIsFollowedAndAReplacedFolderKeepsItsMode) {
  // -o a symlink whose folder does not exist yet: the report is made where
  // it points and the link stays (it was replaced by the report's folder).
  // A report replacing an earlier one keeps that folder's permissions
  // (they became the umask's).
  const ReportFolder folder("symlink");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  const fs::path link = folder.base.path / "latest";
  fs::create_symlink("rep", link);
  ASSERT_FALSE(fs::exists(dir));
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, link), &out), 0) << out;
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(link)));
  EXPECT_TRUE(fs::is_directory(dir));
  EXPECT_TRUE(fs::exists(dir / "REPORT.md"));
  fs::permissions(dir, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec);
  ASSERT_EQ(raylod(pair_report(scene, link), &out), 0) << out;
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(link)));
  EXPECT_EQ(fs::status(dir).permissions() & fs::perms::all,
            fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec);
  EXPECT_EQ(names_in(folder.base.path), (std::vector<std::string>{"latest", "rep"}));
}

TEST(Report, AFailureMidwayLeavesTheEarlierReportAsItWas) {
  // The second report (another image size: every picture differs) fails
  // after its pictures are written, before its tables (a fault point): the
  // first report stays, byte for byte, and no temporary folder is left.
  const ReportFolder folder("midway");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  const raylod::test::ScratchDir& base = folder.base;
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, dir), &out), 0) << out;
  const auto before = files_in(dir);
  ASSERT_EQ(before.count("REPORT.md"), 1u);
  EXPECT_NE(raylod(pair_report(scene, dir, "--width 40 --height 30"), &out, "RAYLOD_FAULT_POINT=report.files:error"), 0)
      << out;
  EXPECT_NE(out.find("fault point report.files"), std::string::npos) << out;
  EXPECT_TRUE(files_in(dir) == before) << "the earlier report was changed";
  EXPECT_EQ(names_in(base.path), std::vector<std::string>{"rep"}) << "a temporary folder was left beside it";
}

TEST(Report, AKilledReportLeavesTheEarlierOneAndTheNextRunClearsUp) {
  // Killed outright (SIGKILL, no clean-up) at the same point: the earlier
  // report stays as it was, beside the killed run's temporary folder, which
  // the next report to the same folder removes.
  const ReportFolder folder("killed");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  const raylod::test::ScratchDir& base = folder.base;
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, dir), &out), 0) << out;
  const auto before = files_in(dir);
  EXPECT_NE(raylod(pair_report(scene, dir, "--width 40 --height 30"), &out, "RAYLOD_FAULT_POINT=report.files"), 0)
      << out;
  EXPECT_NE(out.find("fault point report.files: SIGKILL"), std::string::npos) << out;
  EXPECT_TRUE(files_in(dir) == before) << "the earlier report was changed";
  const auto left = names_in(base.path);
  ASSERT_EQ(left.size(), 2u);
  EXPECT_EQ(left[1].rfind("rep.tmp-", 0), 0u) << left[1];
  ASSERT_EQ(raylod(pair_report(scene, dir, "--width 40 --height 30"), &out), 0) << out;
  EXPECT_EQ(names_in(base.path), std::vector<std::string>{"rep"});
  EXPECT_NE(files_in(dir).at("default-reference.png"), before.at("default-reference.png"));
}

TEST(Report, AFolderOfOtherFilesIsRefusedBeforeAnyWork) {
  // A report replaces its whole folder, so a folder that holds anything but
  // an earlier report (here a note, and a REPORT.md of the user's own) is
  // refused at once, naming it: nothing is built, written or removed.
  const fs::path scene = write_pair_scene("refused");
  raylod::test::ScratchDir base("report-refused");
  const fs::path notes = base.path / "notes", own = base.path / "own";
  fs::create_directories(notes);
  fs::create_directories(own);
  std::ofstream(notes / "notes.txt") << "mine";
  std::ofstream(own / "REPORT.md") << "# my report\n";
  std::ofstream(own / "report.json") << "{}\n";
  for (const fs::path& dir : {notes, own}) {
    const auto before = files_in(dir);
    std::string out;
    EXPECT_EQ(raylod("report '" + scene.string() + "' --quick -o '" + dir.string() + "'", &out), 1) << out;
    EXPECT_NE(out.find(dir.string() + ": the report folder (-o) holds files that are not a raylod report"),
              std::string::npos)
        << out;
    EXPECT_EQ(out.find("building store"), std::string::npos) << out;
    EXPECT_EQ(out.find("reference render"), std::string::npos) << out;
    EXPECT_TRUE(files_in(dir) == before);
  }
  // Nor the folder the shell stands in, or one above it, though empty or
  // an earlier report: replaced whole, it would leave the shell in a
  // removed folder.
  const fs::path empty = base.path / "empty";
  fs::create_directories(empty / "inner");
  for (const auto& [from, target] : {std::pair{empty, std::string(".")}, std::pair{empty / "inner", std::string("..")}}) {
    std::string out;
    EXPECT_EQ(raylod_in(from, "report '" + scene.string() + "' --quick -o " + target, &out), 1) << out;
    EXPECT_NE(out.find(target + ": the report folder (-o) is the current folder or holds it"), std::string::npos) << out;
  }
  EXPECT_TRUE(fs::is_directory(empty / "inner"));
  EXPECT_FALSE(fs::exists(work_dir() / "refused.stl.raylod")) << "a store was built for a refused report";
  EXPECT_EQ(names_in(base.path), (std::vector<std::string>{"empty", "notes", "own"}));
}

// The cells of a REPORT.md table row ("| a | b |" -> {"a", "b"}).
std::vector<std::string> cells(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line.substr(1));
  std::string cell;
  while (std::getline(ss, cell, '|')) {
    const size_t a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
    out.push_back(a == std::string::npos ? "" : cell.substr(a, b - a + 1));
  }
  return out;
}

TEST(Report, ABaselineEqualToTheReferenceIsIdenticalNotTheReference) {
  // Two triangles: quadric edge collapse driven to raylod's count (both of
  // them) leaves the mesh as it is, and its image equals the reference's.
  // Only the full mesh's row says "reference"; that one says "identical",
  // and report.json has a null PSNR and "identical": true for it (not 999).
  const ReportFolder folder("identical");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, dir, "--no-closeup"), &out), 0) << out;
  const std::string md = read(dir / "REPORT.md");
  const auto j = nlohmann::json::parse(read(dir / "report.json"));
  size_t identical = 0;
  for (const auto& row : j["rows"]) {
    EXPECT_TRUE(row["psnr"].is_null() || row["psnr"].get<double>() < 999.0) << row.dump();
    if (row["method"] == "full mesh") {
      EXPECT_TRUE(row["psnr"].is_null()) << row.dump();
      EXPECT_FALSE(row.contains("identical")) << row.dump();
      continue;
    }
    ASSERT_TRUE(row.contains("identical")) << row.dump();
    EXPECT_EQ(row["identical"].get<bool>(), row["psnr"].is_null()) << row.dump();
    if (row["identical"].get<bool>()) ++identical;
  }
  bool seen_edge_collapse = false;
  std::istringstream lines(md);
  std::string line;
  size_t identical_cells = 0;
  while (std::getline(lines, line)) {
    if (line.rfind("| ", 0) != 0) continue;
    const std::vector<std::string> c = cells(line);
    if (c.size() != 14) continue;  // the view's table: PSNR dB is the 11th column
    EXPECT_EQ(c[10] == "reference", c[0] == "full mesh") << line;
    if (c[0] == "edge collapse") {
      seen_edge_collapse = true;
      EXPECT_EQ(c[10], "identical") << line;
    }
    identical_cells += c[10] == "identical";
  }
  EXPECT_TRUE(seen_edge_collapse) << md;
  EXPECT_GE(identical, 1u) << j.dump(2);
  EXPECT_EQ(identical_cells, identical) << md;
}

// Kills and reaps a child left running by a failed test.
struct ChildGuard {
  pid_t pid = -1;
  ~ChildGuard() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      int status = 0;
      ::waitpid(pid, &status, 0);
    }
  }
};

TEST(Report, CtrlCLeavesTheEarlierReportAndNoTemporaryFolder) {
  // Ctrl-C (SIGINT) while a report is under way, once its first picture is
  // written: the earlier report stays as it was (its pictures used to be
  // replaced one by one, leaving a REPORT.md that did not match them), and
  // the interrupted run's folder goes with it. raylod is spawned with SIGINT
  // at its default action (a shell's background job would ignore it).
  const ReportFolder folder("interrupted");
  const fs::path &scene = folder.scene, &dir = folder.dir;
  const raylod::test::ScratchDir& base = folder.base;
  std::string out;
  ASSERT_EQ(raylod(pair_report(scene, dir), &out), 0) << out;
  const auto before = files_in(dir);
  // The default scene's teapot: long enough to be interrupted.
  const fs::path log = work_dir() / "interrupted.log";
  std::vector<std::string> args = {RAYLOD_EXE, "report", "--quick", "--no-baselines", "-o", dir.string()};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_strings = {"RAYLOD_CACHE_DIR=" + (work_dir() / "cache").string()};
  for (char** e = environ; *e; ++e)
    if (std::strncmp(*e, "RAYLOD_CACHE_DIR=", 17) != 0 && std::strncmp(*e, "RAYLOD_FAULT_POINT=", 19) != 0)
      env_strings.push_back(*e);
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  posix_spawnattr_setsigdefault(&attr, &signals);
  sigemptyset(&signals);
  posix_spawnattr_setsigmask(&attr, &signals);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  ChildGuard child;
  const int spawned = posix_spawn(&child.pid, RAYLOD_EXE, &actions, &attr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ASSERT_EQ(spawned, 0) << std::strerror(spawned);
  // Wait for a picture in the temporary folder beside the report's.
  bool seen = false;
  int status = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
  while (!seen && std::chrono::steady_clock::now() < deadline) {
    if (::waitpid(child.pid, &status, WNOHANG) == child.pid) {
      child.pid = -1;
      break;
    }
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(base.path, ec))
      if (e.path().filename().string().rfind("rep.tmp-", 0) == 0 && fs::exists(e.path() / "default-reference.png"))
        seen = true;
    if (!seen) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(seen) << "no picture in a temporary folder beside " << dir << "\n" << read(log);
  ASSERT_EQ(::kill(child.pid, SIGINT), 0);
  ASSERT_EQ(::waitpid(child.pid, &status, 0), child.pid);
  child.pid = -1;
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << "status " << status << "\n" << read(log);
  EXPECT_TRUE(files_in(dir) == before) << "the earlier report was changed";
  EXPECT_EQ(names_in(base.path), std::vector<std::string>{"rep"}) << "a temporary folder was left beside it";
}

}  // namespace
