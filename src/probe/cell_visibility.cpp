#include "probe/cell_visibility.h"

#include <algorithm>
#include <cmath>
#include <limits>

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

namespace raylod {

namespace {

// Two unit vectors completing w to an orthonormal basis.
void basis_around(const Vec3d& w, Vec3d& u, Vec3d& v) {
  const Vec3d a = std::abs(w.x) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
  u = glm::normalize(glm::cross(a, w));
  v = glm::cross(w, u);
}

// The corners of the cube of half-side r around p, which holds the ball.
std::array<Vec3d, 8> cube_corners(const Vec3d& p, double r) {
  std::array<Vec3d, 8> c;
  for (int i = 0; i < 8; ++i) c[size_t(i)] = p + Vec3d(i & 1 ? r : -r, i & 2 ? r : -r, i & 4 ? r : -r);
  return c;
}

// The float at or below v.
float float_down(double v) {
  float f = float(v);
  if (double(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace

ShadowReceivers::Rect ShadowReceivers::project(const std::array<Vec3d, 8>& c) const {
  // A box's shadow from the light, on a plane across its rays, lies within
  // the rectangle of its corners' projections (the projection of a convex
  // box is the hull of its corners', in perspective while every corner is
  // in front of the light).
  Rect r;
  r.x0 = r.y0 = std::numeric_limits<double>::infinity();
  r.x1 = r.y1 = -std::numeric_limits<double>::infinity();
  int behind = 0;
  for (const Vec3d& q : c) {
    const Vec3d d = q - origin_;
    double x = glm::dot(d, u_), y = glm::dot(d, v_);
    if (point_) {
      const double z = glm::dot(d, w_);
      if (std::isnan(z)) return Rect{Rect::kStraddles};  // not a point: nothing is ruled out
      if (!(z > 0)) { ++behind; continue; }
      x /= z;
      y /= z;
    }
    r.x0 = std::min(r.x0, x);
    r.x1 = std::max(r.x1, x);
    r.y0 = std::min(r.y0, y);
    r.y1 = std::max(r.y1, y);
  }
  if (behind == 8) r.where = Rect::kBehind;
  else if (behind > 0 || !(std::isfinite(r.x0) && std::isfinite(r.x1) && std::isfinite(r.y0) && std::isfinite(r.y1)))
    r.where = Rect::kStraddles;
  return r;
}

ShadowReceivers ShadowReceivers::make(const Light& light, std::span<const ShadowReceiver> receivers) {
  ShadowReceivers s;
  if (receivers.empty()) return s;
  s.empty_ = false;
  s.point_ = light.type == LightType::Point;
  const double reach = std::sqrt(3.0);  // a receiver's cube reaches sqrt(3) radius from its point
  if (s.point_) {
    s.origin_ = light.position;
    Vec3d axis(0);
    for (const ShadowReceiver& r : receivers) {
      const Vec3d d = r.point - light.position;
      const double len = glm::length(d);
      if (!(len > 2 * reach * r.radius)) { s.always_ = true; return s; }
      axis += d / len;
    }
    if (!(glm::length(axis) > 0)) { s.always_ = true; return s; }
    s.w_ = glm::normalize(axis);
    const double cos_limit = std::cos(75.0 * 3.14159265358979323846 / 180.0);
    for (const ShadowReceiver& r : receivers) {
      const Vec3d d = r.point - light.position;
      if (glm::dot(d, s.w_) - reach * r.radius < cos_limit * glm::length(d)) { s.always_ = true; return s; }
    }
  } else {
    s.w_ = -glm::normalize(light.direction);
  }
  basis_around(s.w_, s.u_, s.v_);
  std::vector<Rect> rects(receivers.size());
  std::vector<float> low(receivers.size());
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  for (size_t i = 0; i < receivers.size(); ++i) {
    const ShadowReceiver& r = receivers[i];
    rects[i] = s.project(cube_corners(r.point, r.radius));
    if (rects[i].where != Rect::kFront) { s.always_ = true; return s; }
    low[i] = float_down(s.point_ ? -(glm::length(r.point - light.position) + reach * r.radius)
                                 : glm::dot(r.point, s.w_) - reach * r.radius);
    x0 = std::min(x0, rects[i].x0);
    x1 = std::max(x1, rects[i].x1);
    y0 = std::min(y0, rects[i].y0);
    y1 = std::max(y1, rects[i].y1);
  }
  if (!(std::isfinite(x0) && std::isfinite(x1) && std::isfinite(y0) && std::isfinite(y1))) {
    s.always_ = true;
    return s;
  }
  s.x0_ = x0;
  s.y0_ = y0;
  s.x1_ = x1;
  s.y1_ = y1;
  s.bin_ = std::max(x1 - x0, y1 - y0) / kGrid;
  if (!(s.bin_ > 0)) s.bin_ = std::max({std::abs(x0), std::abs(y0), 1.0}) * 1e-12;
  std::vector<float> grid(size_t(kGrid) * kGrid, std::numeric_limits<float>::infinity());
  // Clamped as doubles: a quotient past int's range is not converted.
  auto bin = [&](double t) { return int(std::clamp(std::floor(t / s.bin_), 0.0, double(kGrid - 1))); };
  for (size_t i = 0; i < receivers.size(); ++i) {
    const int bx1 = bin(rects[i].x1 - x0), by1 = bin(rects[i].y1 - y0);
    for (int y = bin(rects[i].y0 - y0); y <= by1; ++y)
      for (int x = bin(rects[i].x0 - x0); x <= bx1; ++x) {
        float& g = grid[size_t(y) * kGrid + size_t(x)];
        g = std::min(g, low[i]);
      }
  }
  s.levels_.push_back(std::move(grid));
  for (int n = kGrid; n > 1; n /= 2) {
    const std::vector<float>& fine = s.levels_.back();
    const size_t m = size_t(n / 2), f = size_t(n);
    std::vector<float> coarse(m * m);
    for (size_t y = 0; y < m; ++y)
      for (size_t x = 0; x < m; ++x)
        coarse[y * m + x] = std::min({fine[2 * y * f + 2 * x], fine[2 * y * f + 2 * x + 1], fine[(2 * y + 1) * f + 2 * x],
                                      fine[(2 * y + 1) * f + 2 * x + 1]});
    s.levels_.push_back(std::move(coarse));
  }
  return s;
}

bool ShadowReceivers::may_shadow(const std::array<Vec3d, 8>& c, const Bbox& wb) const {
  if (empty_) return false;
  if (always_) return true;
  const Rect r = project(c);
  if (r.where == Rect::kBehind) return false;  // every receiver is in front of the light
  if (r.where == Rect::kStraddles) return true;
  // How near the light the box comes.
  double near = -std::numeric_limits<double>::infinity();
  if (point_) near = -glm::length(glm::clamp(origin_, wb.lo, wb.hi) - origin_);
  else
    for (const Vec3d& q : c) near = std::max(near, glm::dot(q, w_));
  if (r.x1 < x0_ || r.y1 < y0_ || r.x0 > x1_ || r.y0 > y1_) return false;  // beside every receiver
  // The finest level at which the rectangle spans at most two bins a side.
  const double extent = std::max(r.x1 - r.x0, r.y1 - r.y0);
  size_t level = 0;
  while (level + 1 < levels_.size() && extent > bin_ * double(size_t(1) << level)) ++level;
  const int n = kGrid >> level;
  const double side = bin_ * double(size_t(1) << level);
  // Clamped as doubles: a box far wider than the receivers' spread (one
  // receiver has none) gives quotients past int's range.
  auto bin = [&](double t) { return int(std::clamp(std::floor(t / side), 0.0, double(n - 1))); };
  const std::vector<float>& g = levels_[level];
  const int bx1 = bin(r.x1 - x0_), by1 = bin(r.y1 - y0_);
  for (int y = bin(r.y0 - y0_); y <= by1; ++y)
    for (int x = bin(r.x0 - x0_); x <= bx1; ++x)
      if (near >= double(g[size_t(y) * size_t(n) + size_t(x)])) return true;
  return false;
}

}  // namespace raylod
