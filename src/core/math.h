// Small math layer over GLM: aliases and an axis-aligned bounding box.
// Float for storage and rendering; double where precision matters
// (quadrics, bounds of CAD coordinates far from the origin).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/glm.hpp>

namespace raylod {

using Vec2 = glm::vec2;
using Vec3 = glm::vec3;
using Vec4 = glm::vec4;
using Vec3d = glm::dvec3;
using Mat3d = glm::dmat3;
using Mat4 = glm::mat4;

inline bool is_finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
inline bool is_finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Axis-aligned box in double; empty() until the first point is added.
struct Bbox {
  Vec3d lo{std::numeric_limits<double>::infinity()};
  Vec3d hi{-std::numeric_limits<double>::infinity()};

  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  void expand(const Vec3d& p) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
  void expand(const Vec3& p) { expand(Vec3d(p)); }
  void expand(const Bbox& b) { if (!b.empty()) { expand(b.lo); expand(b.hi); } }
  Vec3d extent() const { return empty() ? Vec3d(0) : hi - lo; }
  Vec3d center() const { return (lo + hi) * 0.5; }
  double diagonal() const { return glm::length(extent()); }
  bool contains(const Vec3d& p) const {
    return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
  }
  // Smallest cube with the same centre that contains this box.
  Bbox bounding_cube() const {
    Vec3d c = center();
    double h = 0.5 * std::max({extent().x, extent().y, extent().z});
    return Bbox{c - Vec3d(h), c + Vec3d(h)};
  }
};

// Unit normal of triangle (a, b, c) by the right-hand rule, or zero if degenerate.
inline Vec3d face_normal(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  Vec3d n = glm::cross(b - a, c - a);
  double len = glm::length(n);
  return len > 0 ? n / len : Vec3d(0);
}

}  // namespace raylod
