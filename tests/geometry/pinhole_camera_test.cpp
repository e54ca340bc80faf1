// The pinhole camera's pixel -> ray mapping and its derivatives
// (geometry/pinhole_camera.h), shared by the renderer and the probe.
#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "geometry/pinhole_camera.h"

namespace raylod {
namespace {

const Vec3d kEye(1, 2, 3), kLookAt(0, 0.5, -1);

PinholeCamera test_camera() { return make_pinhole_camera(kEye, kLookAt, Vec3d(0, 1, 0), 50, 64, 48); }

TEST(Camera, CentreRayLooksAtTheTarget) {
  const PinholeCamera cam = test_camera();
  const Ray r = cam.generate(32, 24);
  EXPECT_NEAR(glm::length(r.direction - glm::normalize(kLookAt - kEye)), 0, 1e-12);
  EXPECT_EQ(r.origin, kEye);
}

TEST(Camera, RowZeroIsTheTopAndEdgesSpanTheFieldOfView) {
  const PinholeCamera cam = test_camera();
  const Ray top = cam.generate(32, 0), bottom = cam.generate(32, 48);
  EXPECT_GT(glm::dot(top.direction, cam.up), 0);
  EXPECT_LT(glm::dot(bottom.direction, cam.up), 0);
  // The vertical angle between the top and bottom edge rays is fov_y.
  EXPECT_NEAR(glm::degrees(std::acos(glm::dot(top.direction, bottom.direction))), 50.0, 1e-9);
  const Ray left = cam.generate(0, 24);
  EXPECT_LT(glm::dot(left.direction, cam.right), 0);
}

TEST(Camera, DerivativesMatchFiniteDifferences) {
  const PinholeCamera cam = test_camera();
  for (auto [px, py] : {std::pair{0.3, 0.7}, {31.5, 20.25}, {63.9, 47.1}}) {
    const RayDerivatives d = cam.derivatives(px, py);
    const double h = 1e-5;
    const Vec3d fx = (cam.generate(px + h, py).direction - cam.generate(px - h, py).direction) / (2 * h);
    const Vec3d fy = (cam.generate(px, py + h).direction - cam.generate(px, py - h).direction) / (2 * h);
    EXPECT_NEAR(glm::length(d.dd_dx - fx), 0, 1e-8 * glm::length(fx));
    EXPECT_NEAR(glm::length(d.dd_dy - fy), 0, 1e-8 * glm::length(fy));
    EXPECT_EQ(glm::length(d.dp_dx), 0);
  }
}

}  // namespace
}  // namespace raylod
