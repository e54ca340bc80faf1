// `raylod run --width W --height H` renders at that size without editing the
// scene, as `raylod render` does; the views of --orbit take it as theirs.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in, nullptr, false);
}

TEST(RunSizeOption, WidthAndHeightOverrideTheScenesCamera) {
  test::ScratchDir dir("run-size");
  const std::string mesh = (dir.path / "t.ply").string(), scene = (dir.path / "t.json").string();
  std::string out;
  ASSERT_EQ(test::run_raylod("gen teapot --triangles 3000 -o " + mesh + " -q", out), 0) << out;
  ASSERT_EQ(test::run_raylod("scene " + mesh + " -o " + scene + " --width 64 --height 48 --spp 1 -q", out), 0) << out;
  ASSERT_EQ(test::run_raylod("run " + scene + " --rays 300 --no-cache --width 40 --height 30 -o " +
                                 (dir.path / "r.png").string() + " --stats-json " + (dir.path / "r.json").string() + " -q",
                             out),
            0)
      << out;
  const nlohmann::json one = read_json(dir.path / "r.json");
  EXPECT_EQ(one["render"]["width"], 40) << one.dump();
  EXPECT_EQ(one["render"]["height"], 30) << one.dump();
  ASSERT_EQ(test::run_raylod("run " + scene + " --rays 300 --no-cache --width 32 --orbit 2 -o " +
                                 (dir.path / "v_#.png").string() + " --stats-json " + (dir.path / "v.json").string() +
                                 " -q",
                             out),
            0)
      << out;
  const nlohmann::json views = read_json(dir.path / "v.json");
  ASSERT_EQ(views["views"].size(), 2u) << views.dump();
  for (const auto& v : views["views"]) {
    EXPECT_EQ(v["render"]["width"], 32) << v.dump();
    EXPECT_EQ(v["render"]["height"], 48) << v.dump();
  }
  // Out of range: refused before any work, naming the option.
  const test::CommandResult bad = test::run_command(std::string(RAYLOD_EXE) + " run " + scene + " --width 0 -o " +
                                                    (dir.path / "bad.png").string() + " -q");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.out.find("--width"), std::string::npos) << bad.out;
  EXPECT_FALSE(fs::exists(dir.path / "bad.png"));
}

}  // namespace
}  // namespace raylod
