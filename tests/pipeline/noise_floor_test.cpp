// The noise floor (pipeline/noise_floor.h) on tiny in-memory scenes: what it
// measures, that it rises with the sample count, and the verdicts.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "pipeline/noise_floor.h"
#include "render/render_test_util.h"

namespace raylod {
namespace {

using namespace raylod::testing;

// A diffuse sphere on a floor at 96 x 72: antialiased edges and a shadow
// boundary are where two seeds differ.
struct SphereScene {
  Scene scene;
  std::unique_ptr<EmbreeScene> geometry;
};

SphereScene sphere_scene(int spp) {
  SphereScene out;
  Scene& s = out.scene;
  s = base_scene(96, 72);
  s.spp = spp;
  s.camera.eye = {0, 2.2, 5.5};
  s.camera.look_at = {0, 0.8, 0};
  s.background = Vec3(0.55f, 0.65f, 0.8f);
  s.lights.push_back(point_light({3, 6, 4}, 50));
  s.materials = {material("red", MaterialType::Diffuse, {0.8f, 0.2f, 0.15f}),
                 material("floor", MaterialType::Diffuse, {0.7f, 0.7f, 0.7f})};
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_sphere({0, 1, 0}, 1, 24, 48, 0));
  meshes.push_back(make_ground_mesh(Ground{0, 20, 1}, s.camera));
  auto g = EmbreeScene::build(std::move(meshes));
  EXPECT_TRUE(g.is_ok()) << g.status().message();
  out.geometry = std::move(g.value());
  return out;
}

TEST(NoiseFloor, IsTheNextSeedAgainstTheReference) {
  SphereScene ss = sphere_scene(1);
  const RenderResult reference = render_embree_scene(*ss.geometry, ss.scene, quiet_options());
  auto floor = measure_noise_floor(*ss.geometry, ss.scene, quiet_options(), reference.color);
  ASSERT_TRUE(floor.is_ok()) << floor.status().message();
  EXPECT_EQ(floor->seed, 7u);
  EXPECT_EQ(floor->spp, 1);
  // The same as rendering seed 8 by hand and comparing.
  Scene next = ss.scene;
  next.seed = 8;
  const RenderResult other = render_embree_scene(*ss.geometry, next, quiet_options());
  auto e = compare_images(other.color, reference.color);
  ASSERT_TRUE(e.is_ok());
  EXPECT_EQ(floor->psnr(), e->psnr);
  EXPECT_EQ(floor->error.ssim, e->ssim);
  // Sampling noise exists (one jittered sample per pixel) but is small.
  EXPECT_TRUE(std::isfinite(floor->psnr()));
  EXPECT_GT(floor->psnr(), 15.0);
  EXPECT_LT(floor->error.ssim, 1.0);
}

TEST(NoiseFloor, RisesWithTheSampleCount) {
  auto floor_at = [](int spp) {
    SphereScene ss = sphere_scene(spp);
    const RenderResult reference = render_embree_scene(*ss.geometry, ss.scene, quiet_options());
    auto floor = measure_noise_floor(*ss.geometry, ss.scene, quiet_options(), reference.color);
    EXPECT_TRUE(floor.is_ok()) << floor.status().message();
    return floor->psnr();
  };
  const double one = floor_at(1), sixteen = floor_at(16);
  // 16 times the samples: the noise variance drops at least 16-fold for
  // independent samples (12 dB); stratification does better still.
  EXPECT_GT(sixteen, one + 6.0) << "1 spp " << one << " dB, 16 spp " << sixteen << " dB";
}

TEST(NoiseFloor, VerdictsAgainstTheFloor) {
  NoiseFloor floor;
  floor.error.psnr = 40.0;
  ImageError above, at, below, identical;
  above.psnr = 45.0;
  at.psnr = 40.0;
  below.psnr = 37.5;
  identical.psnr = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(within_noise_floor(above, floor));
  EXPECT_TRUE(within_noise_floor(at, floor));
  EXPECT_FALSE(within_noise_floor(below, floor));
  EXPECT_TRUE(within_noise_floor(identical, floor));
  EXPECT_EQ(describe_against_noise_floor(above, floor), "noise floor 40.00 dB: indistinguishable");
  EXPECT_EQ(describe_against_noise_floor(below, floor), "below the noise floor of 40.00 dB by 2.50 dB");
  // A render without sampling noise: only an identical image is within it.
  NoiseFloor exact;
  exact.error.psnr = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(within_noise_floor(above, exact));
  EXPECT_TRUE(within_noise_floor(identical, exact));
  EXPECT_NE(describe_against_noise_floor(above, exact).find("below the noise floor"), std::string::npos);
}

TEST(NoiseFloor, ReferenceOfAnotherSizeIsAnError) {
  SphereScene ss = sphere_scene(1);
  auto floor = measure_noise_floor(*ss.geometry, ss.scene, quiet_options(), Image(32, 24, 3));
  ASSERT_FALSE(floor.is_ok());
  EXPECT_NE(floor.status().message().find("differ in size"), std::string::npos) << floor.status().message();
}

}  // namespace
}  // namespace raylod
