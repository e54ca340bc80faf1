// The scene's camera as the pinhole camera the renderer and the probe share.
// Header-only, so that raylod_scene itself does not link raylod_geometry:
// whoever includes this links both (the renderer, the probe, the pipeline).
#pragma once

#include "geometry/pinhole_camera.h"
#include "scene/scene.h"

namespace raylod {

// Builds the camera from the scene's description (validated by parse_scene).
inline PinholeCamera make_pinhole_camera(const Camera& c) {
  return make_pinhole_camera(c.eye, c.look_at, c.up, c.fov_y_deg, c.width, c.height);
}

}  // namespace raylod
