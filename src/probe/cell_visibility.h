#pragma once
// Whether a view's camera can see an octree cell (probe.h, "Unseen cells"):
// outside the view frustum, facing away from the eye, and where a light's
// shadow of it may fall. Tests of whole boxes, one-sided: a cell is said
// unseen only when no point of its box can be seen (facing away: up to a
// given share of its area).
#include <array>

#include "core/math.h"
#include "geometry/pinhole_camera.h"
#include "scene/scene.h"

namespace raylod {

// The planes of the view frustum through the eye: the four sides and the
// eye's own (normal `forward`), inward normals.
struct Frustum {
  Vec3d eye{0}, forward{0};
  std::array<Vec3d, 4> normals{};
  // The box with corners `c` lies wholly outside one of the planes.
  bool outside(const std::array<Vec3d, 8>& c) const;
  // The shadow a light casts from the box with corners `c` (the box swept
  // away from the light: along a directional light's direction, away from
  // a point light's position) lies wholly outside one of the planes: then
  // nothing the camera sees directly lies in it. A sufficient test, a
  // separating plane among the frustum's.
  bool shadow_outside(const std::array<Vec3d, 8>& c, const Light& l) const;
};

Frustum make_frustum(const PinholeCamera& cam);

// Whether the surface in `box`, whose area's normals have the unit mean
// `mean` and mean resultant length `resultant` (|sum of area-weighted
// normals| / area), faces away from `eye` from every point of the box, on
// all but at most `front_share` of its area. With x = n . u (u the unit
// direction from the eye to the box's centre), x exceeds t = 2 sin(beta / 2)
// (beta: the box's angular radius from the eye, how far the direction to a
// point of the box turns from u) on all but a share Var / (Var + (E x -
// t)^2) of the area (Cantelli's inequality), with E x = resultant (mean . u)
// and Var at most 1 - resultant^2 (the normals' total variance). False if
// the eye is within the box's bounding ball.
bool faces_away(const Vec3d& eye, const Bbox& box, const Vec3d& mean, double resultant, double front_share);

}  // namespace raylod
