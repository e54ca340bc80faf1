// Small math layer over GLM: aliases and an axis-aligned bounding box.
// Float for storage and rendering; double where precision matters
// (quadrics, bounds of CAD coordinates far from the origin).
#pragma once

#include <algorithm>
#include <array>
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
// The largest absolute coordinate.
inline double max_abs(const Vec3d& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); }

// A triangle's three unit vertex normals whose sum is shorter than this
// cancel: what is left is rounding (floats, and the store's normal codes,
// leave up to about 1e-4), whose direction means nothing, and the face
// normal stands for them (the plane of the triangle's quadric).
inline constexpr double kCancelledNormalSum = 1e-3;

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

// The corners of box b under the affine transform M, corner i taking hi on
// axis k where bit k of i is set. M * (x, y, z, 1) is (M[0] x + M[1] y) +
// (M[2] z + M[3]) as glm evaluates it; each product takes one of two values
// per axis, so the corners are sums of those: the same values, with a
// quarter of the multiplications.
inline std::array<Vec3d, 8> world_corners(const glm::dmat4& M, const Bbox& b) {
  const glm::dvec4 px[2] = {M[0] * b.lo.x, M[0] * b.hi.x}, py[2] = {M[1] * b.lo.y, M[1] * b.hi.y};
  const glm::dvec4 zw[2] = {M[2] * b.lo.z + M[3], M[2] * b.hi.z + M[3]};
  std::array<Vec3d, 8> c;
  for (int i = 0; i < 8; ++i) c[size_t(i)] = Vec3d((px[i & 1] + py[(i >> 1) & 1]) + zw[(i >> 2) & 1]);
  return c;
}

// The box around b's corners under M (empty if b is).
inline Bbox world_bounds(const glm::dmat4& M, const Bbox& b) {
  Bbox out;
  if (b.empty()) return out;
  for (const Vec3d& c : world_corners(M, b)) out.expand(c);
  return out;
}

// Unit normal of triangle (a, b, c) by the right-hand rule, or zero if degenerate.
inline Vec3d face_normal(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  Vec3d n = glm::cross(b - a, c - a);
  double len = glm::length(n);
  return len > 0 ? n / len : Vec3d(0);
}

}  // namespace raylod
