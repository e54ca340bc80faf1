// Specular optics shared by the renderer and the probe; see optics.h.
#include "geometry/optics.h"

#include <algorithm>
#include <cmath>

namespace raylod {

Vec3d reflect(const Vec3d& d, const Vec3d& n) { return d - 2.0 * glm::dot(d, n) * n; }

double cos2_transmitted(double cos_i, double eta) {
  // (1 - eta^2) + eta^2 cos_i^2: no cancellation at grazing incidence.
  const double e2 = eta * eta;
  return (1.0 - e2) + e2 * std::min(1.0, cos_i * cos_i);
}

bool refract(const Vec3d& d, const Vec3d& n, double eta, Vec3d& out) {
  const double cos_i = -glm::dot(d, n);
  const double cos2_t = cos2_transmitted(cos_i, eta);
  // Only a ray going into a less dense medium (eta > 1) can be reflected
  // whole; for eta <= 1, cos2_t >= eta^2 cos_i^2 >= 0.
  if (eta > 1.0 && cos2_t <= 0.0) return false;
  const double cos_t = std::sqrt(std::max(0.0, cos2_t));
  out = glm::normalize(eta * d + (eta * cos_i - cos_t) * n);
  return true;
}

double fresnel_dielectric(double cos_i, double eta) {
  // Matched indices are no interface: nothing is reflected, even at grazing
  // incidence (where the formulas below are 0/0).
  if (eta == 1.0) return 0.0;
  cos_i = std::clamp(cos_i, 0.0, 1.0);
  const double cos2_t = cos2_transmitted(cos_i, eta);
  if (cos2_t <= 0.0) return 1.0;
  const double cos_t = std::sqrt(cos2_t);
  // Fresnel equations divided through by n_t.
  const double rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const double rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return 0.5 * (rs * rs + rp * rp);
}

FacingNormals facing_normals(const Vec3d& d, const Vec3d& geometric, const Vec3d& shading) {
  FacingNormals f;
  f.entering = glm::dot(d, geometric) < 0;
  f.geometric = f.entering ? geometric : -geometric;
  f.shading = f.entering ? shading : -shading;
  f.shading_flipped = !f.entering;
  if (glm::dot(f.shading, d) >= 0) {
    f.shading = f.geometric;
    f.shading_is_geometric = true;
  }
  return f;
}

SpecularReflection specular_reflection(const Vec3d& d, const FacingNormals& f) {
  SpecularReflection s;
  s.normal = f.shading;
  s.geometric_fallback = f.shading_is_geometric;
  Vec3d r = reflect(d, f.shading);
  if (glm::dot(r, f.geometric) <= 0) {
    r = reflect(d, f.geometric);
    s.normal = f.geometric;
    s.geometric_fallback = true;
  }
  s.direction = glm::normalize(r);
  return s;
}

SpecularRefraction specular_refraction(const Vec3d& d, const FacingNormals& f, double eta) {
  SpecularRefraction s;
  s.normal = f.shading;
  s.geometric_fallback = f.shading_is_geometric;
  s.ok = refract(d, f.shading, eta, s.direction);
  if (s.ok && glm::dot(s.direction, f.geometric) >= 0) {
    s.normal = f.geometric;
    s.geometric_fallback = true;
    s.ok = refract(d, f.geometric, eta, s.direction);
  }
  return s;
}

}  // namespace raylod
