// Ray and RayDifferential for the probe (method steps A2/A3), after pbrt's
// RayDifferential: a ray plus the derivatives of its origin and direction with
// respect to the continuous pixel coordinates (Igehy 1999; METHOD.md eq. 1).
//
// The Ray itself is the renderer's (render/camera.h), so the probe's test rays
// and the rendered rays come from one pixel -> ray mapping.
#pragma once

#include "core/math.h"
#include "render/camera.h"

namespace raylod {

struct RayDifferential {
  Ray ray;                       // origin P and unit direction D (world units)
  Vec3d dp_dx{0}, dp_dy{0};      // dP/dx, dP/dy per pixel
  Vec3d dd_dx{0}, dd_dy{0};      // dD/dx, dD/dy per pixel
  // False once the differentials blew up and were dropped (see
  // ray_differential.h for the rule); the hit's footprint is then estimated.
  bool has_differentials = false;
};

}  // namespace raylod
