// The bottle: count formula, watertightness, analytic normals against the
// profile's geometry, enclosed volume against the revolved profile.
#include <cmath>
#include <map>

#include "gen/bottle.h"
#include "gen_test_util.h"

namespace raylod {
namespace {

TEST(BottlePlan, TriangleCountFormulaAndRequest) {
  EXPECT_EQ(bottle_triangle_count(2, 3), 6u);
  EXPECT_EQ(bottle_triangle_count(101, 50), 10000u);
  for (uint64_t target : {1000ull, 4321ull, 100000ull, 1000000ull, 50000000ull}) {
    const BottlePlan plan = plan_bottle(target);
    EXPECT_EQ(plan.triangles, bottle_triangle_count(plan.profile_segments, plan.around));
    EXPECT_EQ(plan.vertices, uint64_t(plan.around) * (plan.profile_segments - 1) + 2);
    EXPECT_LT(std::abs(double(plan.triangles) - double(target)) / double(target), 0.01) << target;
    const BottleSurface s(plan);
    EXPECT_EQ(s.triangle_count(), plan.triangles);
    EXPECT_EQ(s.vertex_count(), plan.vertices);
  }
}

TEST(BottlePlan, AGivenNumberOfColumnsAround) {
  // 44,574 triangles (the paper's simplified count) with 40 columns: 2 x 40
  // x 557 = 44,560 is the closest (558 rows: 44,640).
  BottlePlan plan = plan_bottle_around(44574, 40);
  EXPECT_EQ(plan.around, 40u);
  EXPECT_EQ(plan.profile_segments, 558u);
  EXPECT_EQ(plan.triangles, 44560u);
  EXPECT_EQ(plan.vertices, 40u * 557u + 2u);
  const BottleSurface s(plan);
  EXPECT_EQ(s.triangle_count(), plan.triangles);
  // Fewer triangles than one band needs: the coarsest grid with those columns.
  plan = plan_bottle_around(100, 100);
  EXPECT_EQ(plan.profile_segments, 2u);
  EXPECT_EQ(plan.triangles, 200u);
}

TEST(Bottle, ConfigValidation) {
  EXPECT_TRUE(validate_bottle({}).is_ok());
  BottleConfig c;
  c.neck_radius = 1.2;
  EXPECT_FALSE(validate_bottle(c).is_ok());
  c = {};
  c.wall_thickness = 0.3;  // thicker than the base fillet
  EXPECT_FALSE(validate_bottle(c).is_ok());
  c = {};
  c.neck_start = 2.0;  // below the shoulder start
  EXPECT_FALSE(validate_bottle(c).is_ok());
  c = {};
  c.wall_thickness = 0;  // solid bottle
  EXPECT_TRUE(validate_bottle(c).is_ok());
}

TEST(BottleProfile, ClosedG1ChainFromAxisToAxis) {
  for (double wall : {0.06, 0.0}) {
    BottleConfig c;
    c.wall_thickness = wall;
    const BottleProfile prof(c);
    EXPECT_EQ(prof.at(0).point, glm::dvec2(0, 0));
    EXPECT_NEAR(prof.at(prof.length()).point.x, 0.0, 1e-12);
    EXPECT_NEAR(prof.at(prof.length()).point.y, wall > 0 ? wall : c.height, 1e-12);
    // Continuous position and normal (G1) along the whole profile.
    const int n = 20000;
    const double h = prof.length() / n;
    for (int i = 0; i < n; ++i) {
      const ProfileSample a = prof.at(i * h), b = prof.at((i + 1) * h);
      ASSERT_LE(glm::length(b.point - a.point), h * 1.0000001) << i;
      ASSERT_GT(glm::dot(a.normal, b.normal), 0.99) << "normal jumps at s = " << i * h;
      ASSERT_NEAR(glm::length(a.normal), 1.0, 1e-12);
      // The normal is perpendicular to the chord direction (to O(h)).
      ASSERT_LT(std::abs(glm::dot(a.normal, glm::normalize(b.point - a.point))), 0.01) << i;
      ASSERT_GE(a.point.x, 0.0);
    }
  }
}

TEST(Bottle, WatertightAndConsistentlyOriented) {
  for (uint64_t target : {1000ull, 30000ull}) {
    const auto m = test::grid_to_mesh(BottleSurface(plan_bottle(target)));
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    for (size_t t = 0; t < m.triangles(); ++t)
      for (int k = 0; k < 3; ++k) ++directed[{m.indices[3 * t + k], m.indices[3 * t + (k + 1) % 3]}];
    for (const auto& [e, n] : directed) {
      ASSERT_EQ(n, 1) << "directed edge used twice";
      ASSERT_EQ(directed.count({e.second, e.first}), 1u) << "boundary edge " << e.first << "-" << e.second;
    }
    EXPECT_EQ(int64_t(m.positions.size()) - int64_t(directed.size() / 2) + int64_t(m.triangles()), 2);
  }
}

TEST(Bottle, NormalsMatchTheRevolvedProfile) {
  const BottleConfig c;
  const auto m = test::grid_to_mesh(BottleSurface(plan_bottle(40000), c));
  int outer_body = 0, inner_body = 0;
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const Vec3d p(m.positions[i]), n(m.normals[i]);
    ASSERT_NEAR(glm::length(n), 1.0, 1e-6);
    const double r = std::hypot(p.x, p.z);
    // The normal lies in the plane through the axis (no tangential component).
    if (r > 1e-6) {
      EXPECT_NEAR(-p.z / r * n.x + p.x / r * n.z, 0.0, 1e-5);
    }
    // On the cylindrical body: outer wall faces away from the axis, inner wall towards it.
    if (p.y > c.base_corner_radius + 0.01 && p.y < c.shoulder_start - 0.01) {
      const Vec3d radial(p.x / r, 0, p.z / r);
      if (std::abs(r - c.body_radius) < 1e-5) { EXPECT_NEAR(glm::dot(n, radial), 1.0, 1e-6); ++outer_body; }
      if (std::abs(r - (c.body_radius - c.wall_thickness)) < 1e-5) { EXPECT_NEAR(glm::dot(n, radial), -1.0, 1e-6); ++inner_body; }
    }
  }
  EXPECT_GT(outer_body, 100);
  EXPECT_GT(inner_body, 100);
  // Vertex normals agree with the winding.
  size_t agree = 0;
  for (size_t t = 0; t < m.triangles(); ++t) {
    const Vec3d fn = face_normal(test::corner(m, t, 0), test::corner(m, t, 1), test::corner(m, t, 2));
    int ok = 0;
    for (int k = 0; k < 3; ++k) ok += glm::dot(fn, Vec3d(m.normals[m.indices[3 * t + k]])) > 0.5;
    agree += ok == 3;
  }
  EXPECT_EQ(agree, m.triangles());
}

// Signed volume of a closed, outward-oriented mesh (divergence theorem).
double mesh_volume(const test::IndexedMesh& m) {
  double v = 0;
  for (size_t t = 0; t < m.triangles(); ++t)
    v += glm::dot(test::corner(m, t, 0), glm::cross(test::corner(m, t, 1), test::corner(m, t, 2))) / 6.0;
  return v;
}

// Volume of the profile revolved about y: Pappus, V = pi * closed integral of r^2 dy
// over the profile, closed along the axis where r = 0. The profile runs
// counter-clockwise around the glass in the (r, y) plane (the glass is on its
// left), so this is 2 pi times the integral of r over the glass: positive.
double profile_volume(const BottleProfile& prof) {
  const int n = 200000;
  double v = 0;
  glm::dvec2 prev = prof.at(0).point;
  for (int i = 1; i <= n; ++i) {
    const glm::dvec2 p = prof.at(prof.length() * i / n).point;
    const double rm = 0.5 * (p.x + prev.x);
    v += M_PI * rm * rm * (p.y - prev.y);
    prev = p;
  }
  return v;
}

TEST(Bottle, EnclosedVolumeConvergesToTheRevolvedProfile) {
  for (double wall : {0.06, 0.0}) {
    BottleConfig c;
    c.wall_thickness = wall;
    const double exact = profile_volume(BottleProfile(c));
    EXPECT_GT(exact, 0.0);
    double previous_err = 1e9;
    for (uint64_t target : {2000ull, 20000ull, 200000ull}) {
      const double v = mesh_volume(test::grid_to_mesh(BottleSurface(plan_bottle(target, c), c)));
      const double err = std::abs(v - exact) / exact;
      EXPECT_LT(err, previous_err) << "wall " << wall << " target " << target;
      previous_err = err;
    }
    EXPECT_LT(previous_err, 2e-3) << "wall " << wall;
  }
}

}  // namespace
}  // namespace raylod
