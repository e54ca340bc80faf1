// `raylod probe` then `raylod simplify` by hand makes the mesh `raylod run`
// makes (one default for everything): the cut records what run gives
// simplify for its store (fold passes and exact normals on mirrors and
// glass, the normals' quantisation the materials ask for, the crease
// angle), and simplify takes those as its defaults. Before, by hand a glass
// mesh had no fold passes, the cell's mean normals and 10 normal bits where
// run used 17, 2 dB below run's mesh on the glass scene.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "pipeline/pipeline.h"
#include "run_command.h"
#include "streaming/cut_file.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

std::string bytes_of(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(SimplifyByHand, ProbeThenSimplifyGivesTheMeshRunCaches) {
  for (const char* material : {"glass", "glossy"}) {
    test::ScratchDir dir(std::string("by-hand-") + material);
    const std::string d = "'" + dir.path.string() + "'";
    std::string out;
    ASSERT_EQ(test::run_raylod("gen teapot --triangles 30000 -q -o " + d + "/t.ply", out), 0) << out;
    ASSERT_EQ(test::run_raylod("scene " + d + "/t.ply -o " + d + "/t.json --width 96 --height 72 --material " +
                                   material + " -q",
                               out),
              0)
        << out;
    const std::string cache = " --cache " + d + "/cache";
    ASSERT_EQ(test::run_raylod("run " + d + "/t.json --rays 800 -o " + d + "/run.png -q" + cache, out), 0) << out;
    ASSERT_EQ(test::run_raylod("probe " + d + "/t.json --rays 800 -q -o " + d + "/t.cut", out), 0) << out;
    auto cut = read_cut(dir.path / "t.cut");
    ASSERT_TRUE(cut.is_ok()) << cut.status().message();
    const SimplifySettings s = simplify_settings_of(*cut);
    EXPECT_TRUE(s.recorded);
    EXPECT_EQ(s.fold_passes, std::string(material) == "glass" ? kSpecularFoldPasses : 0) << material;
    ASSERT_EQ(test::run_raylod("simplify " + d + "/t.ply.raylod " + d + "/t.cut -o " + d + "/hand.drc -q", out), 0)
        << out;
    // The one entry run cached.
    fs::path cached;
    for (const auto& e : fs::directory_iterator(dir.path / "cache" / "simplified"))
      if (e.path().extension() == ".drc") cached = e.path();
    ASSERT_FALSE(cached.empty());
    EXPECT_EQ(bytes_of(dir.path / "hand.drc"), bytes_of(cached)) << material;
    // An explicit option still wins: other bytes.
    ASSERT_EQ(test::run_raylod("simplify " + d + "/t.ply.raylod " + d + "/t.cut -o " + d +
                                   "/coarse.drc --normal-bits 8 -q",
                               out),
              0)
        << out;
    EXPECT_NE(bytes_of(dir.path / "coarse.drc"), bytes_of(cached)) << material;
  }
}

TEST(SimplifyByHand, ACutWithoutTheRecordGivesSimplifysOwnDefaults) {
  Cut cut;
  const SimplifySettings s = simplify_settings_of(cut);
  EXPECT_FALSE(s.recorded);
  EXPECT_EQ(s.fold_passes, 0);
  EXPECT_EQ(s.normal_bits, kDefaultNormalBits);
  EXPECT_EQ(s.crease_angle_deg, kDefaultCreaseAngleDeg);
  Scene scene;
  Material glass;
  glass.type = MaterialType::Glass;
  scene.materials = {glass};
  scene.crease_angle_deg = 40;
  record_simplify_settings(cut, scene, std::vector<ProbeObject>{{0, glm::dmat4(1.0), 0}}, 0);
  const SimplifySettings r = simplify_settings_of(cut);
  EXPECT_TRUE(r.recorded);
  EXPECT_EQ(r.fold_passes, kSpecularFoldPasses);
  EXPECT_EQ(r.normal_bits, choose_normal_bits(shading_normal_tolerance(scene)));
  EXPECT_DOUBLE_EQ(r.crease_angle_deg, 40.0);
}

}  // namespace
}  // namespace raylod
