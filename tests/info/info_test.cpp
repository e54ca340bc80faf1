// `raylod info` end to end: runs the raylod executable on meshes in data/ and
// on bad files, and checks the output and the exit status.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "geometry/crease_normals.h"
#include "run_command.h"
#include "test_tmp.h"

namespace {

using raylod::test::CommandResult;

// timeout_s > 0 runs raylod under timeout(1), which exits with 124 if it hangs.
CommandResult run(const std::string& args, int timeout_s = 0) {
  const std::string limit = timeout_s > 0 ? "timeout " + std::to_string(timeout_s) + " " : "";
  return raylod::test::run_command(limit + std::string(RAYLOD_EXE) + " " + args);
}

std::filesystem::path scratch() {
  return raylod::test::scratch_dir("info-test");
}

// Removes this process's scratch directory after the last test.
class RemoveScratch : public ::testing::Environment {
  void TearDown() override { std::filesystem::remove_all(scratch()); }
};
const auto* const kRemoveScratch = ::testing::AddGlobalTestEnvironment(new RemoveScratch);

TEST(Info, DescribesABinaryStl) {
  const CommandResult info = run("info " + std::string(RAYLOD_DATA_DIR) + "/abc/abc5.stl");
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("format:     STL (binary)"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("triangles:  5080\n"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("vertices:   15240"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("normals:    no"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("bytes:      254084"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("bounds:     min ("), std::string::npos) << info.out;
}

TEST(Info, DescribesAnAsciiPlyWithNormals) {
  const auto path = scratch() / "tri.ply";
  std::ofstream(path) << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                         "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
                         "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                         "0 0 0 0 0 1\n2 0 0 0 0 1\n2 3 0 0 0 1\n0 3 -1 0 0 1\n4 0 1 2 3\n";
  const CommandResult info = run("info " + path.string());
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("format:     PLY (ascii)"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("triangles:  2\n"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("vertices:   4\n"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("faces:      1 (polygons"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("min (0, 0, -1)"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("max (2, 3, 0)"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("normals:    yes"), std::string::npos) << info.out;
}

TEST(Info, BadFilesFailWithTheFileNamed) {
  const std::string broken = std::string(RAYLOD_DATA_DIR) + "/stl-models/broken/notANumberNormal.ascii.stl";
  CommandResult r = run("info " + broken);
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("raylod info: error: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("notANumberNormal.ascii.stl: line 9: facet normal is not finite"), std::string::npos) << r.out;
  r = run("info " + (scratch() / "missing.ply").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("missing.ply: no such file"), std::string::npos) << r.out;
  const auto txt = scratch() / "notes.txt";
  std::ofstream(txt) << "hello\n";
  r = run("info " + txt.string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("unknown mesh format '.txt'"), std::string::npos) << r.out;
  // A damaged store or cut keeps its extension: its reader says what is
  // wrong, not that it is an unknown mesh format.
  std::ofstream(scratch() / "garbage.cut") << "not a cut at all, long enough for a header";
  r = run("info " + (scratch() / "garbage.cut").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("garbage.cut: not a cut file (bad magic)"), std::string::npos) << r.out;
  std::ofstream(scratch() / "garbage.raylod") << "not a store at all, long enough for a header";
  r = run("info " + (scratch() / "garbage.raylod").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("garbage.raylod: "), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("unknown mesh format"), std::string::npos) << r.out;
  r = run("info");
  EXPECT_EQ(r.status, 1) << r.out;
}

// A path that is not a regular file fails at once, saying what it is.
// `timeout` turns a hang (raylod waiting for a writer on the FIFO) into a
// failure with exit status 124.
TEST(Info, NotRegularFilesFailAtOnce) {
  const auto fifo = scratch() / "pipe.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto dir = scratch() / "folder.ply";
  std::filesystem::create_directories(dir);
  const std::pair<std::string, std::string> cases[] = {
      {fifo.string(), "pipe.ply: is a named pipe (FIFO), not a regular file"},
      {dir.string(), "folder.ply: is a directory"},
      {"/dev/zero", "/dev/zero: is a character device, not a regular file"}};
  for (const auto& [path, expected] : cases) {
    const CommandResult r = run("info '" + path + "'", 20);
    EXPECT_EQ(r.status, 1) << path << "\n" << r.out;
    EXPECT_NE(r.out.find("raylod info: error: " ), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(expected), std::string::npos) << r.out;
  }
}

TEST(Info, CoordinateBeyondTheFloatRangeIsNamed) {
  const auto path = scratch() / "huge.ply";
  std::ofstream(path) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                         "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                         "0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n";
  const CommandResult r = run("info " + path.string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("huge.ply: line 11: vertex 1 coordinate x = 1e39 is beyond the float range"), std::string::npos)
      << r.out;
}

TEST(Info, ZeroNormalsAreRepairedWithOneWarning) {
  const auto path = scratch() / "occ.obj";
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 0\nf 1//1 2//2 3//1\nf 1//2 3//2 4//2\n";
  const CommandResult r = run("info " + path.string());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("triangles:  2\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("normals:    yes"), std::string::npos) << r.out;
  const std::string warning = "raylod: warning: " + path.string() + ": 4 triangle corners had a zero-length normal";
  const size_t at = r.out.find(warning);
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("warning", at + warning.size()), std::string::npos) << r.out;
}

// A cut option's bad value is named before any work, by run and probe alike.
TEST(CutOptions, AnUnknownBalanceIsNamed) {
  for (const char* cmd : {"run", "probe"}) {
    const CommandResult r = run(std::string(cmd) + " '" + RAYLOD_DATA_DIR + "/default_scene.json' --balance sideways", 60);
    EXPECT_EQ(r.status, 1) << cmd;
    EXPECT_NE(r.out.find("--balance: unknown value 'sideways' (specular, all or off)"), std::string::npos) << r.out;
  }
}

// Every command with --crease-angle states the default the code uses (the
// help of `simplify` said 30 after the default had moved to 25).
TEST(CreaseAngleOption, EveryHelpStatesTheDefaultInUse) {
  char expected[32];
  std::snprintf(expected, sizeof expected, "%g", raylod::kDefaultCreaseAngleDeg);
  for (const char* cmd : {"run", "render", "report", "simplify"}) {
    const CommandResult r = run(std::string(cmd) + " --help");
    ASSERT_EQ(r.status, 0) << cmd;
    const size_t at = r.out.find("--crease-angle");
    ASSERT_NE(at, std::string::npos) << cmd << ": " << r.out;
    const size_t next = r.out.find("\n  -", at + 1);
    const std::string entry = r.out.substr(at, next == std::string::npos ? std::string::npos : next - at);
    EXPECT_TRUE(entry.find(std::string(", ") + expected + ")") != std::string::npos ||
                entry.find(std::string("(default ") + expected + ",") != std::string::npos)
        << cmd << " states another default than " << expected << ": " << entry;
  }
}

TEST(Info, Help) {
  const CommandResult r = run("info --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("usage: raylod info FILE"), std::string::npos) << r.out;
}

}  // namespace

namespace {

TEST(ImageOutput, AFullDiskFailsEveryFormatNamesTheFileAndLeavesNothing) {
  // A file size limit (ulimit -f, for the raylod process only) stands in for
  // a full disk: writes past it fail with EFBIG as they would with ENOSPC.
  // (SIGXFSZ is ignored, so the write returns the error.) PNG's writer used to report success for the truncated file, and the run
  // printed "wrote" and exited 0.
  const std::filesystem::path dir = scratch() / "full-disk";
  std::filesystem::create_directories(dir);
  {
    std::ofstream(dir / "tetra.ply") << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                        "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
                                        "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    std::ofstream(dir / "scene.json")
        << R"({"camera": {"eye": [2, 1.5, 3], "look_at": [0.3, 0.3, 0.3], "fov_y": 40, "width": 320, "height": 240},
             "materials": {"m": {"type": "diffuse", "color": [0.8, 0.3, 0.2]}},
             "objects": [{"mesh": "tetra.ply", "material": "m"}],
             "lights": [{"type": "point", "position": [3, 4, 2], "intensity": 30}],
             "background": [0.6, 0.7, 0.85], "spp": 2})";
  }
  for (const char* name : {"out.png", "out.jpg", "out.exr", "out.tif"}) {
    const std::filesystem::path out = dir / name;
    const std::string cmd = "sh -c 'trap \"\" XFSZ; ulimit -f 2; exec \"$0\" render \"$1\" -o \"$2\" -q' " + std::string(RAYLOD_EXE) +
                            " '" + (dir / "scene.json").string() + "' '" + out.string() + "' 2>&1";
    std::FILE* p = ::popen(cmd.c_str(), "r");
    ASSERT_NE(p, nullptr);
    std::string text;
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) text.append(buf, n);
    const int st = ::pclose(p);
    EXPECT_TRUE(WIFEXITED(st) && WEXITSTATUS(st) != 0) << name << ": " << text;
    EXPECT_NE(text.find(out.string()), std::string::npos) << name << ": " << text;
    EXPECT_FALSE(std::filesystem::exists(out)) << name;
  }
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string f = e.path().filename().string();
    EXPECT_TRUE(f == "tetra.ply" || f == "scene.json") << "left behind: " << f;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
