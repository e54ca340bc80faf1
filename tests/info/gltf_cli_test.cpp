// glTF through the raylod executable: `run --export-mesh` and
// `simplify -o OUT.glb` write .glb files, a scene naming a multi-mesh .glb
// runs (and exports again), `info` lists the meshes, bad files fail naming
// the file; and Khronos's glTF-Validator (tools/validate_gltf.js) reports no
// error on any .glb written here. Without node or the gltf-validator package
// (tools/setup.sh test installs it) the validator test is skipped, saying why.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "run_command.h"
#include "test_tmp.h"

namespace {

namespace fs = std::filesystem;

using raylod::test::CommandResult;

CommandResult shell(const std::string& cmd) { return raylod::test::run_command(cmd); }

CommandResult raylod(const std::string& args) { return shell(std::string(RAYLOD_EXE) + " " + args); }

fs::path scratch() { return raylod::test::scratch_dir("gltf-cli"); }

const char* kScene = R"({
  "camera": {"eye": [197.5, 144.0, 47.0], "look_at": [101.5, 0.0, -113.0], "fov_y": 35, "width": 160, "height": 120},
  "materials": {"steel": {"type": "glossy", "color": [0.55, 0.56, 0.58], "specular": [0.4, 0.4, 0.4], "shininess": 60},
                "floor": {"type": "diffuse", "color": [0.7, 0.7, 0.68]}},
  "objects": [OBJECTS],
  "ground": {"height": -20.912, "size": 4000, "material": "floor"},
  "lights": [{"type": "point", "position": [251.5, 400.0, 137.0], "intensity": 200000}],
  "background": [0.62, 0.72, 0.85], "spp": 1, "max_depth": 3, "seed": 1
})";

fs::path write_scene(const std::string& name, const std::string& objects) {
  std::string text = kScene;
  text.replace(text.find("OBJECTS"), 7, objects);
  const fs::path p = scratch() / name;
  std::ofstream(p) << text;
  return p;
}

// Writes every kind of .glb raylod writes (once per process) and returns them.
const std::vector<fs::path>& written_glbs() {
  static std::vector<fs::path> files;
  if (!files.empty()) return files;
  const fs::path dir = scratch();
  fs::copy_file(fs::path(RAYLOD_DATA_DIR) / "cad" / "crankarm_coarse.stl", dir / "crank.stl", fs::copy_options::overwrite_existing);
  fs::copy_file(dir / "crank.stl", dir / "crank2.stl", fs::copy_options::overwrite_existing);
  const std::string cache = " --cache " + (dir / "cache").string();
  // Two meshes, one moved and turned: a .glb with two meshes and node matrices.
  const fs::path two = write_scene("two.json", R"({"mesh": "crank.stl", "material": "steel"},
      {"mesh": "crank2.stl", "material": "steel", "transform": {"translate": [0, 0, -80], "rotate_deg": [0, 20, 0]}})");
  CommandResult r = raylod("run " + two.string() + cache + " -q -o " + (dir / "two.png").string() + " --export-mesh " +
                           (dir / "two.glb").string());
  EXPECT_EQ(r.status, 0) << r.out;
  // A scene naming that .glb: one object per node, exported again.
  const fs::path again = write_scene("again.json", R"({"mesh": "two.glb", "material": "steel"})");
  r = raylod("run " + again.string() + cache + " -q -o " + (dir / "again.png").string() + " --export-mesh " +
             (dir / "again.glb").string());
  EXPECT_EQ(r.status, 0) << r.out;
  // raylod build, probe, simplify -o .glb.
  const fs::path one = write_scene("one.json", R"({"mesh": "crank.stl", "material": "steel"})");
  r = raylod("probe " + one.string() + " -o " + (dir / "one.cut").string());
  EXPECT_EQ(r.status, 0) << r.out;
  r = raylod("simplify " + (dir / "crank.stl.raylod").string() + " " + (dir / "one.cut").string() + " -q -o " +
             (dir / "one.glb").string());
  EXPECT_EQ(r.status, 0) << r.out;
  // The same split into three parts: three primitives of one mesh.
  r = raylod("simplify " + (dir / "crank.stl.raylod").string() + " " + (dir / "one.cut").string() + " -q --parts 3 -o " +
             (dir / "parts.glb").string());
  EXPECT_EQ(r.status, 0) << r.out;
  for (const char* name : {"two.glb", "again.glb", "one.glb", "parts.glb"})
    if (fs::exists(dir / name)) files.push_back(dir / name);
  return files;
}

TEST(GltfCli, ExportsAndReadsBackMultiMeshGlb) {
  const auto& files = written_glbs();
  ASSERT_EQ(files.size(), 4u);
  const CommandResult info = raylod("info " + (scratch() / "two.glb").string());
  ASSERT_EQ(info.status, 0) << info.out;
  EXPECT_NE(info.out.find("2 meshes, 2 node instances"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("meshes[1]"), std::string::npos) << info.out;
  // The scene naming two.glb had two objects, and its export two nodes again.
  const CommandResult again = raylod("info " + (scratch() / "again.glb").string());
  ASSERT_EQ(again.status, 0) << again.out;
  EXPECT_NE(again.out.find("2 meshes, 2 node instances"), std::string::npos) << again.out;
  // One mesh of the file, by reference.
  const CommandResult one = raylod("info '" + (scratch() / "two.glb").string() + "#meshes[1]'");
  ASSERT_EQ(one.status, 0) << one.out;
  EXPECT_NE(one.out.find("format:     glTF (glb)"), std::string::npos) << one.out;
  // The three-part file: one mesh of three primitives, the triangles of the one-part file.
  const CommandResult single = raylod("info " + (scratch() / "one.glb").string());
  const CommandResult parts = raylod("info " + (scratch() / "parts.glb").string());
  ASSERT_EQ(parts.status, 0) << parts.out;
  EXPECT_NE(parts.out.find("3 triangle primitives"), std::string::npos) << parts.out;
  const auto triangles = [](const std::string& out) {
    const size_t at = out.find("triangles:");
    return at == std::string::npos ? std::string() : out.substr(at, out.find('\n', at) - at);
  };
  EXPECT_FALSE(triangles(parts.out).empty()) << parts.out;
  EXPECT_EQ(triangles(parts.out), triangles(single.out));
}

// A cut applied to a store it was not made for is refused before any work,
// and the message says which case it is: another store, or the same store
// file rebuilt since (here with another --max-depth, which changes the
// layout the cut's cells refer to).
TEST(SimplifyCli, ACutForAnotherOrAChangedStoreIsRefusedSayingWhich) {
  const auto& files = written_glbs();
  ASSERT_EQ(files.size(), 4u);
  const fs::path dir = scratch();
  const std::string cut = (dir / "one.cut").string();
  CommandResult r = raylod("build " + (dir / "crank2.stl").string() + " -q");
  ASSERT_EQ(r.status, 0) << r.out;
  r = raylod("simplify " + (dir / "crank2.stl.raylod").string() + " " + cut + " -q -o " + (dir / "x.drc").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("one.cut: the cut was made for a different store"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "x.drc"));

  raylod::test::ScratchDir own("cut-store");
  fs::copy_file(dir / "crank.stl", own.path / "c.stl");
  fs::copy_file(dir / "crank.stl.raylod", own.path / "c.stl.raylod");
  // The cut names the store by path: point it at the copy by probing the copy.
  std::ofstream(own.path / "c.json") << std::string(kScene).replace(std::string(kScene).find("OBJECTS"), 7,
                                                                     R"({"mesh": "c.stl", "material": "steel"})");
  r = raylod("probe " + (own.path / "c.json").string() + " -q -o " + (own.path / "c.cut").string());
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_EQ(r.out, "");  // -q: errors only
  EXPECT_TRUE(fs::exists(own.path / "c.cut"));
  r = raylod("build " + (own.path / "c.stl").string() + " --max-depth 6 -q");
  ASSERT_EQ(r.status, 0) << r.out;
  r = raylod("simplify " + (own.path / "c.stl.raylod").string() + " " + (own.path / "c.cut").string() + " -q -o " +
             (own.path / "x.drc").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("c.cut: the store " + (own.path / "c.stl.raylod").string() + " has changed since the cut"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(own.path / "x.drc"));
}

TEST(GltfCli, BadGlbFailsNamingTheFile) {
  const fs::path bad = scratch() / "truncated.glb";
  std::ofstream(bad, std::ios::binary) << std::string("glTF\2\0\0\0\x40\0\0\0", 12) << "{}";
  const CommandResult r = raylod("info " + bad.string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("truncated.glb: truncated GLB"), std::string::npos) << r.out;
}

TEST(GltfValidator, EveryGlbRaylodWritesHasNoErrors) {
  const auto& files = written_glbs();
  ASSERT_EQ(files.size(), 4u);
  if (shell("node --version").status != 0) GTEST_SKIP() << "node is not installed: glTF-Validator not run";
  std::string cmd = "node " + (fs::path(RAYLOD_TEST_DIR) / ".." / "tools" / "validate_gltf.js").string();
  for (const auto& f : files) cmd += " " + f.string();
  const CommandResult r = shell(cmd);
  if (r.status == 77) GTEST_SKIP() << r.out;
  EXPECT_EQ(r.status, 0) << r.out;
  std::printf("%s", r.out.c_str());  // the validator's summary, for the log
}

}  // namespace
