// Pinhole camera: the one mapping from continuous pixel coordinates to rays,
// shared by the renderer and by the probe's test rays (whose ray
// differentials must be the exact derivatives of this mapping, Igehy 1999).
#pragma once

#include <span>

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

// The smallest angle between neighbouring pixels' rays, |dD/dx| or |dD/dy|,
// over the pixels the points project to (their image-plane bounding box,
// clamped to the image); 0 if a point lies at or behind the eye's plane.
// A pixel's angle shrinks away from the image centre: at the image-plane
// point (s_x, s_y) = (d.u, d.v) / (d.w), |dD/dx|^2 = k^2 (1 + s_y^2) / (1 +
// s_x^2 + s_y^2)^2 with k = 2 tan_half_x / width (likewise dD/dy), which
// falls as |s_x| grows and, along s_y, is least at an end of the range; so
// the four corners of the box's |s_x| x |s_y| range hold the minimum. In a
// wide view a mesh near the centre is then bounded by its own pixels, not
// by the image's corners (at fov_y 150, cos^2(75 deg) = 0.07 of the centre's).
double smallest_pixel_angle_over(const PinholeCamera& cam, std::span<const Vec3d> points);
// The same over a ball (centre, radius), from a range of |s_x| and |s_y|
// that holds every point of it (a little wider than the ball's image):
// cheaper, for the probe's many cells; never larger than the points' bound
// for points inside the ball.
double smallest_pixel_angle_over_ball(const PinholeCamera& cam, const Vec3d& centre, double radius);

// Builds the camera looking from eye towards look_at, with up the rough up
// direction and fov_y_deg the vertical field of view in degrees, for an image
// of width x height pixels (values validated by the caller, e.g. parse_scene;
// the scene's Camera goes through scene/scene_camera.h).
PinholeCamera make_pinhole_camera(const Vec3d& eye, const Vec3d& look_at, const Vec3d& up, double fov_y_deg, int width,
                                  int height);

}  // namespace raylod
