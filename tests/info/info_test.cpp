// `raylod info` end to end: runs the raylod executable on meshes in data/ and
// on bad files, and checks the output and the exit status.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include "test_tmp.h"

namespace {

struct CommandResult {
  int status = -1;
  std::string out;  // stdout and stderr
};

CommandResult run(const std::string& args) {
  CommandResult r;
  const std::string cmd = std::string(RAYLOD_EXE) + " " + args + " 2>&1";
  std::FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = ::pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

std::filesystem::path scratch() {
  return raylod::test::scratch_dir("info-test");
}

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
  r = run("info");
  EXPECT_EQ(r.status, 1) << r.out;
}

TEST(Info, Help) {
  const CommandResult r = run("info --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("usage: raylod info FILE"), std::string::npos) << r.out;
}

}  // namespace
