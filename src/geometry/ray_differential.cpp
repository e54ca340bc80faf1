// Igehy, "Tracing Ray Differentials", SIGGRAPH 1999: transfer (eqs. 10-12),
// reflection (13-15), refraction (16-18) and the interpolated-normal
// derivative; see ray_differential.h for the formulas and the blow-up rule.
#include "geometry/ray_differential.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "geometry/optics.h"

namespace raylod {

namespace {

double squared(const Vec3d& v) { return glm::dot(v, v); }

// Drops the differentials if any vector is non-finite or past the limit.
void check(RayDifferential& r, const DifferentialLimits& limits) {
  if (!r.has_differentials) return;
  if (!differentials_ok(r, limits)) drop_differentials(r);
}

}  // namespace

bool differentials_ok(const RayDifferential& r, const DifferentialLimits& limits) {
  const double max_dp = limits.max_ratio * r.travelled;
  for (const Vec3d* v : {&r.dp_dx, &r.dp_dy}) {
    if (!is_finite(*v)) return false;
    if (r.travelled > 0 && squared(*v) > max_dp * max_dp) return false;
  }
  for (const Vec3d* v : {&r.dd_dx, &r.dd_dy}) {
    if (!is_finite(*v)) return false;
    if (squared(*v) > limits.max_turn * limits.max_turn) return false;
  }
  return true;
}

void drop_differentials(RayDifferential& r) {
  r.dp_dx = r.dp_dy = r.dd_dx = r.dd_dy = Vec3d(0);
  r.has_differentials = false;
}

RayDifferential camera_ray_differential(const PinholeCamera& camera, double px, double py) {
  RayDifferential r;
  r.ray = camera.generate(px, py);
  const RayDerivatives d = camera.derivatives(px, py);
  r.dp_dx = d.dp_dx;
  r.dp_dy = d.dp_dy;
  r.dd_dx = d.dd_dx;
  r.dd_dy = d.dd_dy;
  r.has_differentials = true;
  check(r, {});
  return r;
}

void transfer(RayDifferential& r, double t, const Vec3d& plane_normal, const DifferentialLimits& limits) {
  const Vec3d d = r.ray.direction;
  r.ray.origin = r.ray.origin + t * d;
  r.travelled += std::abs(t);
  if (!r.has_differentials) return;
  const double n_len = glm::length(plane_normal);
  if (!(n_len > 0)) { drop_differentials(r); return; }
  const Vec3d n = plane_normal / n_len;
  const double dn = glm::dot(d, n);
  // Grazing incidence: dt/dx ~ 1 / (D.N) blows up (the footprint stretches
  // without bound along the surface).
  if (!(std::abs(dn) >= limits.min_cos)) { drop_differentials(r); return; }
  const Vec3d ax = r.dp_dx + t * r.dd_dx;
  const Vec3d ay = r.dp_dy + t * r.dd_dy;
  const double dtdx = -glm::dot(ax, n) / dn;  // Igehy eq. 11
  const double dtdy = -glm::dot(ay, n) / dn;
  r.dp_dx = ax + dtdx * d;                    // Igehy eq. 12
  r.dp_dy = ay + dtdy * d;
  check(r, limits);
}

Vec3d reflect_direction(const Vec3d& d, const Vec3d& n) { return reflect(d, n); }

namespace {

// The normal the renderer's optics used (optics.h) and its derivative: the
// shading normal's Jacobian, negated with the normal, or zero for the face
// normal (constant over the triangle).
Mat3d used_normal_jacobian(const HitSurface& s, const FacingNormals& f, bool geometric_fallback) {
  if (geometric_fallback) return Mat3d(0.0);
  return f.shading_flipped ? -s.normal_jacobian : s.normal_jacobian;
}

// Igehy eqs. 13-15 about the unit normal n with Jacobian jac; `direction` is
// the reflected direction the optics chose (about n).
RayDifferential reflect_about(const RayDifferential& in, const HitSurface& s, const Vec3d& n, const Mat3d& jac,
                              const Vec3d& direction, const DifferentialLimits& limits) {
  RayDifferential out;
  const Vec3d d = in.ray.direction;
  const double dn = glm::dot(d, n);
  out.ray.origin = in.ray.origin;
  out.travelled = in.travelled;
  out.ray.direction = direction;  // Igehy eq. 13: D - 2 (D.N) N, normalised
  out.dp_dx = in.dp_dx;
  out.dp_dy = in.dp_dy;
  out.has_differentials = in.has_differentials && !s.normal_degenerate;
  if (!out.has_differentials) { drop_differentials(out); return out; }
  const Vec3d dndx = jac * in.dp_dx;
  const Vec3d dndy = jac * in.dp_dy;
  const double ddn_dx = glm::dot(in.dd_dx, n) + glm::dot(d, dndx);  // d(D.N)/dx, Igehy eq. 15
  const double ddn_dy = glm::dot(in.dd_dy, n) + glm::dot(d, dndy);
  out.dd_dx = in.dd_dx - 2.0 * (dn * dndx + ddn_dx * n);             // Igehy eq. 14
  out.dd_dy = in.dd_dy - 2.0 * (dn * dndy + ddn_dy * n);
  check(out, limits);
  return out;
}

RayDifferential reflect_facing(const RayDifferential& in, const HitSurface& s, const FacingNormals& f,
                               const DifferentialLimits& limits) {
  const SpecularReflection r = specular_reflection(in.ray.direction, f);
  return reflect_about(in, s, r.normal, used_normal_jacobian(s, f, r.geometric_fallback), r.direction, limits);
}

}  // namespace

RayDifferential reflect(const RayDifferential& in, const HitSurface& s, const DifferentialLimits& limits) {
  return reflect_facing(in, s, facing_normals(in.ray.direction, s.geometric_normal, s.normal), limits);
}

Refraction refract(const RayDifferential& in, const HitSurface& s, double ior, const DifferentialLimits& limits) {
  Refraction result;
  const Vec3d d = in.ray.direction;
  // The renderer's normals and direction (optics.h): N faces the incident
  // ray, D.N < 0, with the face normal where the shading normal fails.
  const FacingNormals f = facing_normals(d, s.geometric_normal, s.normal);
  result.entering = f.entering;
  const double eta = dielectric_eta(f.entering, ior);  // n_incident / n_transmitted
  const SpecularRefraction t = specular_refraction(d, f, eta);
  if (!t.ok) {  // total internal reflection
    result.ray = reflect_facing(in, s, f, limits);
    result.total_internal_reflection = true;
    return result;
  }
  const Vec3d n = t.normal;
  const Mat3d jac = used_normal_jacobian(s, f, t.geometric_fallback);
  const double c = glm::dot(d, n);  // <= 0
  const double tn = -std::sqrt(std::max(0.0, cos2_transmitted(-c, eta)));  // T.N, as refract() computes it
  const double mu = eta * c - tn;   // Igehy eq. 16
  result.fresnel = fresnel_dielectric(-c, eta);
  result.tilt_gain = -tn > 0 ? std::abs(mu) / -tn : std::numeric_limits<double>::infinity();
  RayDifferential& out = result.ray;
  out.ray.origin = in.ray.origin;
  out.travelled = in.travelled;
  out.ray.direction = t.direction;  // eta D - mu N, normalised
  out.dp_dx = in.dp_dx;
  out.dp_dy = in.dp_dy;
  out.has_differentials = in.has_differentials && !s.normal_degenerate;
  // Near the critical angle the transmitted ray grazes the surface and
  // dmu/dx ~ 1 / (T.N) blows up.
  if (out.has_differentials && !(-tn >= limits.min_cos)) out.has_differentials = false;
  if (!out.has_differentials) { drop_differentials(out); return result; }
  const Vec3d dndx = jac * in.dp_dx;
  const Vec3d dndy = jac * in.dp_dy;
  const double dc_dx = glm::dot(in.dd_dx, n) + glm::dot(d, dndx);
  const double dc_dy = glm::dot(in.dd_dy, n) + glm::dot(d, dndy);
  const double dmu_factor = eta - eta * eta * c / tn;            // Igehy eq. 18
  out.dd_dx = eta * in.dd_dx - (mu * dndx + dmu_factor * dc_dx * n);  // Igehy eq. 17
  out.dd_dy = eta * in.dd_dy - (mu * dndy + dmu_factor * dc_dy * n);
  check(out, limits);
  return result;
}

double footprint(const RayDifferential& r) {
  if (!r.has_differentials) return 0;
  return std::sqrt(std::max(squared(r.dp_dx), squared(r.dp_dy)));
}

HitSurface triangle_surface_point(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, const Vec3d* n, double b1,
                                    double b2, const DifferentialLimits& limits) {
  HitSurface s;
  const Vec3d e1 = p1 - p0, e2 = p2 - p0;
  const Vec3d g = glm::cross(e1, e2);
  const double gg = glm::dot(g, g);
  s.point = p0 + b1 * e1 + b2 * e2;
  if (!(gg > 0)) {  // zero-area triangle: no plane, no normal
    s.geometric_normal = s.normal = Vec3d(0, 0, 1);
    s.normal_degenerate = true;
    return s;
  }
  s.geometric_normal = g / std::sqrt(gg);
  s.normal = s.geometric_normal;
  if (!n) return s;
  const double b0 = 1.0 - b1 - b2;
  const Vec3d ni = b0 * n[0] + b1 * n[1] + b2 * n[2];
  const double len = glm::length(ni);
  if (!(len > kMinShadingNormalLength)) {  // the renderer's rule (render/embree_scene.cpp)
    s.normal_degenerate = true;
    return s;
  }
  s.normal = ni / len;
  // CAD vertex normals are the reliable outward side; the winding may not be.
  if (glm::dot(s.geometric_normal, s.normal) < 0) s.geometric_normal = -s.geometric_normal;
  // Normals that nearly cancel: the normal is still the renderer's, but dN/dx ~ 1/|n| is not usable.
  if (!(len >= limits.min_normal_length)) {
    s.normal_degenerate = true;
    return s;
  }
  // Gradients of the barycentrics b1, b2 in the triangle's plane: L1.e1 = 1,
  // L1.e2 = 0, L2.e1 = 0, L2.e2 = 1, both orthogonal to the normal.
  const Vec3d l1 = glm::cross(e2, g) / gg;
  const Vec3d l2 = glm::cross(g, e1) / gg;
  const Mat3d dn_dp = glm::outerProduct(n[1] - n[0], l1) + glm::outerProduct(n[2] - n[0], l2);
  const Mat3d project = Mat3d(1.0) - glm::outerProduct(s.normal, s.normal);
  s.normal_jacobian = project * dn_dp * (1.0 / len);
  return s;
}

}  // namespace raylod
