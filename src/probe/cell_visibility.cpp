#include "probe/cell_visibility.h"

#include <algorithm>
#include <cmath>

namespace raylod {

bool Frustum::outside(const std::array<Vec3d, 8>& c) const {
  auto all_below = [&](const Vec3d& n) {
    for (const Vec3d& p : c)
      if (glm::dot(n, p - eye) >= 0) return false;
    return true;
  };
  if (all_below(forward)) return true;  // wholly behind the eye
  for (const Vec3d& n : normals)
    if (all_below(n)) return true;
  return false;
}

bool Frustum::shadow_outside(const std::array<Vec3d, 8>& c, const Light& l) const {
  auto swept_below = [&](const Vec3d& n) {
    for (const Vec3d& p : c) {
      const Vec3d away = l.type == LightType::Directional ? l.direction : p - l.position;
      if (glm::dot(n, p - eye) >= 0 || glm::dot(n, away) > 0) return false;
    }
    return true;
  };
  if (swept_below(forward)) return true;
  for (const Vec3d& n : normals)
    if (swept_below(n)) return true;
  return false;
}

Frustum make_frustum(const PinholeCamera& cam) {
  Frustum f;
  f.eye = cam.eye;
  f.forward = cam.forward;
  const double w = cam.width, h = cam.height;
  const Vec3d tl = cam.direction_unnormalized(0, 0), tr = cam.direction_unnormalized(w, 0);
  const Vec3d bl = cam.direction_unnormalized(0, h), br = cam.direction_unnormalized(w, h);
  const std::array<std::pair<Vec3d, Vec3d>, 4> edges{{{tl, bl}, {tr, br}, {tl, tr}, {bl, br}}};
  for (int i = 0; i < 4; ++i) {
    Vec3d n = glm::normalize(glm::cross(edges[i].first, edges[i].second));
    if (glm::dot(n, cam.forward) < 0) n = -n;
    f.normals[i] = n;
  }
  return f;
}

bool faces_away(const Vec3d& eye, const Bbox& box, const Vec3d& mean, double resultant, double front_share) {
  const double var = std::max(0.0, 1.0 - resultant * resultant);
  const Vec3d centre = 0.5 * (box.lo + box.hi);
  const double radius = 0.5 * glm::length(box.hi - box.lo);
  const Vec3d d = centre - eye;
  const double dist = glm::length(d);
  if (!(dist > radius)) return false;
  const double turn = 2.0 * std::sin(0.5 * std::asin(radius / dist));
  const double margin = resultant * glm::dot(mean, d) / dist - turn;
  return margin > 0 && var <= front_share * (var + margin * margin);
}

}  // namespace raylod
