// Pinhole camera: the one mapping from continuous pixel coordinates to rays,
// shared by the renderer and by the probe's test rays (whose ray
// differentials must be the exact derivatives of this mapping, Igehy 1999).
#pragma once

#include "core/math.h"
#include "geometry/ray.h"

namespace raylod {

// Derivatives of a camera ray with respect to the continuous pixel
// coordinates: <dP/dx, dD/dx> and <dP/dy, dD/dy> of the paper's eq. (1), per
// pixel (dx = dy = 1 is the neighbouring pixel). D is the unit direction.
struct RayDerivatives {
  Vec3d dp_dx{0}, dp_dy{0};  // zero for a pinhole: all rays start at the eye
  Vec3d dd_dx{0}, dd_dy{0};
};

// Pixel (i, j) covers [i, i+1) x [j, j+1); its centre is (i + 0.5, j + 0.5);
// x grows to the right, y grows DOWN (row 0 is the top row of the image).
//
//   w = normalize(look_at - eye), u = normalize(w x up), v = u x w
//   t_y = tan(fov_y / 2), t_x = t_y * width / height
//   d(px, py) = w + (2 px / width - 1) t_x u + (1 - 2 py / height) t_y v
//   D = d / |d|,  P = eye
//
// so dd/dpx = (2 t_x / width) u, dd/dpy = -(2 t_y / height) v, and
// dD/dp = (|d|^2 dd/dp - (d . dd/dp) d) / |d|^3   (Igehy 1999, eq. 9).
struct PinholeCamera {
  Vec3d eye{0};
  Vec3d forward{0, 0, -1};  // w
  Vec3d right{1, 0, 0};     // u
  Vec3d up{0, 1, 0};        // v (orthogonal to w and u)
  double tan_half_x = 0, tan_half_y = 0;
  int width = 1, height = 1;

  // Unnormalised direction d(px, py) of the mapping above.
  Vec3d direction_unnormalized(double px, double py) const;
  // The camera ray through the continuous pixel position (px, py).
  Ray generate(double px, double py) const;
  // Its derivatives with respect to px and py.
  RayDerivatives derivatives(double px, double py) const;
  // Angle subtended by one pixel at the image centre (radians, vertical);
  // the footprint of a pixel at distance t is about t * pixel_angle().
  double pixel_angle() const { return 2.0 * tan_half_y / height; }
};

// Builds the camera looking from eye towards look_at, with up the rough up
// direction and fov_y_deg the vertical field of view in degrees, for an image
// of width x height pixels (values validated by the caller, e.g. parse_scene;
// the scene's Camera goes through scene/scene_camera.h).
PinholeCamera make_pinhole_camera(const Vec3d& eye, const Vec3d& look_at, const Vec3d& up, double fov_y_deg, int width,
                                  int height);

}  // namespace raylod
