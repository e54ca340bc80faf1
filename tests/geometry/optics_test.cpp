// The shared optics (geometry/optics.h): exact cases, and seeded property
// tests against an independent statement of Snell's law and the Fresnel
// equations (angles measured with acos/asin, not the module's formulas).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "geometry/optics.h"
#include "random_unit.h"

namespace raylod {
namespace {

TEST(Optics, FresnelAtNormalIncidenceAndSymmetry) {
  EXPECT_NEAR(fresnel_dielectric(1.0, 1 / 1.5), 0.04, 1e-12);  // ((n-1)/(n+1))^2
  EXPECT_NEAR(fresnel_dielectric(1.0, 1.5), 0.04, 1e-12);
  // Reciprocity: the same interface seen from either side reflects the same.
  const double ti = 0.6, eta = 1 / 1.5, tt = std::asin(std::sin(ti) * eta);
  EXPECT_NEAR(fresnel_dielectric(std::cos(ti), eta), fresnel_dielectric(std::cos(tt), 1 / eta), 1e-12);
  EXPECT_NEAR(fresnel_dielectric(0.0, eta), 1.0, 1e-12);  // grazing
}

TEST(Optics, TotalInternalReflectionBeyondTheCriticalAngle) {
  const double crit = std::asin(1 / 1.5);
  const Vec3d n(0, 1, 0);
  for (double a : {crit - 1e-3, crit + 1e-3}) {
    const Vec3d d(std::sin(a), -std::cos(a), 0);
    Vec3d t;
    const bool ok = refract(d, n, 1.5, t);
    EXPECT_EQ(ok, a < crit);
    EXPECT_EQ(fresnel_dielectric(std::cos(a), 1.5) == 1.0, a >= crit);
    if (ok) {
      EXPECT_NEAR(std::sin(std::acos(-t.y)), 1.5 * std::sin(a), 1e-9);  // Snell
    }
  }
}

TEST(Optics, MatchedIndicesTransmitEveryRayStraightEvenAtGrazingIncidence) {
  // An ior of 1 in air is no interface. At grazing incidence 1 - cos_i^2
  // rounds to 1 once cos_i^2 is below the double epsilon, which a naive
  // sin^2(theta_t) turns into total internal reflection.
  const Vec3d n(0, 1, 0);
  for (double cos_i : {1e-3, 1e-8, 1e-9, 1e-12, 1e-200, 0.0}) {
    const Vec3d d = glm::normalize(Vec3d(std::sqrt(1 - cos_i * cos_i), -cos_i, 0));
    for (double eta : {1.0, 1.0 - 1e-12}) {
      Vec3d t;
      ASSERT_TRUE(refract(d, n, eta, t)) << "cos_i " << cos_i << " eta " << eta;
      // eta < 1 bends a grazing ray by up to sqrt(1 - eta^2) ~ 1.4e-6 here.
      EXPECT_LT(glm::length(t - d), eta == 1.0 ? 1e-12 : 2e-6) << "cos_i " << cos_i;
    }
    EXPECT_EQ(fresnel_dielectric(cos_i, 1.0), 0.0) << cos_i;
    // Just above 1, a grazing ray is reflected whole, as it should be.
    EXPECT_EQ(fresnel_dielectric(cos_i, 1.0 + 1e-3), cos_i < 1e-2 ? 1.0 : fresnel_dielectric(cos_i, 1.0 + 1e-3));
  }
  // Straight through at every angle, reflecting nothing.
  for (double a = 0; a < 1.5707; a += 0.05) {
    const Vec3d d(std::sin(a), -std::cos(a), 0);
    Vec3d t;
    ASSERT_TRUE(refract(d, n, 1.0, t));
    EXPECT_LT(glm::length(t - d), 1e-12) << a;
    EXPECT_EQ(fresnel_dielectric(std::cos(a), 1.0), 0.0);
  }
}

using test::random_unit;

// Angle between two unit vectors, robust near 0 and pi.
double angle(const Vec3d& a, const Vec3d& b) { return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)); }

// Brute-force Fresnel: the s and p amplitude coefficients from the angles.
double fresnel_from_angles(double theta_i, double n1, double n2) {
  const double s = n1 / n2 * std::sin(theta_i);
  if (s >= 1) return 1;
  const double theta_t = std::asin(s);
  const double ci = std::cos(theta_i), ct = std::cos(theta_t);
  const double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
  const double rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
  return 0.5 * (rs * rs + rp * rp);
}

TEST(Optics, RandomRaysObeySnellAndFresnel) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> u01(0, 1);
  int tir = 0, refracted = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3d n = random_unit(rng);
    Vec3d d = random_unit(rng);
    if (glm::dot(d, n) > 0) d = -d;  // refract() wants n facing against d
    if (!(glm::dot(d, n) < -1e-9)) continue;
    const double ior = 1.0 + 1.5 * u01(rng);
    const bool entering = u01(rng) < 0.5;
    const double n1 = entering ? 1.0 : ior, n2 = entering ? ior : 1.0;
    const double eta = dielectric_eta(entering, ior);
    EXPECT_DOUBLE_EQ(eta, n1 / n2);
    const double theta_i = angle(-d, n);
    const double critical = n1 > n2 ? std::asin(n2 / n1) : M_PI / 2;
    Vec3d t;
    const bool ok = refract(d, n, eta, t);
    // TIR exactly beyond the critical angle (a margin for the angle's rounding).
    if (std::abs(theta_i - critical) > 1e-9) {
      EXPECT_EQ(ok, theta_i < critical) << theta_i << " " << critical;
    }
    const double f = fresnel_dielectric(-glm::dot(d, n), eta);
    EXPECT_GE(f, 0.0);
    EXPECT_LE(f, 1.0);
    if (!ok) {
      ++tir;
      EXPECT_EQ(f, 1.0);
    } else {
      ++refracted;
      EXPECT_NEAR(glm::length(t), 1.0, 1e-12);
      const double theta_t = angle(t, -n);
      EXPECT_NEAR(n1 * std::sin(theta_i), n2 * std::sin(theta_t), 1e-9);  // Snell
      EXPECT_LT(glm::dot(t, n), 0);  // transmitted: through the surface
      // In the plane of incidence: t is a combination of d and n.
      EXPECT_NEAR(glm::dot(t, glm::cross(d, n)), 0, 1e-9);
      if (std::abs(theta_i - critical) > 1e-4) {
        EXPECT_NEAR(f, fresnel_from_angles(theta_i, n1, n2), 1e-9);
      }
    }
    // Mirror: the angle out equals the angle in, on the same side, in the plane.
    const Vec3d r = reflect(d, n);
    EXPECT_NEAR(glm::length(r), 1.0, 1e-12);
    EXPECT_NEAR(angle(r, n), theta_i, 1e-9);
    EXPECT_NEAR(glm::dot(r, glm::cross(d, n)), 0, 1e-9);
  }
  EXPECT_GT(tir, 1000);
  EXPECT_GT(refracted, 1000);
}

// A shading normal facing away from the ray is replaced by the face normal.
TEST(Optics, ShadingNormalFacingAwayFallsBackToTheFaceNormal) {
  const Vec3d g(0, 1, 0);
  const Vec3d d = glm::normalize(Vec3d(1, -0.05, 0));  // grazing, from above
  const Vec3d s = glm::normalize(Vec3d(1, 0.2, 0));    // tilted so that d . s > 0
  const FacingNormals f = facing_normals(d, g, s);
  EXPECT_TRUE(f.entering);
  EXPECT_TRUE(f.shading_is_geometric);
  EXPECT_EQ(f.shading, g);
  // From below (leaving): both normals turn to face the ray.
  const FacingNormals b = facing_normals(Vec3d(0, 1, 0), g, glm::normalize(Vec3d(0.1, 1, 0)));
  EXPECT_FALSE(b.entering);
  EXPECT_TRUE(b.shading_flipped);
  EXPECT_FALSE(b.shading_is_geometric);
  EXPECT_EQ(b.geometric, -g);
  EXPECT_LT(glm::dot(b.shading, Vec3d(0, 1, 0)), 0);
}

// Bent by the shading normal, the reflected or refracted ray would cross the
// surface; the face normal is used instead.
TEST(Optics, DirectionsThatCrossTheSurfaceUseTheFaceNormal) {
  const Vec3d g(0, 1, 0);
  const Vec3d d = glm::normalize(Vec3d(1, -0.1, 0));
  const Vec3d s = glm::normalize(Vec3d(0.08, 1, 0));  // faces the ray, but reflects it below the surface
  const FacingNormals f = facing_normals(d, g, s);
  ASSERT_FALSE(f.shading_is_geometric);
  EXPECT_LE(glm::dot(reflect(d, f.shading), g), 0);
  const SpecularReflection r = specular_reflection(d, f);
  EXPECT_TRUE(r.geometric_fallback);
  EXPECT_EQ(r.normal, g);
  EXPECT_EQ(r.direction, glm::normalize(reflect(d, g)));
  EXPECT_GT(glm::dot(r.direction, g), 0);
  // Without the fallback the reflection keeps the shading normal.
  const FacingNormals flat = facing_normals(d, g, g);
  const SpecularReflection r0 = specular_reflection(d, flat);
  EXPECT_FALSE(r0.geometric_fallback);
  // Refraction, leaving glass of index 1.1 at a shallow angle: find shading
  // tilts where the transmitted ray would turn back into the glass; there the
  // face normal refracts (or reflects totally).
  const Vec3d up = glm::normalize(Vec3d(1, 0.1, 0));
  const double eta = dielectric_eta(false, 1.1);
  int fallbacks = 0;
  for (int k = -80; k <= 80; ++k) {
    const Vec3d sn = glm::normalize(Vec3d(std::sin(k * 0.01), std::cos(k * 0.01), 0));
    const FacingNormals fk = facing_normals(up, g, sn);
    ASSERT_FALSE(fk.entering);
    if (fk.shading_is_geometric) continue;
    Vec3d direct;
    const bool crosses = refract(up, fk.shading, eta, direct) && glm::dot(direct, fk.geometric) >= 0;
    const SpecularRefraction t = specular_refraction(up, fk, eta);
    EXPECT_EQ(t.geometric_fallback, crosses);
    if (t.ok) {  // left the glass
      EXPECT_LT(glm::dot(t.direction, fk.geometric), 0);
    }
    if (crosses) {
      ++fallbacks;
      Vec3d expected;
      const bool ok = refract(up, fk.geometric, eta, expected);
      EXPECT_EQ(t.ok, ok);
      if (ok) {
        EXPECT_EQ(t.direction, expected);
      }
      EXPECT_EQ(t.normal, fk.geometric);
    }
  }
  EXPECT_GT(fallbacks, 0);
}

}  // namespace
}  // namespace raylod
