// `raylod run --orbit N`: N cameras on a horizontal circle around a camera's
// look-at point (horizontal: in the plane through the eye perpendicular to the
// camera's up vector), at the eye's radius and height, the first at the eye
// itself, evenly spaced counter-clockwise seen from above (right-handed about
// up). Each keeps the camera's look_at, up, fov_y and image size.
#pragma once

#include <vector>

#include "core/status.h"
#include "scene/scene.h"

namespace raylod {

// An error if n < 1 or the eye is on the axis through look_at along up (no circle).
StatusOr<std::vector<Camera>> orbit_cameras(const Camera& camera, int n);

}  // namespace raylod
