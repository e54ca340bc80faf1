#include "scene/orbit.h"

#include <cmath>
#include <numbers>
#include <string>

namespace raylod {

StatusOr<std::vector<Camera>> orbit_cameras(const Camera& camera, int n) {
  if (n < 1) return Status::error("--orbit needs at least 1 view, not " + std::to_string(n));
  const Vec3d axis = glm::normalize(camera.up);
  const Vec3d offset = camera.eye - camera.look_at;
  const Vec3d height = axis * glm::dot(offset, axis);
  const Vec3d radial = offset - height;
  if (!(glm::length(radial) > 1e-9 * glm::length(offset)))
    return Status::error("--orbit: the scene's eye is straight above or below its look_at point (along up): no circle to orbit on");
  const Vec3d side = glm::cross(axis, radial);  // radial turned a quarter about the axis, same length
  std::vector<Camera> views;
  for (int i = 0; i < n; ++i) {
    Camera c = camera;
    if (i > 0) {
      const double angle = 2.0 * std::numbers::pi * double(i) / double(n);
      c.eye = camera.look_at + height + radial * std::cos(angle) + side * std::sin(angle);
    }
    views.push_back(c);
  }
  return views;
}

}  // namespace raylod
