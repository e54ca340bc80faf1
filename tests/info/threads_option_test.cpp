// --threads: main() sets the thread count once for the whole command (one
// tbb::global_control); the stages use that ambient parallelism and report
// it. Runs the raylod executable (this folder's tests may).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

int run(const std::string& args, std::string& out) { return test::run_raylod(args, out); }

struct Tiny {
  fs::path dir = test::scratch_dir("threads-option");
  fs::path mesh = dir / "tri.obj";
  Tiny() { std::ofstream(mesh) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"; }
  std::string render(const std::string& threads) const {
    return "render --mesh " + mesh.string() + " --spp 1 -o " + (dir / "tri.png").string() + " " + threads;
  }
};

TEST(ThreadsOption, TheRenderRunsWithTheCountGiven) {
  const Tiny t;
  for (const char* given : {"--threads 1", "--threads=1", "--threads 2 --threads 1"}) {
    std::string out;
    ASSERT_EQ(run(t.render(given), out), 0) << given << "\n" << out;
    EXPECT_NE(out.find("1 spp, 1 threads)"), std::string::npos) << given << "\n" << out;
  }
  std::string out;  // 0, like no --threads at all, is every core
  ASSERT_EQ(run(t.render("--threads 0"), out), 0) << out;
  EXPECT_EQ(out.find("1 spp, 0 threads)"), std::string::npos) << out;
}

TEST(ThreadsOption, BadValuesFailTheCommandNamingTheOption) {
  const Tiny t;
  const std::pair<const char*, const char*> bad[] = {
      {"--threads abc", "raylod render: error: --threads: 'abc' is not an integer"},
      {"--threads -1", "raylod render: error: --threads must be between 0 and 4096"},
      {"--threads 5000", "raylod render: error: --threads must be between 0 and 4096"},
      {"--threads", "raylod render: error: option --threads needs a value"}};
  for (const auto& [given, expected] : bad) {
    std::string out;
    EXPECT_EQ(run(t.render(given), out), 1) << given << "\n" << out;
    EXPECT_NE(out.find(expected), std::string::npos) << given << "\n" << out;
  }
  for (const char* command : {"build", "probe", "run", "report"}) {  // one parser for every command
    std::string out;
    EXPECT_EQ(run(std::string(command) + " --threads x", out), 1) << command << "\n" << out;
    EXPECT_NE(out.find(std::string("raylod ") + command + ": error: --threads: 'x' is not an integer"),
              std::string::npos) << out;
  }
}

}  // namespace
}  // namespace raylod
