// Ray and RayDifferential, after pbrt's: a ray plus the derivatives of its
// origin and direction with respect to the continuous pixel coordinates
// (Igehy 1999; METHOD.md eq. 1). One type for the renderer's rays and the
// probe's test rays, so both come from one pixel -> ray mapping
// (geometry/pinhole_camera.h).
#pragma once

#include "core/math.h"

namespace raylod {

// A ray with unit-length direction, in double (world units).
struct Ray {
  Vec3d origin{0};
  Vec3d direction{0, 0, -1};
  Vec3d at(double t) const { return origin + t * direction; }
};

struct RayDifferential {
  Ray ray;                       // origin P and unit direction D (world units)
  Vec3d dp_dx{0}, dp_dy{0};      // dP/dx, dP/dy per pixel
  Vec3d dd_dx{0}, dd_dy{0};      // dD/dx, dD/dy per pixel
  // False once the differentials blew up and were dropped (see
  // ray_differential.h for the rule); the hit's footprint is then estimated.
  bool has_differentials = false;
  // The distance travelled from the camera (world units, summed by
  // transfer): what dP/dx is measured against when deciding whether it blew
  // up, so that the rule does not depend on the scene's unit of length.
  double travelled = 0;
};

}  // namespace raylod
