// Pinhole camera mapping; see pinhole_camera.h for the formulas.
#include "geometry/pinhole_camera.h"

#include <cmath>

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

}  // namespace raylod
