// Igehy's ray differentials (H. Igehy, "Tracing Ray Differentials",
// SIGGRAPH 1999): initialisation from the pinhole camera, transfer to a hit,
// reflection and refraction, with the derivative of an interpolated vertex
// normal across a triangle; and the footprint ||dP|| of METHOD.md eq. (2).
//
// Blow-up rule. A differential is DROPPED (has_differentials = false, all
// four vectors zeroed) instead of being passed on as Inf or NaN when
//   - transfer meets the surface at grazing incidence, |D.N_g| < min_cos
//     (dt/dx carries 1 / (D.N_g));
//   - refraction leaves at grazing angle, i.e. within min_cos of the critical
//     angle, |T.N| < min_cos (dmu/dx carries 1 / (T.N));
//   - the interpolated vertex normal is degenerate (|n| < min_normal_length,
//     normals that cancel), so dN/dx is undefined;
//   - a direction's derivative is longer than max_turn (1e8 radians per
//     pixel: pbrt's limit of 1e16 on the square, which for a direction has
//     no unit), or a position's derivative longer than max_ratio (1e8) times
//     the distance the ray has travelled from the camera (pbrt's limit made
//     relative, so that a scene in kilometres and the same scene in
//     micrometres drop the same differentials; a differential made by hand,
//     with no distance travelled, is held to finiteness alone); or any
//     vector is not finite.
// A dropped differential stays dropped along the rest of the path; the probe
// then estimates that hit's footprint conservatively (probe.h).
// Total internal reflection is treated as a reflection (with differentials).
//
// Directions and the normals they are taken about are the renderer's
// (geometry/optics.h): the same Snell refraction and TIR test, and the same
// fallbacks to the face normal; the differentials follow the normal used
// (the face normal's derivative is zero).
#pragma once

#include "core/math.h"
#include "geometry/pinhole_camera.h"
#include "geometry/ray.h"

namespace raylod {

struct DifferentialLimits {
  double min_cos = 1e-4;             // grazing / critical-angle cut-off (cosine)
  double max_turn = 1e8;    // |dD/dx| (radians per pixel) past which it "blew up"
  double max_ratio = 1e8;   // |dP/dx| over the distance travelled past which it did
  double min_normal_length = 1e-6;   // interpolated normal shorter than this is degenerate
};

// A hit point as the differentials need it (world units).
struct HitSurface {
  Vec3d point{0};
  Vec3d geometric_normal{0, 0, 1};  // unit normal of the plane the hit moves in (transfer)
  Vec3d normal{0, 0, 1};            // unit shading normal (either side)
  // dN = normal_jacobian * dP for dP in the tangent plane: the derivative of the
  // unit shading normal with respect to the hit position (zero for flat shading).
  Mat3d normal_jacobian{0.0};
  // The interpolated vertex normal (nearly) cancelled, |n| < min_normal_length:
  // dN is unusable and reflection/refraction drop the differentials; below
  // kMinShadingNormalLength (optics.h) the shading normal is the geometric one.
  bool normal_degenerate = false;
};

// The camera ray through continuous pixel (px, py) with its differentials
// (dP = 0 for a pinhole; dD from PinholeCamera::derivatives, Igehy eq. 9).
RayDifferential camera_ray_differential(const PinholeCamera& camera, double px, double py);

// Moves the ray to distance t along its direction, onto a surface whose
// tangent plane has normal plane_normal (Igehy eqs. 10-12):
//   dP'/dx = (dP/dx + t dD/dx) + (dt/dx) D,  dt/dx = -((dP/dx + t dD/dx).N) / (D.N).
void transfer(RayDifferential& ray, double t, const Vec3d& plane_normal, const DifferentialLimits& limits = {});

// Mirror direction of unit D about unit N (either orientation).
Vec3d reflect_direction(const Vec3d& d, const Vec3d& n);

// Reflection at the (already transferred) hit s (Igehy eqs. 13-15):
//   R = D - 2 (D.N) N,  dR/dx = dD/dx - 2 [(D.N) dN/dx + d(D.N)/dx N],
// with R and N those of specular_reflection (optics.h).
RayDifferential reflect(const RayDifferential& incident, const HitSurface& s, const DifferentialLimits& limits = {});

struct Refraction {
  RayDifferential ray;
  bool total_internal_reflection = false;  // ray is the reflected ray
  bool entering = false;                   // D.N_g < 0: from outside into the medium
  // The Fresnel reflectance at the refracting normal, as the renderer weighs
  // the reflected ray (1 under total internal reflection).
  double fresnel = 1;
  // How far the transmitted ray turns per radian the normal tilts, at most:
  // |cos t - eta cos i| / cos t = |mu| / |T.N| (a tilt in the plane of
  // incidence; out of it the turn is cos t times that). 1/3 entering glass
  // of index 1.5 head-on, 1/2 leaving it; it grows without bound towards the
  // critical angle. A mirror turns its ray by 2. 0 under total internal
  // reflection (no transmitted ray).
  double tilt_gain = 0;
};
// Refraction at the (already transferred) hit s of a dielectric with index
// `ior` surrounded by vacuum/air (Igehy eqs. 16-18). Entering or leaving is
// decided by the geometric normal (outward for a closed, consistently
// oriented mesh): entering uses eta = 1/ior, leaving eta = ior, and N faces
// the incident ray, D.N < 0 (facing_normals and specular_refraction, optics.h):
//   T = eta D - mu N,  mu = eta (D.N) - T.N,  T.N = -sqrt(1 - eta^2 (1 - (D.N)^2)),
//   dT/dx = eta dD/dx - (mu dN/dx + dmu/dx N),  dmu/dx = (eta - eta^2 (D.N)/(T.N)) d(D.N)/dx.
// When eta^2 (1 - (D.N)^2) >= 1 there is no transmitted ray: total internal
// reflection, returned as reflect().
Refraction refract(const RayDifferential& incident, const HitSurface& s, double ior,
                   const DifferentialLimits& limits = {});

// The footprint of METHOD.md eq. (2): the distance to the neighbouring
// pixels' hits, max(|dP/dx|, |dP/dy|) (one pixel step, dx = dy = 1).
// Undefined (0) when the ray has no differentials.
double footprint(const RayDifferential& ray);

// True if the differentials are finite and within limits.max_turn and max_ratio.
bool differentials_ok(const RayDifferential& ray, const DifferentialLimits& limits = {});
// Zeroes the differentials and clears has_differentials.
void drop_differentials(RayDifferential& ray);

// The surface point on triangle (p0, p1, p2) at barycentrics (b1, b2) (weights
// of p1 and p2). With vertex normals (n != nullptr, three of them), the shading
// normal is the normalised interpolation n = b0 n0 + b1 n1 + b2 n2 and its
// Jacobian follows Igehy: dn = (n1 - n0) (L1.dP) + (n2 - n0) (L2.dP), with L1, L2
// the gradients of the barycentrics in the triangle's plane, and
// dN = (I - N N^T) dn / |n|. Without normals the shading normal is the face normal.
HitSurface triangle_surface_point(const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, const Vec3d* n,
                                    double b1, double b2, const DifferentialLimits& limits = {});

}  // namespace raylod
