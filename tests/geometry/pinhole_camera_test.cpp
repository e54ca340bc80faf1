// The pinhole camera's pixel -> ray mapping and its derivatives
// (geometry/pinhole_camera.h), shared by the renderer and the probe.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
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

TEST(Camera, SmallestPixelAngleOverABoxIsThatOfItsPixels) {
  // Against brute force: the angles of every pixel whose centre sees a
  // point of the box's projection (a dense grid of its image-plane box), in
  // a narrow and two wide views; the bound must never exceed any of them
  // and must come within 2% of their minimum (the bound's corner lies
  // between pixel centres).
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const double fov : {30.0, 120.0, 170.0}) {
    const PinholeCamera cam = make_pinhole_camera(Vec3d(0), Vec3d(0, 0, -1), Vec3d(0, 1, 0), fov, 160, 120);
    int checked = 0;
    for (int trial = 0; trial < 60; ++trial) {
      const Vec3d centre(4 * u(rng), 3 * u(rng), -5 + 2 * u(rng)), half(0.05 + 0.5 * std::abs(u(rng)));
      std::array<Vec3d, 8> corners;
      for (int i = 0; i < 8; ++i)
        corners[size_t(i)] = centre + Vec3d(i & 1 ? half.x : -half.x, i & 2 ? half.y : -half.y, i & 4 ? half.z : -half.z);
      const double bound = smallest_pixel_angle_over(cam, corners);
      ASSERT_GT(bound, 0) << "in front of the eye";
      // The pixels of the corners' image-plane box.
      double x_lo = 1e9, x_hi = -1e9, y_lo = 1e9, y_hi = -1e9;
      for (const Vec3d& p : corners) {
        const double px = 0.5 * cam.width * (1 + glm::dot(p, cam.right) / -p.z / cam.tan_half_x);
        const double py = 0.5 * cam.height * (1 - glm::dot(p, cam.up) / -p.z / cam.tan_half_y);
        x_lo = std::min(x_lo, px), x_hi = std::max(x_hi, px), y_lo = std::min(y_lo, py), y_hi = std::max(y_hi, py);
      }
      x_lo = std::max(x_lo, 0.0), y_lo = std::max(y_lo, 0.0);
      x_hi = std::min(x_hi, double(cam.width)), y_hi = std::min(y_hi, double(cam.height));
      if (!(x_lo < x_hi && y_lo < y_hi)) continue;  // off the image
      double brute = 1e9;
      for (int i = 0; i <= 40; ++i)
        for (int j = 0; j <= 40; ++j) {
          const RayDerivatives d = cam.derivatives(x_lo + (x_hi - x_lo) * i / 40.0, y_lo + (y_hi - y_lo) * j / 40.0);
          brute = std::min({brute, glm::length(d.dd_dx), glm::length(d.dd_dy)});
        }
      EXPECT_LE(bound, brute * (1 + 1e-12)) << "fov " << fov << " trial " << trial;
      // The ball around the box (the probe's cheaper bound) gives no more,
      // and not much less for these boxes, seen from 3 to 7 times their size.
      const double ball = smallest_pixel_angle_over_ball(cam, centre, glm::length(half));
      EXPECT_LE(ball, bound * (1 + 1e-12)) << "fov " << fov << " trial " << trial;
      EXPECT_GE(ball, 0.25 * bound) << "fov " << fov << " trial " << trial;
      EXPECT_GE(bound, 0.98 * brute) << "fov " << fov << " trial " << trial;
      ++checked;
    }
    EXPECT_GT(checked, 10) << "fov " << fov;
    // At the centre of a wide view a pixel subtends far more than at its
    // corners, and a box there gets the centre's angle.
    const std::array<Vec3d, 2> centre_box{Vec3d(-0.01, -0.01, -5), Vec3d(0.01, 0.01, -5.1)};
    const double at_centre = smallest_pixel_angle_over(cam, centre_box);
    EXPECT_NEAR(at_centre, cam.pixel_angle(), 1e-3 * cam.pixel_angle()) << "fov " << fov;
    EXPECT_NEAR(smallest_pixel_angle_over_ball(cam, Vec3d(0, 0, -5), 0.01), cam.pixel_angle(), 1e-3 * cam.pixel_angle());
    EXPECT_EQ(smallest_pixel_angle_over_ball(cam, Vec3d(0, 0, -1), 1.5), 0.0);  // reaches behind the eye
    // A point behind the eye's plane: no bound (0).
    const std::array<Vec3d, 2> behind{Vec3d(0, 0, -1), Vec3d(0, 0, 1)};
    EXPECT_EQ(smallest_pixel_angle_over(cam, behind), 0.0);
  }
}

}  // namespace
}  // namespace raylod
