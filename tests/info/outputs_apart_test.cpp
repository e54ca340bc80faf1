// Outputs never replace inputs (core/system.h, check_outputs_apart): the
// check itself, and the commands that write files refusing before they
// write anything.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/system.h"
#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(OutputsApart, TheSameFileByAnyNameIsRefused) {
  const std::filesystem::path dir = test::scratch_dir("outputs-apart");
  std::ofstream(dir / "mesh.ply") << "ply\n";
  std::filesystem::create_directories(dir / "sub");
  std::filesystem::create_hard_link(dir / "mesh.ply", dir / "hard.ply");
  std::filesystem::create_symlink(dir / "mesh.ply", dir / "soft.ply");
  const std::vector<FileRole> inputs = {{dir / "mesh.ply", "the mesh"}};
  for (const std::filesystem::path& out :
       {dir / "mesh.ply", dir / "sub" / ".." / "mesh.ply", dir / "hard.ply", dir / "soft.ply"}) {
    const Status st = check_outputs_apart({{out, "-o"}}, inputs);
    EXPECT_FALSE(st) << out;
    EXPECT_NE(st.message().find("would replace the mesh"), std::string::npos) << st.message();
    EXPECT_NE(st.message().find(out.string()), std::string::npos) << st.message();
  }
  // Another file, and outputs that do not exist yet, pass; two outputs on
  // one new path do not.
  EXPECT_TRUE(check_outputs_apart({{dir / "mesh.ply.raylod", "-o"}}, inputs));
  EXPECT_TRUE(check_outputs_apart({{dir / "a.png", "-o"}, {dir / "a.json", "--stats-json"}}, inputs));
  const Status both = check_outputs_apart({{dir / "a.png", "-o"}, {dir / "sub/../a.png", "--stats-json"}}, inputs);
  EXPECT_FALSE(both);
  EXPECT_NE(both.message().find("given as both -o and --stats-json"), std::string::npos) << both.message();
  // A symlink to a file not made yet names that file: two outputs through
  // it and beside it, or a chain of links, are one.
  std::filesystem::create_symlink("new.png", dir / "alias.png");
  std::filesystem::create_symlink("alias.png", dir / "alias2.png");
  std::filesystem::create_symlink(dir / "sub" / ".." / "new.png", dir / "absolute.png");
  for (const char* other : {"alias.png", "alias2.png", "absolute.png"}) {
    const Status st = check_outputs_apart({{dir / "new.png", "-o"}, {dir / other, "--stats-json"}}, inputs);
    EXPECT_FALSE(st) << other;
    EXPECT_NE(st.message().find("given as both -o and --stats-json"), std::string::npos) << st.message();
  }
  EXPECT_TRUE(check_outputs_apart({{dir / "other.png", "-o"}, {dir / "alias.png", "--stats-json"}}, inputs));
  // Empty paths (an option not given) are left out.
  EXPECT_TRUE(check_outputs_apart({{"", "-o"}}, {{"", "the mesh"}}));
}

TEST(OutputsApart, CommandsRefuseToWriteOverTheirInputs) {
  const std::filesystem::path dir = test::scratch_dir("outputs-apart-cli");
  const std::filesystem::path mesh = dir / "tetra.ply", scene = dir / "scene.json";
  std::ofstream(mesh) << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                         "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
                         "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  std::ofstream(scene) << R"({"camera": {"eye": [2, 1.5, 3], "look_at": [0.3, 0.3, 0.3], "fov_y": 40, "width": 64, "height": 48},
       "materials": {"m": {"type": "diffuse", "color": [0.8, 0.3, 0.2]}},
       "objects": [{"mesh": "tetra.ply", "material": "m"}],
       "lights": [{"type": "point", "position": [3, 4, 2], "intensity": 30}], "spp": 1})";
  const std::string mesh_bytes = read_all(mesh), scene_bytes = read_all(scene);
  const std::string m = "'" + mesh.string() + "'", s = "'" + scene.string() + "'";
  const std::string cache = " --cache '" + (dir / "cache").string() + "'";
  struct Case {
    std::string args, expect;
  };
  const Case cases[] = {
      // `build MESH -o MESH` used to replace the mesh with the store.
      {"build " + m + " -o " + m + " -q", "the store (-o) would replace the mesh"},
      {"probe " + s + " -o " + s + " -q", "the cut (-o) would replace the scene file"},
      {"probe " + s + " -o " + m + " -q", "the cut (-o) would replace the mesh of objects[0]"},
      {"render " + s + " -o out.png --stats-json " + s + " -q", "--stats-json would replace the scene file"},
      {"render " + s + " -o out.png --stats-json out.png -q", "given as both the image (-o) and --stats-json"},
      {"run " + s + " -o out.png --stats-json " + m + " -q" + cache, "--stats-json would replace the mesh"},
      // The names an output implies: --compare's images beside it, and a
      // sequence's numbered images (only view 0's was checked).
      {"run " + s + " -o out.png --compare --stats-json out.full.png -q" + cache,
       "given as both --compare's full-mesh image and --stats-json"},
      {"run " + s + " -o out.png --compare --stats-json out.diff.png -q" + cache,
       "given as both --compare's difference image and --stats-json"},
      {"run " + s + " -o 'v_#.png' --orbit 3 --stats-json v_2.png -q" + cache,
       "v_2.png: the image of view 2 would replace --stats-json"},
  };
  for (const Case& c : cases) {
    const test::CommandResult r =
        test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) + "' " + c.args);
    EXPECT_NE(r.status, 0) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.expect), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_EQ(read_all(mesh), mesh_bytes) << c.args;
    EXPECT_EQ(read_all(scene), scene_bytes) << c.args;
    EXPECT_FALSE(std::filesystem::exists(dir / "out.png")) << c.args;
    EXPECT_FALSE(std::filesystem::exists(dir / "v_0.png")) << c.args;
  }
  // simplify -o naming the mesh its store was built from.
  std::string out;
  ASSERT_EQ(test::run_raylod("build " + m + " -q", out), 0) << out;
  // run's --stats-json naming the store it reads (or its check record).
  const std::string store_bytes = read_all(mesh.string() + ".raylod");
  for (const std::string& over : {mesh.string() + ".raylod", mesh.string() + ".raylod.checked"}) {
    const test::CommandResult stats = test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) +
                                                        "' run " + s + " -o out.png -q --stats-json '" + over + "'" + cache);
    EXPECT_NE(stats.status, 0) << stats.out;
    EXPECT_NE(stats.out.find("--stats-json would replace the "), std::string::npos) << stats.out;
    EXPECT_NE(stats.out.find("store"), std::string::npos) << stats.out;
  }
  EXPECT_EQ(read_all(mesh.string() + ".raylod"), store_bytes);
  ASSERT_EQ(test::run_raylod("probe " + s + " -o '" + (dir / "t.cut").string() + "' -q", out), 0) << out;
  const test::CommandResult r = test::run_command("'" + std::string(RAYLOD_EXE) + "' simplify '" + mesh.string() +
                                                  ".raylod' '" + (dir / "t.cut").string() + "' -o " + m + " -q");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("would replace the store's mesh"), std::string::npos) << r.out;
  EXPECT_EQ(read_all(mesh), mesh_bytes);
  std::filesystem::remove_all(dir);
}

// A glTF file's meshes are objects named "FILE.glb#meshes[N]": the file is
// what an output must not replace (run --export-mesh wrote its simplified
// copy over the scene's own mesh).
TEST(OutputsApart, AGltfSceneMeshIsAnInputByItsFileName) {
  test::ScratchDir dir("outputs-apart-gltf");
  const std::string d = "'" + dir.path.string() + "'";
  std::string out;
  ASSERT_EQ(test::run_raylod("gen teapot --triangles 2000 -q -o " + d + "/t.ply", out), 0) << out;
  ASSERT_EQ(test::run_raylod("scene " + d + "/t.ply -o " + d + "/t.json --width 48 --height 36 -q", out), 0) << out;
  ASSERT_EQ(test::run_raylod("run " + d + "/t.json --no-cache --rays 200 -o " + d + "/t.png --export-mesh " + d +
                                 "/in.glb -q",
                             out),
            0)
      << out;
  ASSERT_EQ(test::run_raylod("scene " + d + "/in.glb -o " + d + "/in.json --width 48 --height 36 -q", out), 0) << out;
  const std::string glb = read_all(dir.path / "in.glb");
  const test::CommandResult r = test::run_command("'" + std::string(RAYLOD_EXE) + "' run " + d + "/in.json --no-cache " +
                                                  "--rays 200 -o " + d + "/in.png --export-mesh " + d + "/in.glb -q");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("in.glb: --export-mesh would replace the mesh of objects[0]"), std::string::npos) << r.out;
  EXPECT_EQ(read_all(dir.path / "in.glb"), glb);
  EXPECT_FALSE(std::filesystem::exists(dir.path / "in.png"));
}

// Output paths that cannot be written are refused before rendering, and a
// render whose AOV cannot be written leaves neither the image nor the AOVs
// written before it.
TEST(OutputsApart, UnwritableOutputsFailBeforeRendering) {
  const std::filesystem::path dir = test::scratch_dir("outputs-unwritable");
  std::ofstream(dir / "tetra.ply") << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  std::ofstream(dir / "scene.json") << R"({"camera": {"eye": [2, 1.5, 3], "look_at": [0.3, 0.3, 0.3], "fov_y": 40, "width": 64, "height": 48},
       "materials": {"m": {"type": "diffuse", "color": [0.8, 0.3, 0.2]}},
       "objects": [{"mesh": "tetra.ply", "material": "m"}], "spp": 1})";
  std::ofstream(dir / "big.json") << R"([{"eye": [2, 1.5, 3], "look_at": [0.3, 0.3, 0.3]},
       {"eye": [2, 1.5, 3], "look_at": [0.3, 0.3, 0.3], "width": 8000, "height": 8000}])";
  std::filesystem::create_directories(dir / "d.png");
  std::filesystem::create_directories(dir / "o.normal.exr");
  std::filesystem::create_directories(dir / "c.full.png");
  std::filesystem::create_directories(dir / "v_1.png");
  std::filesystem::create_directories(dir / "m.drc");
  struct Case {
    std::string args, expect;
  };
  const Case cases[] = {
      {"render scene.json -o d.png -q", "d.png: the image: is a directory"},
      {"render scene.json -o o.png --aov depth,normal -q", "o.normal.exr: the image: is a directory"},
      {"render scene.json -o tetra.ply/x.png -q", "x.png: the image: tetra.ply is not a directory"},
      {"render scene.json -o missing/x.png -q", "directory missing does not exist"},
      // Checked before the pipeline runs, not when the file is written.
      {"run scene.json --no-cache -o o.png --export-mesh missing/s.glb -q", "--export-mesh: directory missing does not exist"},
      {"build tetra.ply -o missing/a/x.raylod -q", "the store (-o): directory missing/a does not exist"},
      {"probe scene.json -o missing/b/x.cut -q", "the cut (-o): directory missing/b does not exist"},
      {"probe scene.json -o tetra.ply/x.cut -q", "x.cut: the cut (-o): tetra.ply is not a directory"},
      {"run scene.json --no-cache -o /dev/null --compare -q", "must then be a file, not a device or FIFO"},
      {"render scene.json -o /dev/null --aov depth -q", "--aov writes its images beside the image (-o), which must then"},
      // Images written after the first one: checked before it is written.
      {"run scene.json --no-cache -o c.png --compare -q", "c.full.png: the image: is a directory"},
      {"run scene.json --no-cache --orbit 2 -o v_#.png -q", "v_1.png: the image: is a directory"},
      {"render scene.json --mesh d.png -o r.png -q", "d.png: is a directory, not a mesh file"},
      // The report makes its folder, not the folders above it.
      {"report scene.json -o missing/r -q", "the report folder (-o): directory missing does not exist"},
      {"report scene.json -o tetra.ply -q", "tetra.ply: the report folder (-o) names a file"},
      // The commands that write meshes and scenes, before any work.
      {"simplify none.raylod none.cut -o missing/s.drc -q", "the simplified mesh (-o): directory missing does not exist"},
      {"simplify none.raylod none.cut -o m.drc -q", "m.drc: the simplified mesh (-o): is a directory"},
      {"gen teapot --triangles 200 -o missing/t.ply -q", "the mesh (-o): directory missing does not exist"},
      {"gen teapot --triangles 200 -o d.png -q", "d.png: the mesh (-o): is a directory"},
      {"scene tetra.ply -o d.png -q", "d.png: the scene (-o): is a directory"},
      // A name longer than a file name may be: before any work (it failed
      // when renamed into place, after the render).
      {"render scene.json -o " + std::string(252, 'c') + ".png -q", "the file name is 256 bytes"},
      {"probe scene.json -o " + std::string(252, 'c') + ".cut -q", "the cut (-o): the file name is 256 bytes"},
      // Writers OpenImageIO has that cannot write raylod's images, or write
      // no file: before any work, not after the render.
      {"render scene.json -o x.zfile -q", "x.zfile: OpenImageIO's writer for '.zfile' files cannot write a 3-channel"},
      {"run scene.json --no-cache -o x.zfile -q", "x.zfile: OpenImageIO's writer for '.zfile' files cannot write"},
      {"render scene.json -o x.term -q", "'.term' is OpenImageIO's terminal display, not an image file"},
      {"render scene.json -o x.null -q", "'.null' is OpenImageIO's writer that discards the image"},
      // A view of a views file too large for the memory limit: named, before
      // the views before it are rendered.
      {"run scene.json --no-cache --views big.json -o v_#.png --memory-limit 300M -q",
       "big.json: [1]: the 8000 x 8000 image needs about"},
      // Empty names: said so, not an internal error.
      {"scene tetra.ply -o '' -q", "the scene (-o): no file name given"},
      {"build '' -q", "the mesh: no file name given"},
  };
  for (const Case& c : cases) {
    const test::CommandResult r =
        test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) + "' " + c.args);
    EXPECT_NE(r.status, 0) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.expect), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_EQ(r.out.find("render:"), r.out.rfind("render:")) << "one line, no progress: " << r.out;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "o.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "x.zfile"));
  EXPECT_FALSE(std::filesystem::exists(dir / "o.depth.exr"));
  EXPECT_FALSE(std::filesystem::exists(dir / "c.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "v_0.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "r.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "missing"));  // probe made it before
  EXPECT_FALSE(std::filesystem::exists(dir / "tetra.ply.raylod"));  // nothing built for the refused probe
  // A device without an extension takes a PNG (the bytes pass through);
  // a plain name without one is still refused.
  for (const char* command : {"render scene.json -o /dev/null -q", "run scene.json --no-cache -o /dev/null -q"}) {
    const test::CommandResult r =
        test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) + "' " + command);
    EXPECT_EQ(r.status, 0) << command << "\n" << r.out;
  }
  const test::CommandResult r = test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) +
                                                  "' render scene.json -o noext -q");
  EXPECT_NE(r.out.find("noext: no file extension to choose the image format from"), std::string::npos) << r.out;
  // A format without a writer: refused at once, before any store is built
  // (`run` loads the image codec beside its store stage, and waits for it
  // first where the extension is not one every build writes).
  std::filesystem::remove(dir / "tetra.ply.raylod");
  std::filesystem::remove(dir / "tetra.ply.raylod.checked");
  for (const Case& c : {Case{"render scene.json -o o.xyz -q", "o.xyz: no image writer for '.xyz' files"},
                        Case{"run scene.json --no-cache -o o.xyz -q", "o.xyz: no image writer for '.xyz' files"},
                        Case{"run scene.json --no-cache --orbit 2 -o v_#.xyz -q", "v_0.xyz: no image writer"}}) {
    const test::CommandResult x =
        test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) + "' " + c.args);
    EXPECT_NE(x.status, 0) << c.args << "\n" << x.out;
    EXPECT_NE(x.out.find(c.expect), std::string::npos) << c.args << "\n" << x.out;
    EXPECT_EQ(x.out.find("probe"), std::string::npos) << c.args << "\n" << x.out;
  }
  for (const char* name : {"o.xyz", "v_0.xyz", "v_1.xyz"}) EXPECT_FALSE(std::filesystem::exists(dir / name)) << name;
  EXPECT_FALSE(std::filesystem::exists(dir / "tetra.ply.raylod"));
  // A writer that reported success for an empty file (OpenJPEG's in this
  // build, .jp2): a complete image or a failure that says so, never 0 bytes.
  const test::CommandResult jp2 = test::run_command("cd '" + dir.string() + "' && '" + std::string(RAYLOD_EXE) +
                                                    "' render scene.json -o o.jp2 -q");
  if (jp2.status == 0) {
    EXPECT_GT(std::filesystem::file_size(dir / "o.jp2"), 0u) << jp2.out;
  } else {
    EXPECT_NE(jp2.out.find("o.jp2: the image writer wrote nothing"), std::string::npos) << jp2.out;
    EXPECT_FALSE(std::filesystem::exists(dir / "o.jp2"));
  }
  // A TMPDIR that does not exist: the scratch files go to /tmp (run failed
  // with "internal error: filesystem error: temp_directory_path").
  const test::CommandResult t = test::run_command("cd '" + dir.string() + "' && TMPDIR='" + (dir / "no-such").string() +
                                                  "' '" + std::string(RAYLOD_EXE) +
                                                  "' run scene.json --no-cache -o t.png -q");
  EXPECT_EQ(t.status, 0) << t.out;
  EXPECT_TRUE(std::filesystem::exists(dir / "t.png"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace raylod
