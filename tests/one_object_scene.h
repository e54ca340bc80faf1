// A test scene of one object: material 0 of `type` (glass and the like with
// an index of 1.5), a diffuse floor material 1, and where asked a ground
// plane of that floor (height 0, 40 wide) and a default light.
#pragma once

#include "scene/scene.h"

namespace raylod::test {

inline Scene one_object_scene(MaterialType type, const Vec3d& eye, const Vec3d& look_at, int width, int height,
                              double fov_y_deg, bool ground, bool lights) {
  Scene s;
  s.camera.eye = eye;
  s.camera.look_at = look_at;
  s.camera.width = width;
  s.camera.height = height;
  s.camera.fov_y_deg = fov_y_deg;
  Material m;
  m.name = "object";
  m.type = type;
  m.ior = 1.5f;
  Material floor;
  floor.name = "floor";
  s.materials = {m, floor};
  if (ground) s.ground = Ground{0.0, 40.0, 1};
  if (lights) s.lights.push_back(Light{});
  return s;
}

}  // namespace raylod::test
