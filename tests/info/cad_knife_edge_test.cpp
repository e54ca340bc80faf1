// An ABC CAD plate end to end (data/abc/abc5.stl, facet normals only):
// framed by `raylod scene`, probed and simplified at the defaults, the
// simplified mesh reaches as far as the input on every side, within a
// quarter of a pixel at the part. The plate's end is a concave groove that
// leaves its top and bottom faces tangentially (two knife edges); their
// cells' quadrics pinned the edges only weakly, and the end drew 1.2 pixels
// inside where it is (collapse_deviation.h, "folds").
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "run_command.h"
#include "test_tmp.h"

namespace {

namespace fs = std::filesystem;
using raylod::test::CommandResult;

CommandResult raylod_cli(const std::string& args) {
  return raylod::test::run_command(std::string(RAYLOD_EXE) + " " + args);
}

fs::path scratch() { return raylod::test::scratch_dir("cad-knife-edge"); }

class RemoveScratch : public ::testing::Environment {
  void TearDown() override { fs::remove_all(scratch()); }
};
const auto* const kRemoveScratch = ::testing::AddGlobalTestEnvironment(new RemoveScratch);

struct Bounds {
  double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
};

// The "bounds:" lines of `raylod info`.
bool read_bounds(const std::string& info, Bounds& b) {
  const size_t min_at = info.find("bounds:     min ("), max_at = info.find("max (", min_at);
  if (min_at == std::string::npos || max_at == std::string::npos) return false;
  return std::sscanf(info.c_str() + min_at, "bounds:     min (%lf, %lf, %lf)", &b.lo[0], &b.lo[1], &b.lo[2]) == 3 &&
         std::sscanf(info.c_str() + max_at, "max (%lf, %lf, %lf)", &b.hi[0], &b.hi[1], &b.hi[2]) == 3;
}

TEST(CadKnifeEdges, TheSimplifiedAbcPlateReachesAsFarAsTheInput) {
  const fs::path dir = scratch() / "abc5";
  fs::create_directories(dir);
  const fs::path mesh = dir / "abc5.stl", scene = dir / "abc5.json", cut = dir / "abc5.cut", out = dir / "abc5.ply";
  fs::copy_file(fs::path(RAYLOD_DATA_DIR) / "abc" / "abc5.stl", mesh, fs::copy_options::overwrite_existing);

  const CommandResult framed = raylod_cli("scene " + mesh.string() + " --up z -o " + scene.string());
  ASSERT_EQ(framed.status, 0) << framed.out;
  // The pixel at the part: the camera's distance to its look-at point (the
  // bounds' centre), over the image height, through the vertical field of view.
  double eye[3], centre[3], fov = 0;
  int width = 0, height = 0;
  const size_t camera_at = framed.out.find("camera     eye ("), centre_at = framed.out.find("centre (");
  ASSERT_NE(camera_at, std::string::npos) << framed.out;
  ASSERT_NE(centre_at, std::string::npos) << framed.out;
  ASSERT_EQ(std::sscanf(framed.out.c_str() + camera_at, "camera     eye (%lf, %lf, %lf), fov_y %lf, %d x %d", &eye[0],
                        &eye[1], &eye[2], &fov, &width, &height),
            6)
      << framed.out;
  ASSERT_EQ(std::sscanf(framed.out.c_str() + centre_at, "centre (%lf, %lf, %lf)", &centre[0], &centre[1], &centre[2]), 3)
      << framed.out;
  const double distance = std::hypot(eye[0] - centre[0], eye[1] - centre[1], eye[2] - centre[2]);
  const double pixel = 2 * distance * std::tan(fov * M_PI / 360) / height;
  ASSERT_GT(pixel, 0);

  const CommandResult probed = raylod_cli("probe " + scene.string() + " -o " + cut.string() + " -q");
  ASSERT_EQ(probed.status, 0) << probed.out;
  const CommandResult simplified =
      raylod_cli("simplify " + mesh.string() + ".raylod " + cut.string() + " -o " + out.string() + " -q");
  ASSERT_EQ(simplified.status, 0) << simplified.out;

  Bounds input, output;
  const CommandResult input_info = raylod_cli("info " + mesh.string());
  const CommandResult output_info = raylod_cli("info " + out.string());
  ASSERT_TRUE(read_bounds(input_info.out, input)) << input_info.out;
  ASSERT_TRUE(read_bounds(output_info.out, output)) << output_info.out;
  // Something was collapsed, or the test would not test anything.
  EXPECT_EQ(output_info.out.find("triangles:  5080\n"), std::string::npos) << output_info.out;
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_NEAR(output.lo[axis], input.lo[axis], 0.25 * pixel) << "axis " << axis << ", pixel " << pixel;
    EXPECT_NEAR(output.hi[axis], input.hi[axis], 0.25 * pixel) << "axis " << axis << ", pixel " << pixel;
  }
}

}  // namespace
