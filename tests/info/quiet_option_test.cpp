// -q / --quiet means the same on every command that takes it: no progress
// bars, log lines or summary, only errors and warnings. Runs the raylod
// executable through the whole pipeline on a small generated teapot.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

struct Step {
  std::string name;
  std::string args;
};

// Every command that writes something, in pipeline order, each reading what
// the one before wrote.
std::vector<Step> pipeline_steps(const fs::path& d) {
  const std::string mesh = (d / "t.ply").string();
  const std::string store = (d / "t.raylod").string();
  const std::string scene = (d / "t.json").string();
  const std::string cut = (d / "t.cut").string();
  const std::string drc = (d / "t.drc").string();
  return {{"gen", "gen teapot --triangles 3000 -o " + mesh},
          {"build", "build " + mesh + " -o " + store + " --force"},
          {"scene", "scene " + mesh + " -o " + scene + " --width 64 --height 48 --spp 1"},
          {"probe", "probe " + scene + " --mesh " + mesh + " --rays 300 -o " + cut},
          {"simplify", "simplify " + mesh + ".raylod " + cut + " -o " + drc},
          {"render", "render " + scene + " --mesh " + drc + " -o " + (d / "r.png").string()},
          {"run", "run " + scene + " --rays 300 --no-cache --compare -o " + (d / "run.png").string() +
                      " --stats-json " + (d / "run.json").string()}};
}

TEST(QuietOption, EveryCommandPrintsNothingUnderQuietAndItsSummaryWithout) {
  for (const bool quiet : {false, true}) {
    test::ScratchDir dir(quiet ? "quiet-q" : "quiet-loud");
    for (const Step& s : pipeline_steps(dir.path)) {
      std::string out;
      ASSERT_EQ(test::run_raylod(s.args + (quiet ? " -q" : ""), out), 0) << s.args << "\n" << out;
      if (quiet)
        EXPECT_EQ(out, "") << s.name << " -q printed something";
      else
        EXPECT_NE(out, "") << s.name << " printed no summary";
    }
    // The files are written either way, --compare's with them.
    for (const char* f : {"t.ply", "t.json", "t.cut", "t.drc", "r.png", "run.png", "run.full.png", "run.diff.png"})
      EXPECT_TRUE(fs::exists(dir.path / f)) << f;
    std::ifstream stats(dir.path / "run.json");
    const std::string json((std::istreambuf_iterator<char>(stats)), std::istreambuf_iterator<char>());
    EXPECT_NE(json.find("\"noise_floor\""), std::string::npos) << json;
  }
}

TEST(QuietOption, WarningsAndErrorsStillShow) {
  test::ScratchDir dir("quiet-warn");
  const std::string mesh = (dir.path / "w.obj").string();
  std::ofstream(mesh) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string scene = (dir.path / "w.json").string();
  const std::string cut = (dir.path / "w.cut").string();
  std::string out;
  ASSERT_EQ(test::run_raylod("scene " + mesh + " -o " + scene + " --width 32 --height 24 -q", out), 0) << out;
  ASSERT_EQ(test::run_raylod("probe " + scene + " --rays 100 -o " + cut + " -q", out), 0) << out;
  ASSERT_EQ(out, "");
  // A position error floats cannot meet is a warning, shown under -q.
  ASSERT_EQ(test::run_raylod("simplify " + mesh + ".raylod " + cut + " -o " + (dir.path / "w.drc").string() +
                                 " --position-error 1e-15 -q",
                             out),
            0);
  EXPECT_NE(out.find("raylod simplify: warning: --position-error 1e-15 cannot be met"), std::string::npos) << out;
  // And render's (its log was off under -q, warnings with it): a mesh of
  // degenerate triangles only.
  const std::string flat = (dir.path / "flat.obj").string();
  std::ofstream(flat) << "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
  ASSERT_EQ(test::run_raylod("render " + scene + " --mesh " + flat + " -o " + (dir.path / "f.png").string() + " -q", out),
            0)
      << out;
  EXPECT_NE(out.find("raylod render: warning: " + flat + ": all 1 triangles are degenerate"), std::string::npos) << out;
  out.clear();
  EXPECT_EQ(test::run_raylod("render " + (dir.path / "missing.json").string() + " -o " +
                                 (dir.path / "x.png").string() + " -q",
                             out),
            1);
  EXPECT_NE(out.find("raylod render: error: "), std::string::npos) << out;
  EXPECT_NE(out.find("missing.json"), std::string::npos) << out;
}

}  // namespace
}  // namespace raylod
