// The crease rule (geometry/crease_normals.h): tiny exact cases, then a seeded
// property test against the brute-force pairwise rule.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "geometry/crease_normals.h"

namespace raylod {
namespace {

// A "roof": two triangles sharing edge (0,1) with a dihedral of `deg` degrees
// between their normals.
void roof(double deg, std::vector<Vec3>& pos, std::vector<uint32_t>& idx) {
  const double a = deg * M_PI / 180.0 / 2.0;
  pos = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5f, float(std::cos(a)), float(std::sin(a))),
         Vec3(0.5f, float(-std::cos(a)), float(std::sin(a)))};
  idx = {0, 1, 2, 1, 0, 3};
}

TEST(CreaseNormals, FlatAtACreaseSmoothBelowIt) {
  std::vector<Vec3> pos;
  std::vector<uint32_t> idx;
  roof(90, pos, idx);  // normals 90 degrees apart
  const Vec3d n0 = face_normal(Vec3d(pos[0]), Vec3d(pos[1]), Vec3d(pos[2]));
  const Vec3d n1 = face_normal(Vec3d(pos[1]), Vec3d(pos[0]), Vec3d(pos[3]));
  ASSERT_NEAR(glm::dot(n0, n1), 0.0, 1e-6);
  // 30 degrees: a crease; every corner has its face's normal.
  std::vector<Vec3> n = crease_corner_normals(pos, idx, 30);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(glm::distance(Vec3d(n[k]), n0), 0.0, 1e-6);
  for (int k = 3; k < 6; ++k) EXPECT_NEAR(glm::distance(Vec3d(n[k]), n1), 0.0, 1e-6);
  // 100 degrees: smooth; the shared corners get the (equal-angle) mean and
  // the apexes, touched by one face each, keep their face's normal.
  n = crease_corner_normals(pos, idx, 100);
  const Vec3d mean = glm::normalize(n0 + n1);
  for (int k : {0, 1, 3, 4}) EXPECT_NEAR(glm::distance(Vec3d(n[k]), mean), 0.0, 1e-6) << k;
  EXPECT_NEAR(glm::distance(Vec3d(n[2]), n0), 0.0, 1e-6);
  EXPECT_NEAR(glm::distance(Vec3d(n[5]), n1), 0.0, 1e-6);
}

// The default angle sits between the steps of curved faces' tessellations
// and the design angles of CAD edges: a 30-degree chamfer, whose facets a
// mesher leaves a degree either side of 30 (OpenCASCADE's Pump_Nut.brep: 29
// to 30 degrees), is a crease on both sides of 30; a 20-degree step (the
// script's coarse crank arm, tessellated at a 10-degree angular deflection)
// is smoothed.
TEST(CreaseNormals, TheDefaultKeepsThirtyDegreeChamfersAndSmoothsTwentyDegreeSteps) {
  std::vector<Vec3> pos;
  std::vector<uint32_t> idx;
  for (const double deg : {29.0, 29.5, 30.0, 30.5, 31.0}) {
    roof(deg, pos, idx);
    const Vec3d n0 = face_normal(Vec3d(pos[0]), Vec3d(pos[1]), Vec3d(pos[2]));
    const Vec3d n1 = face_normal(Vec3d(pos[1]), Vec3d(pos[0]), Vec3d(pos[3]));
    const std::vector<Vec3> n = crease_corner_normals(pos, idx, kDefaultCreaseAngleDeg);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(glm::distance(Vec3d(n[k]), n0), 0.0, 1e-6) << deg;
    for (int k = 3; k < 6; ++k) EXPECT_NEAR(glm::distance(Vec3d(n[k]), n1), 0.0, 1e-6) << deg;
  }
  roof(20, pos, idx);
  const Vec3d mean = glm::normalize(face_normal(Vec3d(pos[0]), Vec3d(pos[1]), Vec3d(pos[2])) +
                                    face_normal(Vec3d(pos[1]), Vec3d(pos[0]), Vec3d(pos[3])));
  const std::vector<Vec3> n = crease_corner_normals(pos, idx, kDefaultCreaseAngleDeg);
  for (int k : {0, 1, 3, 4}) EXPECT_NEAR(glm::distance(Vec3d(n[k]), mean), 0.0, 1e-6) << k;
}

TEST(CreaseNormals, AngleWeightingIgnoresHowAFaceIsCut) {
  // A vertex of a flat square fan cut into one big and many thin triangles on
  // one side, one triangle on the other side of a 20-degree fold: with angle
  // weights the result depends on the angles, not on the number of slivers.
  std::vector<Vec3> pos = {Vec3(0, 0, 0)};
  std::vector<uint32_t> idx;
  const int slivers = 9;
  for (int i = 0; i <= slivers; ++i) {
    const double a = M_PI / 2 * double(i) / slivers;
    pos.push_back(Vec3(float(std::cos(a)), float(std::sin(a)), 0));
  }
  for (int i = 0; i < slivers; ++i) idx.insert(idx.end(), {0, uint32_t(i + 1), uint32_t(i + 2)});
  const std::vector<Vec3> n = crease_corner_normals(pos, idx, 30);
  for (size_t c = 0; c < idx.size(); ++c) EXPECT_NEAR(glm::distance(n[c], Vec3(0, 0, 1)), 0.0f, 1e-6f);
}

TEST(CreaseNormals, DegenerateTrianglesGetFiniteNormals) {
  const std::vector<Vec3> pos = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(0, 1, 0)};
  const std::vector<uint32_t> idx = {0, 1, 2, 0, 1, 3, 2, 2, 2};
  const std::vector<Vec3> n = crease_corner_normals(pos, idx, 30);
  for (const Vec3& v : n) {
    EXPECT_TRUE(is_finite(v));
    EXPECT_NEAR(glm::length(v), 1.0f, 1e-6f);
  }
}

// A zero-area cap filling a T-junction (A, B and V, the float midpoint of
// AB, on one plane): its face normal is rounding noise, 16.5 degrees off the
// plane here, inside the crease angle, and its corner angle at V is pi, half
// of V's weight: it tilted V's normal 8.3 degrees off a flat face (found by a
// review). It now weighs nothing.
TEST(CreaseNormals, AZeroAreaCapDoesNotTiltAFlatFacesNormal) {
  const std::vector<Vec3> pos = {Vec3(-0.113094211f, -0.540845573f, 0.142097369f),
                                 Vec3(-0.0221331995f, 0.14353925f, -0.0220678896f),
                                 Vec3(0.0688278154f, 0.827924073f, -0.186233148f),
                                 Vec3(-0.49750796f, 0.23647137f, 0.101958118f)};
  const std::vector<uint32_t> idx = {1, 2, 3, 1, 3, 0, 0, 2, 1};
  const Vec3d plane = glm::normalize(Vec3d(0.3, 0.2, 1));
  const std::vector<Vec3> n = crease_corner_normals(pos, idx, kDefaultCreaseAngleDeg);
  for (int corner : {0, 5}) {  // V in the two fan triangles
    const double off = std::acos(std::min(1.0, std::abs(glm::dot(glm::normalize(Vec3d(n[size_t(corner)])), plane))));
    EXPECT_LT(off, 1e-4) << "corner " << corner;
  }
  EXPECT_EQ(corner_angle(pos[0], pos[2], pos[1], 2), 0.0);  // the cap weighs nothing
  EXPECT_GT(corner_angle(pos[1], pos[2], pos[3], 0), 0.1);   // a fan triangle does
}

TEST(CreaseNormals, ClusterPoolResolvesByKeyAndCapsClusters) {
  NormalClusterPool pool(1);
  pool.add(0, Vec3d(0, 0, 1), 1, 2);
  pool.add(0, Vec3d(0, 0, 1), 3, 2);           // merges
  pool.add(0, Vec3d(1, 0, 0), 1, 2);           // a second cluster
  const Vec3d tilted = glm::normalize(Vec3d(0, 0.1, 1));  // 5.7 degrees off +z
  pool.add(0, tilted, 1, 2);                   // over the cap: into the nearest seed (+z)
  pool.add(0, glm::normalize(Vec3d(0, 1, 1)), 1, 2);  // over the cap, 45 degrees from every seed: leftover
  const double c30 = crease_cosine(30);
  EXPECT_NEAR(glm::distance(pool.resolve(0, Vec3d(1, 0, 0), c30), Vec3d(1, 0, 0)), 0.0, 1e-6);
  const Vec3d z = pool.resolve(0, Vec3d(0, 0, 1), c30);
  EXPECT_NEAR(glm::distance(z, glm::normalize(Vec3d(0, 0, 4) + tilted)), 0.0, 1e-6);
  EXPECT_EQ(glm::length(pool.resolve(0, Vec3d(0, -1, 0), c30)), 0.0);  // nothing within 30 degrees
  // Crease angle 180 (smooth everything) sums every normal, the leftover too.
  const Vec3d all = pool.resolve(0, Vec3d(0, -1, 0), crease_cosine(180));
  EXPECT_NEAR(glm::distance(all, glm::normalize(Vec3d(0, 0, 4) + Vec3d(1, 0, 0) + tilted +
                                                glm::normalize(Vec3d(0, 1, 1)))), 0.0, 1e-6);
  EXPECT_EQ(crease_cosine(-5), 1.0);
  EXPECT_NEAR(crease_cosine(500), -1.0, 1e-12);
}

TEST(CreaseNormals, AFlatSideIsItsOwnClusterWhenOnlySliversLieNearIt) {
  const double c10 = std::cos(10.0 * M_PI / 180.0);
  auto tilt = [](double deg) { return Vec3d(std::sin(deg * M_PI / 180.0), 0, std::cos(deg * M_PI / 180.0)); };
  // A flat face (+z, weight 10) and the rows of a small fillet beside it
  // (1.5 to 43.5 degrees, weight 0.1 each): the face with the rows within
  // 10 degrees of it (1.5 to 9.5), not the crease angle's band.
  NormalClusterPool pool(3);
  pool.add(0, Vec3d(0, 0, 1), 10, 64);
  for (double deg = 1.5; deg <= 45; deg += 2) pool.add(0, tilt(deg), 0.1, 64);
  Vec3d near = 10.0 * Vec3d(0, 0, 1);
  for (double deg = 1.5; deg <= 10; deg += 2) near += 0.1 * tilt(deg);
  EXPECT_NEAR(glm::distance(pool.flat_side(0, Vec3d(0, 0, 1), c10, 0.8, 4), glm::normalize(near)), 0.0, 1e-6);
  // The band of the crease angle would tilt it: what flat_side replaces.
  const Vec3d band = pool.resolve(0, Vec3d(0, 0, 1), crease_cosine(30));
  EXPECT_GT(std::acos(std::min(1.0, band.z)), 0.02);
  // A fillet row's own cluster is no flat side.
  EXPECT_EQ(glm::length(pool.flat_side(0, tilt(19.5), c10, 0.8, 4)), 0.0);
  // Two rows of a curved tessellation 6 degrees apart, 60 and 40: neither.
  pool.add(1, tilt(0), 6, 64);
  pool.add(1, tilt(6), 4, 64);
  EXPECT_EQ(glm::length(pool.flat_side(1, tilt(0), c10, 0.8, 4)), 0.0);
  EXPECT_EQ(glm::length(pool.flat_side(1, tilt(6), c10, 0.8, 4)), 0.0);
  // Fewer rows than asked for: a small cell of a scan, one large triangle
  // beside a few small ones.
  EXPECT_EQ(glm::length(pool.flat_side(0, Vec3d(0, 0, 1), c10, 0.8, 20)), 0.0);
  // No cluster in the key's direction: nothing to stand for it.
  pool.add(2, tilt(20), 1, 64);
  EXPECT_EQ(glm::length(pool.flat_side(2, Vec3d(0, 0, 1), c10, 0.8, 4)), 0.0);
}

TEST(CreaseNormals, AFullClusterListNeverSmearsAroundACylinder) {
  // A cell holding a flat ring face and the whole bore through it: normals
  // all around the bore, far more than the cluster cap. Merging by a drifting
  // mean used to sum opposite bore normals into a cluster pointing anywhere,
  // which then passed the crease test of the flat face and tilted it by
  // 20 degrees (star-shaped wedges on OpenCASCADE ring faces).
  // The bore's normals arrive in order around it, so the cap fills up on
  // one side before the other side is seen.
  NormalClusterPool pool(1);
  pool.add(0, Vec3d(0, 0, 1), 0.3, 12);
  for (int i = 0; i < 360; ++i) {
    const double a = 2 * M_PI * i / 360.0;
    pool.add(0, Vec3d(std::cos(a), std::sin(a), 0), 1.0, 12);
  }
  const Vec3d flat = pool.resolve(0, Vec3d(0, 0, 1), crease_cosine(30));
  EXPECT_NEAR(glm::distance(flat, Vec3d(0, 0, 1)), 0.0, 1e-6);
  // A bore corner still gets the bore's nearby normals only.
  const Vec3d side = pool.resolve(0, Vec3d(1, 0, 0), crease_cosine(30));
  EXPECT_GT(side.x, 0.95);
  EXPECT_NEAR(side.z, 0.0, 1e-6);
}

TEST(CreaseNormalsProperty, MatchesThePairwiseRuleOnRandomBumpyGrids) {
  // Brute force: each corner sums the angle-weighted normals of every
  // triangle at its vertex within the crease angle of its own triangle.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> h(-0.3, 0.3);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 8;
    std::vector<Vec3> pos;
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) pos.push_back(Vec3(float(i), float(h(rng)), float(j)));
    std::vector<uint32_t> idx;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
        idx.insert(idx.end(), {a, c, b, b, c, d});
      }
    const double crease = 5 + 5 * trial;
    const std::vector<Vec3> got = crease_corner_normals(pos, idx, crease);
    const double cs = crease_cosine(crease);
    std::vector<Vec3d> fn(idx.size() / 3);
    for (size_t t = 0; t < fn.size(); ++t)
      fn[t] = face_normal(Vec3d(pos[idx[3 * t]]), Vec3d(pos[idx[3 * t + 1]]), Vec3d(pos[idx[3 * t + 2]]));
    int mismatches = 0;
    for (size_t c = 0; c < idx.size(); ++c) {
      Vec3d sum(0);
      for (size_t d = 0; d < idx.size(); ++d) {
        if (idx[d] != idx[c]) continue;
        const size_t t = d / 3;
        if (glm::dot(fn[t], fn[c / 3]) < cs) continue;
        sum += corner_angle(pos[idx[3 * t]], pos[idx[3 * t + 1]], pos[idx[3 * t + 2]], int(d % 3)) * fn[t];
      }
      const Vec3d want = glm::normalize(sum);
      // Clustering may move a normal within the merge angle of the threshold
      // to the other side; anything else must agree closely.
      if (glm::distance(Vec3d(got[c]), want) > 1e-5) ++mismatches;
    }
    EXPECT_LE(mismatches, int(idx.size()) / 50) << "crease " << crease;
  }
}

}  // namespace
}  // namespace raylod
