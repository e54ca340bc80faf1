// Fault injection (core/fault_point.h): `raylod build` and `raylod run` are
// killed with SIGKILL at named points (RAYLOD_FAULT_POINT), then the same
// command is run again. The rerun must succeed, use nothing partial (its
// image is byte-identical to a run in a clean folder, and its store passes
// `raylod build --verify` without a rebuild) and leave no orphans (no
// temporaries anywhere under the mesh's folder or the cache, and the same
// files as the clean run). Each point is its own test case (ctest process).
//
// raylod runs as a subprocess through popen (never fork() here: OpenImageIO
// threads in this process could deadlock a forked child), under `exec env`
// so that the wait status is raylod's own and a SIGKILL shows as one.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <vector>

#include "test_tmp.h"

namespace {

namespace fs = std::filesystem;

// A generated teapot: 40,000 triangles make a store of 8 pages (the build
// can be killed mid-way through them) and a run of a fraction of a second.
const char* const kMesh = "teapot.ply";

struct Outcome {
  int status = -1;  // raw wait status
  std::string out;  // stdout and stderr
};

std::string quote(const fs::path& p) { return "'" + p.string() + "'"; }

// Runs raylod with RAYLOD_FAULT_POINT set to `fault` (unset if empty).
Outcome raylod(const std::string& args, const std::string& fault = "") {
  const std::string env = fault.empty() ? "env -u RAYLOD_FAULT_POINT" : "env RAYLOD_FAULT_POINT=" + fault;
  const std::string cmd = "exec " + env + " " + quote(RAYLOD_EXE) + " " + args + " 2>&1";
  Outcome r;
  std::FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  r.status = ::pclose(p);
  return r;
}

bool exited_ok(const Outcome& r) { return r.status != -1 && WIFEXITED(r.status) && WEXITSTATUS(r.status) == 0; }
bool killed(const Outcome& r) { return r.status != -1 && WIFSIGNALED(r.status) && WTERMSIG(r.status) == SIGKILL; }

std::string describe(const Outcome& r) {
  std::string how = r.status == -1          ? "could not run"
                    : WIFEXITED(r.status)   ? "exit " + std::to_string(WEXITSTATUS(r.status))
                    : WIFSIGNALED(r.status) ? "signal " + std::to_string(WTERMSIG(r.status))
                                            : "status " + std::to_string(r.status);
  return how + "\n" + r.out;
}

std::string read_bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

// Every file under dir, relative, sorted, with cache keys (their store hash
// names the mesh's path and mtime, so they differ between folders) as KEY.
std::vector<std::string> files_under(const fs::path& dir) {
  static const std::regex key("[0-9a-f]{8}-[0-9a-f]{16}");
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (!e.is_directory()) out.push_back(std::regex_replace(fs::relative(e.path(), dir).string(), key, "KEY"));
  std::sort(out.begin(), out.end());
  return out;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += "  " + x + "\n";
  return s;
}

// A folder with a copy of the mesh, a tiny scene (the default scene's view
// at 96 x 72, 1 spp) and the commands on them; the cache is inside it too,
// so nothing touches the user's cache.
struct Workspace {
  fs::path dir;
  Workspace(const fs::path& d, const fs::path& mesh) : dir(d) {
    fs::create_directories(dir);
    fs::copy_file(mesh, dir / kMesh);
    std::ofstream(dir / "scene.json") << R"({
      "camera": {"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0.0], "up": [0, 1, 0],
                 "fov_y": 34, "width": 96, "height": 72},
      "materials": {"porcelain": {"type": "glossy", "color": [0.72, 0.12, 0.10], "specular": [0.45, 0.45, 0.45],
                                  "shininess": 80},
                    "floor": {"type": "diffuse", "color": [0.70, 0.70, 0.68]}},
      "objects": [{"mesh": "teapot.ply", "material": "porcelain"}],
      "ground": {"height": 0.0, "size": 200.0, "material": "floor"},
      "lights": [{"type": "point", "position": [6, 10, 6], "intensity": 160}],
      "background": [0.62, 0.72, 0.85], "spp": 1, "max_depth": 3, "seed": 1})";
  }
  fs::path image() const { return dir / "out.png"; }
  std::string build() const { return "build -q " + quote(dir / kMesh); }
  std::string run() const {
    return "run -q " + quote(dir / "scene.json") + " -o " + quote(image()) + " --cache " + quote(dir / "cache") +
           " --rays 400";
  }
};

enum class Command { Build, Run };

struct FaultCase {
  const char* point;
  Command command;
  // A file (substring of its path under the workspace) the kill must leave
  // behind: proof that it came at a moment with something partial on disk.
  const char* leftover;
};

std::ostream& operator<<(std::ostream& os, const FaultCase& c) {
  return os << c.point << (c.command == Command::Build ? " (build)" : " (run)");
}

class FaultInjection : public ::testing::TestWithParam<FaultCase> {};

TEST_P(FaultInjection, NextRunUsesNothingPartialAndLeavesNoOrphans) {
  const FaultCase& fc = GetParam();
  // Folders of this case's own (all cases may run in one process).
  const fs::path scratch = raylod::test::scratch_dir("fault-injection") /
                           ::testing::UnitTest::GetInstance()->current_test_info()->name();
  fs::remove_all(scratch);
  fs::create_directories(scratch);

  const fs::path mesh = scratch / kMesh;
  const Outcome gen = raylod("gen teapot -q -n 40000 -o " + quote(mesh));
  ASSERT_TRUE(exited_ok(gen)) << describe(gen);

  // The reference: the same run in a clean folder.
  const Workspace ref(scratch / "reference", mesh);
  const Outcome ref_run = raylod(ref.run());
  ASSERT_TRUE(exited_ok(ref_run)) << describe(ref_run);
  const std::string ref_image = read_bytes(ref.image());
  ASSERT_FALSE(ref_image.empty());
  if (std::string(fc.point) == "build.pages") {  // mid-way through several pages, not after the only one
    const Outcome info = raylod("info " + quote(ref.dir / (std::string(kMesh) + ".raylod")));
    ASSERT_TRUE(exited_ok(info)) << describe(info);
    EXPECT_NE(info.out.find("  pages         8,"), std::string::npos) << info.out;
  }

  const Workspace ws(scratch / "work", mesh);
  const std::string command = fc.command == Command::Build ? ws.build() : ws.run();
  const fs::path store = ws.dir / (std::string(kMesh) + ".raylod");

  // Killed at the point: SIGKILL, and nothing under a final name that the
  // point comes before.
  const Outcome faulted = raylod(command, fc.point);
  ASSERT_TRUE(killed(faulted)) << "expected SIGKILL at " << fc.point << ", got " << describe(faulted);
  EXPECT_NE(faulted.out.find(std::string("raylod: fault point ") + fc.point + ": SIGKILL"), std::string::npos)
      << faulted.out;
  EXPECT_FALSE(fs::exists(ws.image())) << "the killed run has no image";
  if (std::string(fc.point).rfind("build.", 0) == 0) {
    EXPECT_FALSE(fs::exists(store)) << "the killed build has no store";
  }
  if (*fc.leftover) {
    const std::vector<std::string> left = files_under(ws.dir);
    EXPECT_TRUE(std::any_of(left.begin(), left.end(),
                            [&](const std::string& f) { return f.find(fc.leftover) != std::string::npos; }))
        << "expected the kill to leave a file matching '" << fc.leftover << "'; left:\n" << join(left);
    if (std::string(fc.point) == "cache.before_meta") {
      EXPECT_EQ(std::count(left.begin(), left.end(), "cache/simplified/KEY.json"), 0) << join(left);
    }
  }

  // The same command again, without the fault; a build is followed by the run.
  const Outcome again = raylod(command);
  ASSERT_TRUE(exited_ok(again)) << describe(again);
  if (fc.command == Command::Build) {
    const Outcome then = raylod(ws.run());
    ASSERT_TRUE(exited_ok(then)) << describe(then);
  }
  ASSERT_TRUE(fs::exists(ws.image()));
  EXPECT_TRUE(read_bytes(ws.image()) == ref_image) << "the image after the kill differs from the clean run's";

  // No orphans: no temporaries anywhere, and the same files as the clean run.
  const std::vector<std::string> files = files_under(ws.dir);
  for (const auto& f : files) {
    EXPECT_EQ(f.find(".tmp-"), std::string::npos) << "temporary left behind: " << f;
    EXPECT_EQ(f.find(".runs-"), std::string::npos) << "build runs file left behind: " << f;
  }
  // A store's .checked record (source_record.h) is written only for a mesh
  // unchanged for a second before its hash was read, so whether a run leaves
  // one depends on how fast the runs came: it is not compared.
  auto comparable = [](std::vector<std::string> v) {
    std::erase_if(v, [](const std::string& f) { return f.ends_with(".raylod.checked"); });
    return v;
  };
  EXPECT_EQ(comparable(files), comparable(files_under(ref.dir)))
      << "after the kill and rerun:\n" << join(files) << "clean run:\n" << join(files_under(ref.dir));

  // The store is whole: every page's checksum matches, and it is not rebuilt.
  const Outcome verify = raylod("build --verify " + quote(ws.dir / kMesh));
  ASSERT_TRUE(exited_ok(verify)) << describe(verify);
  EXPECT_NE(verify.out.find("nothing to do"), std::string::npos) << verify.out;
}

INSTANTIATE_TEST_SUITE_P(
    Points, FaultInjection,
    ::testing::Values(FaultCase{"build.binned", Command::Build, ""},
                      FaultCase{"build.pages", Command::Build, "teapot.ply.raylod.tmp-"},
                      FaultCase{"build.before_rename", Command::Build, "teapot.ply.raylod.tmp-"},
                      FaultCase{"build.pages", Command::Run, "teapot.ply.raylod.tmp-"},
                      FaultCase{"cut.before_rename", Command::Run, "cache/simplified/KEY.cut.tmp-"},
                      FaultCase{"draco.partial", Command::Run, ".drc.tmp-"},
                      FaultCase{"cache.before_meta", Command::Run, "cache/simplified/KEY.drc"},
                      FaultCase{"run.render", Command::Run, "cache/simplified/simplified-"},
                      FaultCase{"image.before_rename", Command::Run, "out.png.tmp-"}),
    [](const ::testing::TestParamInfo<FaultCase>& p) {
      std::string name = p.param.point;
      std::replace(name.begin(), name.end(), '.', '_');
      return name + (p.param.command == Command::Build ? "_Build" : "_Run");
    });

}  // namespace
