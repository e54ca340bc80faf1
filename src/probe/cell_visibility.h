#pragma once
// Whether a view's camera can see an octree cell (probe.h, "Unseen cells"):
// outside the view frustum, facing away from the eye, and where a light's
// shadow of it may fall. Tests of whole boxes, one-sided: a cell is said
// unseen only when no point of its box can be seen (facing away: up to a
// given share of its area).
#include <array>
#include <span>
#include <vector>

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

namespace raylod {

// Where a light's shadows can be seen in a view (probe.h, "Unseen cells"):
// the points its test rays met, each standing for the surface within
// `radius` of it (out to the neighbouring test rays), seen from the light.
// An unseen cell can move the edge of a shadow the camera sees only if some
// point of it lies between the light and such a surface.
struct ShadowReceiver {
  Vec3d point{0};
  double radius = 0;
};

// The receivers of one light, binned on a grid across the light's rays (a
// directional light's plane; for a point light the plane through the
// receivers' mean direction, seen in perspective from the light), each bin
// holding how near the light the receivers over it come, less their radius.
class ShadowReceivers {
 public:
  static constexpr int kGrid = 128;  // bins per side
  // No receivers: may_shadow is always false. A point light within a
  // receiver's reach, or receivers not within 75 degrees of one direction
  // from it: always true.
  static ShadowReceivers make(const Light& light, std::span<const ShadowReceiver> receivers);
  // Whether some point of the box with world corners `c` (world bounding
  // box `wb`) may lie between the light and some point of a receiver's
  // reach. One-sided: false only where none can.
  bool may_shadow(const std::array<Vec3d, 8>& c, const Bbox& wb) const;

 private:
  struct Rect {
    enum { kFront, kBehind, kStraddles } where = kFront;  // of a point light's plane
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  };
  Rect project(const std::array<Vec3d, 8>& c) const;
  bool always_ = false, empty_ = true, point_ = false;
  Vec3d origin_{0}, u_{0}, v_{0}, w_{0};  // w: towards a directional light; a point light's axis
  double x0_ = 0, y0_ = 0, bin_ = 1;      // the grid's corner and its bins' side
  double x1_ = 0, y1_ = 0;                // the receivers' farthest projected extent
  // levels_[k]: (kGrid >> k)^2 bins, each the least nearness to the light
  // (along w for a directional light, minus the distance from a point
  // light) of the receivers' reach over it, rounded down; +inf where none.
  std::vector<std::vector<float>> levels_;
};

}  // namespace raylod
