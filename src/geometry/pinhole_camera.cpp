// Pinhole camera mapping; see pinhole_camera.h for the formulas.
#include "geometry/pinhole_camera.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace raylod {

PinholeCamera make_pinhole_camera(const Vec3d& eye, const Vec3d& look_at, const Vec3d& up, double fov_y_deg, int width,
                                  int height) {
  PinholeCamera cam;
  cam.eye = eye;
  cam.forward = glm::normalize(look_at - eye);
  cam.right = glm::normalize(glm::cross(cam.forward, up));
  cam.up = glm::cross(cam.right, cam.forward);
  cam.width = width;
  cam.height = height;
  cam.tan_half_y = std::tan(glm::radians(fov_y_deg) * 0.5);
  cam.tan_half_x = cam.tan_half_y * double(width) / double(height);
  return cam;
}

Vec3d PinholeCamera::direction_unnormalized(double px, double py) const {
  const double sx = (2.0 * px / width - 1.0) * tan_half_x;
  const double sy = (1.0 - 2.0 * py / height) * tan_half_y;
  return forward + sx * right + sy * up;
}

Ray PinholeCamera::generate(double px, double py) const {
  return Ray{eye, glm::normalize(direction_unnormalized(px, py))};
}

RayDerivatives PinholeCamera::derivatives(double px, double py) const {
  const Vec3d d = direction_unnormalized(px, py);
  const double dd = glm::dot(d, d);
  const double inv_len3 = 1.0 / (dd * std::sqrt(dd));
  const Vec3d ddx = (2.0 * tan_half_x / width) * right;
  const Vec3d ddy = (-2.0 * tan_half_y / height) * up;
  RayDerivatives r;
  // Derivative of d / |d| (Igehy 1999, eq. 9 with the camera's dd/dp).
  r.dd_dx = (dd * ddx - glm::dot(d, ddx) * d) * inv_len3;
  r.dd_dy = (dd * ddy - glm::dot(d, ddy) * d) * inv_len3;
  return r;
}

namespace {

// The smallest of |dD/dx| and |dD/dy| over the corners of [x0, x1] x [y0,
// y1], ranges of |s_x| and |s_y| already clamped to the image
// (smallest_pixel_angle_over).
double smallest_pixel_angle_at(const PinholeCamera& cam, const std::array<double, 2>& ax,
                               const std::array<double, 2>& ay) {
  // The closed forms (derivatives() at that pixel, squared), with k_x = 2
  // tan_half_x / width and k_y = 2 tan_half_y / height.
  const double kx = 2.0 * cam.tan_half_x / cam.width, ky = 2.0 * cam.tan_half_y / cam.height;
  double a2 = std::numeric_limits<double>::infinity();
  for (const double sx : ax)
    for (const double sy : ay) {
      const double r2 = 1.0 + sx * sx + sy * sy;
      a2 = std::min(a2, std::min(kx * kx * (1.0 + sy * sy), ky * ky * (1.0 + sx * sx)) / (r2 * r2));
    }
  return std::sqrt(a2);
}

// |s| over [lo, hi] clamped to the image's [-t, t]: from the nearer of 0 and
// the range to its farther end.
std::array<double, 2> abs_range(double lo, double hi, double t) {
  lo = std::clamp(lo, -t, t), hi = std::clamp(hi, -t, t);
  const double far = std::max(std::abs(lo), std::abs(hi));
  const double near = lo <= 0 && hi >= 0 ? 0.0 : std::min(std::abs(lo), std::abs(hi));
  return {near, far};
}

}  // namespace

double smallest_pixel_angle_over_ball(const PinholeCamera& cam, const Vec3d& centre, double radius) {
  const Vec3d q = centre - cam.eye;
  const double z = glm::dot(q, cam.forward);
  if (!(z - radius > 0)) return 0;
  // Every point of the ball has |x'| <= |x| + r and z' >= z - r (and |x'|
  // >= |x| - r, z' <= z + r), so |s_x| = |x'| / z' lies in this range.
  const double x = std::abs(glm::dot(q, cam.right)), y = std::abs(glm::dot(q, cam.up));
  const double near = 1.0 / (z + radius), far = 1.0 / (z - radius);
  return smallest_pixel_angle_at(cam, abs_range(std::max(0.0, x - radius) * near, (x + radius) * far, cam.tan_half_x),
                                 abs_range(std::max(0.0, y - radius) * near, (y + radius) * far, cam.tan_half_y));
}

double smallest_pixel_angle_over(const PinholeCamera& cam, std::span<const Vec3d> points) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  double x_lo = kInf, x_hi = -kInf, y_lo = kInf, y_hi = -kInf;
  for (const Vec3d& p : points) {
    const Vec3d q = p - cam.eye;
    const double z = glm::dot(q, cam.forward);
    if (!(z > 0)) return 0;
    const double x = glm::dot(q, cam.right) / z, y = glm::dot(q, cam.up) / z;
    x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x), y_lo = std::min(y_lo, y), y_hi = std::max(y_hi, y);
  }
  if (points.empty()) return 0;
  return smallest_pixel_angle_at(cam, abs_range(x_lo, x_hi, cam.tan_half_x), abs_range(y_lo, y_hi, cam.tan_half_y));
}

}  // namespace raylod
