// The probe's specular paths are the renderer's: at random mirror and glass
// hits (random directions, face and shading normals, indices of refraction),
// the probe's reflect/refract (geometry/ray_differential.h) leave in exactly
// the directions the integrator's scatter_specular picks, with the same
// entering side and the same total internal reflection decision.
#include <gtest/gtest.h>

#include <random>

#include "geometry/ray_differential.h"
#include "render/integrator.h"
#include "random_unit.h"

namespace raylod {
namespace {

using test::random_unit;

TEST(SpecularAgreement, ProbeDirectionsEqualTheIntegrators) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u01(0, 1);
  int tir = 0, refracted = 0, bent_shading = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3d g = random_unit(rng);
    // Shading normals from close to the face normal to far off it (and
    // sometimes facing away from the ray, which exercises the fallbacks).
    const Vec3d shading = glm::normalize(g + (u01(rng) < 0.5 ? 0.1 : 1.0) * random_unit(rng));
    const Vec3d d = random_unit(rng);
    if (glm::dot(d, g) == 0) continue;
    Material glass;
    glass.type = MaterialType::Glass;
    glass.ior = float(1.05 + 1.5 * u01(rng));

    SurfacePoint sp;
    sp.position = Vec3d(0.5, -2, 3);
    sp.geometric = g;
    sp.shading = shading;
    const SpecularScatter s = scatter_specular(glass, d, sp, 0.0);

    HitSurface hs;
    hs.point = sp.position;
    hs.geometric_normal = g;
    hs.normal = shading;
    RayDifferential in;
    in.ray = Ray{hs.point, d};
    in.dd_dx = Vec3d(1e-3, 0, 0);
    in.dd_dy = Vec3d(0, 1e-3, 0);
    in.has_differentials = true;

    const RayDifferential r = reflect(in, hs);
    EXPECT_EQ(r.ray.direction, s.reflected.direction);
    const Refraction rf = refract(in, hs, glass.ior);
    EXPECT_EQ(rf.entering, s.entering);
    EXPECT_EQ(rf.total_internal_reflection, s.total_internal_reflection);
    EXPECT_EQ(rf.total_internal_reflection, !s.refracts);
    if (s.refracts) {
      ++refracted;
      EXPECT_EQ(rf.ray.ray.direction, s.refracted.direction);
    } else {
      ++tir;
      EXPECT_EQ(rf.ray.ray.direction, s.reflected.direction);
    }
    bent_shading += glm::dot(shading, d) * glm::dot(g, d) > 0;

    // A mirror reflects the same way.
    Material mirror;
    mirror.type = MaterialType::Mirror;
    mirror.reflectance = 0.9f;
    EXPECT_EQ(scatter_specular(mirror, d, sp, 0.0).reflected.direction, r.ray.direction);
  }
  EXPECT_GT(tir, 500);
  EXPECT_GT(refracted, 5000);
  EXPECT_GT(bent_shading, 500);
}

}  // namespace
}  // namespace raylod
