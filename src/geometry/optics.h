// Specular optics shared by the renderer (render/integrator.h) and the probe
// (geometry/ray_differential.h): mirror reflection, Snell refraction with
// total internal reflection, the dielectric Fresnel reflectance, and the
// fallbacks to the face normal where an interpolated shading normal would
// send a ray to the wrong side of the surface. Written once, so a probe ray
// leaves a mirror or glass hit in exactly the direction a rendered ray does.
// All vectors are unit length, in double.
#pragma once

#include <algorithm>

#include "core/math.h"

namespace raylod {

// An interpolated vertex normal shorter than this is no direction: the face
// normal shades instead.
inline constexpr double kMinShadingNormalLength = 1e-12;

// Secondary rays whose throughput (largest channel) falls below this are not
// traced: they cannot change an 8-bit pixel (glass: 4% reflections nest).
// The renderer's default (IntegratorConfig::min_throughput), and the probe's,
// so that the probe follows the paths the renderer traces.
inline constexpr float kMinThroughput = 1e-3f;
// A throughput's largest channel: what kMinThroughput is compared with.
inline float max_channel(const Vec3& c) { return std::max({c.x, c.y, c.z}); }

// Mirror direction of d about the unit normal n (either orientation).
Vec3d reflect(const Vec3d& d, const Vec3d& n);
// Refracts unit d at unit normal n facing against d (d . n < 0), with
// eta = n_incident / n_transmitted (Snell's law). False on total internal
// reflection, i.e. when eta > 1 and sin^2(theta_t) = eta^2 (1 - cos^2(theta_i))
// >= 1; never for eta <= 1, even at grazing incidence.
bool refract(const Vec3d& d, const Vec3d& n, double eta, Vec3d& out);
// cos^2(theta_t) = 1 - eta^2 sin^2(theta_i) for cos_i = cos(theta_i),
// written so that it does not cancel at grazing incidence: for eta = 1 it
// is cos_i^2 exactly, where 1 - (1 - cos_i^2) rounds to 0 (a false total
// internal reflection) once cos_i^2 drops below the double epsilon. What
// refract(), fresnel_dielectric() and the refracted ray differential use.
double cos2_transmitted(double cos_i, double eta);
// Unpolarised Fresnel reflectance of a dielectric interface (average of the
// s and p terms), cos_i = cosine of the incidence angle, eta as above;
// 1 under total internal reflection, 0 for eta = 1 (no interface).
double fresnel_dielectric(double cos_i, double eta);

// The normals of a specular hit, turned to the side the ray arrives from.
// geometric is the unit face normal oriented as the surface says (outward
// for a closed mesh), shading the unit shading normal on the same side.
struct FacingNormals {
  bool entering = false;      // d . geometric < 0: the ray hits the front face (outside -> inside)
  Vec3d geometric{0, 0, 1};   // face normal facing the ray
  Vec3d shading{0, 0, 1};     // shading normal on the same side, or `geometric` (below)
  bool shading_flipped = false;      // shading is the negated input (its derivative flips too)
  bool shading_is_geometric = false; // the shading normal faced away from the ray and was replaced
};
// An interpolated normal can face away from the ray at grazing angles on a
// coarse mesh; the face normal is used then.
FacingNormals facing_normals(const Vec3d& d, const Vec3d& geometric, const Vec3d& shading);

// The eta of refract() for a dielectric of index ior in air or vacuum.
inline double dielectric_eta(bool entering, double ior) { return entering ? 1.0 / ior : ior; }

// The mirror direction at a hit (unit). A direction bent by the shading
// normal may cross the true surface: then the face normal reflects, so the
// reflected ray stays outside.
struct SpecularReflection {
  Vec3d direction{0};
  Vec3d normal{0};                // the normal that reflected (shading or geometric)
  bool geometric_fallback = false;  // normal is the face normal, not the shading one
};
SpecularReflection specular_reflection(const Vec3d& d, const FacingNormals& f);

// The refracted direction at a hit (unit), with the same fallback: a
// transmitted ray that would leave on the incoming side is refracted by the
// face normal instead. ok = false is total internal reflection (at the
// shading normal, or at the face normal after the fallback).
struct SpecularRefraction {
  bool ok = false;
  Vec3d direction{0};
  Vec3d normal{0};                // the normal that refracted (the Fresnel term's too)
  bool geometric_fallback = false;
};
SpecularRefraction specular_refraction(const Vec3d& d, const FacingNormals& f, double eta);

}  // namespace raylod
