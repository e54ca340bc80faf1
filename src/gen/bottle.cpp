#include "gen/bottle.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

namespace raylod {
namespace {

using glm::dvec2;
constexpr double kPi = std::numbers::pi;

// The shoulder: a convex arc leaving the body vertically and a concave arc
// arriving at the neck vertically, tangent to each other. Both sweep the same
// angle phi; with radii a + b = k the spans are k (1 - cos phi) = dr and
// k sin phi = dy, so tan(phi / 2) = dr / dy.
struct Shoulder {
  double phi, a, b;
};
Shoulder shoulder(const BottleConfig& c) {
  const double dr = c.body_radius - c.neck_radius, dy = c.neck_start - c.shoulder_start;
  const double phi = 2.0 * std::atan2(dr, dy);
  const double k = dy / std::sin(phi);
  return {phi, c.convex_share * k, (1.0 - c.convex_share) * k};
}

// Lip or top fillet radius of the solid bottle.
double top_fillet(const BottleConfig& c) { return std::min(0.1, 0.5 * c.neck_radius); }

}  // namespace

Status validate_bottle(const BottleConfig& c) {
  auto bad = [](const std::string& what) { return Status::error("bottle: " + what); };
  const double t = c.wall_thickness;
  if (!(c.body_radius > 0) || !(c.neck_radius > 0) || !(c.base_corner_radius > 0))
    return bad("radii must be positive");
  if (!(c.neck_radius < c.body_radius)) return bad("neck_radius must be smaller than body_radius");
  if (!(c.base_corner_radius < c.body_radius)) return bad("base_corner_radius must be smaller than body_radius");
  if (!(c.shoulder_start > c.base_corner_radius)) return bad("shoulder_start must be above the base fillet");
  if (!(c.neck_start > c.shoulder_start)) return bad("neck_start must be above shoulder_start");
  if (!(c.height > c.neck_start + (t > 0 ? 0.0 : top_fillet(c)))) return bad("height must be above neck_start");
  if (!(c.convex_share > 0 && c.convex_share < 1)) return bad("convex_share must be in (0, 1)");
  if (!(t >= 0)) return bad("wall_thickness must not be negative");
  if (t > 0) {
    const Shoulder s = shoulder(c);
    if (!(t < c.base_corner_radius && t < s.a && t < c.neck_radius))
      return bad("wall_thickness must be smaller than the base fillet, the convex shoulder radius and the neck radius");
  }
  return Status::ok();
}

BottleProfile::Segment BottleProfile::line(dvec2 a, dvec2 b) {
  Segment s;
  s.a = a;
  s.b = b;
  s.length = glm::length(b - a);
  return s;
}

BottleProfile::Segment BottleProfile::arc(dvec2 centre, double radius, double ang0, double ang1) {
  Segment s;
  s.arc = true;
  s.centre = centre;
  s.radius = radius;
  s.ang0 = ang0;
  s.ang1 = ang1;
  s.length = radius * std::abs(ang1 - ang0);
  return s;
}

// The segment moved by d against its outward normal, traversed backwards: the
// inside wall. A counter-clockwise arc's normal points away from its centre, so
// its radius shrinks by d; a clockwise arc's grows.
BottleProfile::Segment BottleProfile::reversed_offset(const Segment& s, double d) {
  if (!s.arc) {
    const dvec2 t = (s.b - s.a) / s.length;
    const dvec2 n(t.y, -t.x);
    return line(s.b - d * n, s.a - d * n);
  }
  const double r = s.ang1 > s.ang0 ? s.radius - d : s.radius + d;
  return arc(s.centre, r, s.ang1, s.ang0);
}

ProfileSample BottleProfile::eval(const Segment& s, double u) {
  const double f = s.length > 0 ? std::clamp(u / s.length, 0.0, 1.0) : 0.0;
  dvec2 p, t;
  if (!s.arc) {
    p = s.a + (s.b - s.a) * f;
    t = (s.b - s.a) / s.length;
  } else {
    const double th = s.ang0 + (s.ang1 - s.ang0) * f;
    p = s.centre + s.radius * dvec2(std::cos(th), std::sin(th));
    t = (s.ang1 > s.ang0 ? 1.0 : -1.0) * dvec2(-std::sin(th), std::cos(th));
  }
  // Outward normal: the tangent turned clockwise (the glass lies to the left
  // of the direction of travel in the (r, y) plane).
  return {p, dvec2(t.y, -t.x)};
}

BottleProfile::BottleProfile(const BottleConfig& c) {
  assert(validate_bottle(c).is_ok());
  const double R = c.body_radius, rc = c.base_corner_radius, rn = c.neck_radius, t = c.wall_thickness;
  const Shoulder sh = shoulder(c);
  // Outside, from the centre of the base to the top of the neck.
  std::vector<Segment> outer;
  outer.push_back(line({0, 0}, {R - rc, 0}));
  outer.push_back(arc({R - rc, rc}, rc, -0.5 * kPi, 0));
  outer.push_back(line({R, rc}, {R, c.shoulder_start}));
  outer.push_back(arc({R - sh.a, c.shoulder_start}, sh.a, 0, sh.phi));
  outer.push_back(arc({rn + sh.b, c.neck_start}, sh.b, kPi + sh.phi, kPi));
  if (t > 0) {
    outer.push_back(line({rn, c.neck_start}, {rn, c.height}));
    segments_ = outer;
    // Over the lip (a half circle as wide as the wall), then down the inside.
    segments_.push_back(arc({rn - 0.5 * t, c.height}, 0.5 * t, 0, kPi));
    for (auto it = outer.rbegin(); it != outer.rend(); ++it) segments_.push_back(reversed_offset(*it, t));
  } else {
    const double rl = top_fillet(c);
    outer.push_back(line({rn, c.neck_start}, {rn, c.height - rl}));
    outer.push_back(arc({rn - rl, c.height - rl}, rl, 0, 0.5 * kPi));
    outer.push_back(line({rn - rl, c.height}, {0, c.height}));
    segments_ = outer;
  }
  for (const auto& s : segments_) {
    starts_.push_back(length_);
    length_ += s.length;
  }
}

ProfileSample BottleProfile::at(double s) const {
  const size_t i = size_t(std::upper_bound(starts_.begin(), starts_.end(), s) - starts_.begin());
  const size_t k = i == 0 ? 0 : i - 1;
  return eval(segments_[k], s - starts_[k]);
}

uint64_t bottle_triangle_count(uint32_t profile_segments, uint32_t around) {
  return 2ull * around * (profile_segments - 1);
}

BottlePlan plan_bottle(uint64_t target, const BottleConfig& config) {
  const BottleProfile profile(config);
  // Equal spacing on the body: 2 pi R / around = length / profile_segments.
  const double ideal = 2.0 * kPi * config.body_radius / profile.length();
  struct Candidate {
    uint32_t n, m;
    uint64_t tri;
    double err, aspect;
  };
  std::vector<Candidate> candidates{{2, 3, bottle_triangle_count(2, 3), 0, 1e300}};
  candidates[0].err = std::abs(double(candidates[0].tri) - double(target));
  const uint32_t n_max = uint32_t(std::sqrt(double(target) / ideal)) + 3;
  for (uint32_t n = 2; n <= n_max; ++n) {
    const double m_real = double(target) / (2.0 * (n - 1));
    for (double mm : {std::floor(m_real), std::ceil(m_real)}) {
      if (mm < 3) continue;
      const uint32_t m = uint32_t(mm);
      const double ratio = (double(m) / n) / ideal;
      if (ratio < 0.5 || ratio > 2.0) continue;
      const uint64_t tri = bottle_triangle_count(n, m);
      candidates.push_back({n, m, tri, std::abs(double(tri) - double(target)), std::abs(std::log(ratio))});
    }
  }
  const Candidate* best = &pick_squarest_resolution(candidates, target);
  BottlePlan plan{best->n, best->m, best->tri, 0};
  plan.vertices = uint64_t(plan.around) * (plan.profile_segments - 1) + 2;
  return plan;
}

BottlePlan plan_bottle_around(uint64_t target, uint32_t around) {
  assert(around >= 3);
  // triangles = 2 around (profile_segments - 1)
  const double rows = std::round(double(target) / (2.0 * around));
  BottlePlan plan;
  plan.around = around;
  plan.profile_segments = uint32_t(std::clamp(rows, 1.0, 4e9)) + 1;
  plan.triangles = bottle_triangle_count(plan.profile_segments, plan.around);
  plan.vertices = uint64_t(plan.around) * (plan.profile_segments - 1) + 2;
  return plan;
}

BottleSurface::BottleSurface(const BottlePlan& plan, const BottleConfig& config)
    : plan_(plan), profile_(config) {
  assert(plan.profile_segments >= 2 && plan.around >= 3);
  GridPiece g;
  g.rows = plan.profile_segments + 1;
  g.cols = plan.around;
  g.wrap = true;
  g.pole_first = g.pole_last = true;
  pieces_.push_back(g);
  for (uint32_t c = 0; c < plan.around; ++c) {
    const double th = 2.0 * kPi * double(c) / double(plan.around);
    cos_.push_back(std::cos(th));
    sin_.push_back(std::sin(th));
  }
}

void BottleSurface::eval_row(size_t, uint32_t row, std::span<Vec3> positions, std::span<Vec3> normals) const {
  const uint32_t n = plan_.profile_segments;
  const ProfileSample ps = profile_.at(profile_.length() * double(row) / double(n));
  if (row == 0 || row == n) {
    // Poles sit exactly on the axis; the normal there is vertical.
    positions[0] = Vec3(0.0f, float(ps.point.y), 0.0f);
    normals[0] = Vec3(0.0f, ps.normal.y > 0 ? 1.0f : -1.0f, 0.0f);
    return;
  }
  // x = r cos(theta), z = r sin(theta): with the profile running base -> lip
  // (rows) and theta increasing (columns), dP/drow x dP/dcol points outward.
  for (uint32_t c = 0; c < plan_.around; ++c) {
    positions[c] = Vec3(float(ps.point.x * cos_[c]), float(ps.point.y), float(ps.point.x * sin_[c]));
    normals[c] = Vec3(glm::normalize(Vec3d(ps.normal.x * cos_[c], ps.normal.y, ps.normal.x * sin_[c])));
  }
}

}  // namespace raylod
