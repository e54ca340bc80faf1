// Unfolding turned-over triangles (simplify/unfold.h): tiny exact cases, the
// allowance both ways, open outlines left alone, and a seeded property test
// on jittered planar grids.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "simplify/unfold.h"

namespace raylod {
namespace {

using Tri = std::array<uint32_t, 3>;

struct Case {
  std::vector<Tri> tris;
  std::vector<Vec3> keys;
  std::vector<Vec3> reps;
  std::vector<Vec3> kept;
  std::vector<UnfoldLimit> limits;  // per representative
  std::vector<uint8_t> dead;  // per triangle, from UnfoldResult::dead
  UnfoldResult result;

  UnfoldStats run() {
    const UnfoldStats s = unfold_representatives(
        tris, keys, reps, kept, [&](uint32_t v) { return v < limits.size(); },
        [&](uint32_t v) { return limits[v]; }, result);
    dead.assign(tris.size(), 0);
    for (uint32_t t : result.dead) dead[t] = 1;
    return s;
  }
  Vec3d pos(uint32_t v) const { return v < reps.size() ? Vec3d(reps[v]) : Vec3d(kept[v - reps.size()]); }
  bool folded(size_t t) const {
    return keys[t] != Vec3(0) && faces_against(pos(tris[t][0]), pos(tris[t][1]), pos(tris[t][2]), Vec3d(keys[t]));
  }
  size_t live() const {
    size_t n = 0;
    for (size_t t = 0; t < tris.size(); ++t) n += dead.empty() || !dead[t];
    return n;
  }
  size_t live_folded() const {
    size_t n = 0;
    for (size_t t = 0; t < tris.size(); ++t) n += (dead.empty() || !dead[t]) && folded(t);
    return n;
  }
};

// Representative 0 with a closed fan of six kept vertices on a unit hexagon
// in z = 0, every input triangle facing +z; the representative at `at`.
Case hexagon_fan(const Vec3& at, const Bbox& cell, const Vec3d& plane, double allowance) {
  Case c;
  c.reps = {at};
  for (int i = 0; i < 6; ++i) {
    const double a = i * M_PI / 3;
    c.kept.push_back(Vec3(float(std::cos(a)), float(std::sin(a)), 0));
  }
  for (uint32_t i = 0; i < 6; ++i) {
    c.tris.push_back({0, 1 + i, 1 + (i + 1) % 6});
    c.keys.push_back({0, 0, 1});
  }
  c.limits = {UnfoldLimit{cell, plane, allowance}};
  return c;
}

TEST(Unfold, ARepresentativeOutsideItsFanSlidesBackWithinItsCellAndPlane) {
  const Bbox cell{{-0.5, -0.5, -0.5}, {1.5, 0.5, 0.5}};
  Case c = hexagon_fan({1.4f, 0.1f, 0}, cell, {0, 0, 1}, 1e-6);
  const size_t before = c.live_folded();
  ASSERT_GT(before, 0u) << "the case must turn triangles over";
  const UnfoldStats s = c.run();
  EXPECT_EQ(s.folded_before, before);
  EXPECT_EQ(s.folded_after, 0u);
  EXPECT_EQ(s.moved, 1u);
  EXPECT_EQ(s.merged, 0u);
  EXPECT_EQ(c.result.slid, std::vector<uint32_t>{0});
  EXPECT_EQ(c.live(), 6u);
  EXPECT_EQ(c.live_folded(), 0u);
  EXPECT_EQ(c.reps[0].z, 0.0f);
  EXPECT_TRUE(cell.contains(Vec3d(c.reps[0])));
  // Every triangle at least the minimum height over its outer edge (a unit
  // edge), less the slack the projections accept.
  for (size_t t = 0; t < c.tris.size(); ++t) {
    const Vec3d a = c.pos(c.tris[t][0]), b = c.pos(c.tris[t][1]), d = c.pos(c.tris[t][2]);
    EXPECT_GE(glm::length(glm::cross(b - a, d - a)), 0.25 * kUnfoldMinHeight) << t;
  }
}

TEST(Unfold, WhereNoPointOfTheCellHelpsAnEdgeCollapsesOntoAKeptCorner) {
  // The cell lies wholly outside the hexagon: no slide can unfold the fan.
  const Bbox cell{{1.2, -0.2, -0.2}, {1.6, 0.2, 0.2}};
  Case c = hexagon_fan({1.4f, 0.0f, 0}, cell, {0, 0, 1}, 1e-6);
  ASSERT_GT(c.live_folded(), 0u);
  const UnfoldStats s = c.run();
  EXPECT_EQ(s.moved, 0u);
  EXPECT_EQ(s.merged, 1u);
  EXPECT_EQ(s.dropped, 2u);  // the two triangles on the collapsed edge
  EXPECT_EQ(s.folded_after, 0u);
  EXPECT_EQ(c.live(), 4u);
  EXPECT_EQ(c.live_folded(), 0u);
  // The four moved corners keep the representative's name for their normals.
  ASSERT_EQ(c.result.renamed.size(), 4u);
  for (const auto& [corner, was] : c.result.renamed) {
    EXPECT_FALSE(c.dead[corner / 3]);
    EXPECT_EQ(was, 0u);
    EXPECT_NE(c.tris[corner / 3][corner % 3], 0u);
  }
  // The four left fan out from one hexagon corner and cover the hexagon
  // once: their areas sum to its area.
  double area = 0;
  for (size_t t = 0; t < c.tris.size(); ++t) {
    if (c.dead[t]) continue;
    for (uint32_t v : c.tris[t]) EXPECT_NE(v, 0u) << "the representative is gone";
    const Vec3d a = c.pos(c.tris[t][0]), b = c.pos(c.tris[t][1]), d = c.pos(c.tris[t][2]);
    area += 0.5 * glm::dot(glm::cross(b - a, d - a), Vec3d(0, 0, 1));
  }
  EXPECT_NEAR(area, 1.5 * std::sqrt(3.0), 1e-5);
}

TEST(Unfold, AMoveOffTheSurfaceBeyondTheAllowanceIsNotMade) {
  // The representative stands 0.5 above the hexagon and outside it: any
  // unfolding move takes the surface off its fan's planes by far more than
  // 0.01; with an allowance of 1 it unfolds.
  const Bbox cell{{-0.5, -0.5, -0.5}, {1.5, 0.5, 0.6}};
  for (const double allowance : {0.01, 1.0}) {
    Case c = hexagon_fan({1.4f, 0.1f, 0.5f}, cell, {0, 0, 1}, allowance);
    const Case before = c;
    const size_t folded = c.live_folded();
    ASSERT_GT(folded, 0u);
    const UnfoldStats s = c.run();
    if (allowance < 0.1) {
      EXPECT_EQ(s.moved + s.merged, 0u);
      EXPECT_EQ(c.reps, before.reps);
      EXPECT_EQ(c.tris, before.tris);
      EXPECT_EQ(s.folded_after, folded);
    } else {
      EXPECT_EQ(s.folded_after, 0u);
      EXPECT_EQ(c.live_folded(), 0u);
    }
  }
}

TEST(Unfold, AVertexOnAnOpenOutlineStays) {
  // Half the hexagon's fan: the representative lies on the outline, and
  // moving it would move the outline.
  Case c = hexagon_fan({1.4f, 0.1f, 0}, Bbox{{-0.5, -0.5, -0.5}, {1.5, 0.5, 0.5}}, {0, 0, 1}, 1e-6);
  c.tris.resize(3);
  c.keys.resize(3);
  ASSERT_GT(c.live_folded(), 0u);
  const Case before = c;
  const UnfoldStats s = c.run();
  EXPECT_EQ(s.moved + s.merged, 0u);
  EXPECT_EQ(c.reps, before.reps);
  EXPECT_EQ(c.tris, before.tris);
}

TEST(Unfold, AnInputTriangleWithoutAreaIsNeverTurnedOverButKeepsSomeArea) {
  // The hexagon fan with its first triangle split at the middle of its
  // outer edge, one half's input without area (its key zero): that half
  // counts as neither turned over nor upright, so it neither starts a move
  // nor blocks one, but a move may not flatten it.
  Case c = hexagon_fan({1.4f, 0.1f, 0}, Bbox{{-0.5, -0.5, -0.5}, {1.5, 0.5, 0.5}}, {0, 0, 1}, 1e-6);
  c.kept.push_back(0.5f * (c.kept[0] + c.kept[1]));
  c.tris[0] = {0, 1, 7};
  c.keys[0] = Vec3(0);
  c.tris.push_back({0, 7, 2});
  c.keys.push_back({0, 0, 1});
  const size_t keyed_folded = c.live_folded();
  const UnfoldStats s = c.run();
  EXPECT_EQ(s.folded_before, keyed_folded) << "the zero-key triangle is not counted";
  EXPECT_EQ(s.folded_after, 0u);
  EXPECT_EQ(s.moved, 1u);
  const Vec3d a = c.pos(0), b = c.pos(7), d = c.pos(1);
  EXPECT_GT(glm::length(glm::cross(b - a, d - a)), 0.0);
}

TEST(Unfold, AMergeThatWouldDoubleATriangleIsNotMade) {
  // A tetrahedron's corner: representative 0 over the kept triangle
  // (1, 2, 3), its three triangles around it, and the base (1, 3, 2) seen
  // from below. Collapsing 0 onto 1 would leave (1, 2, 3) beside its reverse
  // (1, 3, 2): two coincident layers, no better than the fold. 0 is pushed
  // through the base so that its triangles turn over.
  Case c;
  c.reps = {Vec3(0.3f, 0.3f, -0.5f)};
  c.kept = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  c.tris = {{0, 1, 2}, {0, 2, 3}, {0, 3, 1}, {1, 3, 2}};
  const Vec3d top(0.3, 0.3, 0.5);
  const auto face = [&](const Vec3d& a, const Vec3d& b, const Vec3d& d) { return Vec3(glm::normalize(glm::cross(b - a, d - a))); };
  c.keys = {face(top, Vec3d(0, 0, 0), Vec3d(1, 0, 0)), face(top, Vec3d(1, 0, 0), Vec3d(0, 1, 0)),
            face(top, Vec3d(0, 1, 0), Vec3d(0, 0, 0)), Vec3(0, 0, -1)};
  c.limits = {UnfoldLimit{Bbox{{-1, -1, -1}, {1, 1, -0.4}}, {0, 0, 0}, 10.0}};
  ASSERT_GT(c.live_folded(), 0u);
  const Case before = c;
  const UnfoldStats s = c.run();
  EXPECT_EQ(s.merged, 0u);
  EXPECT_EQ(c.tris, before.tris);
  EXPECT_EQ(c.live(), 4u);
}

// A planar n x n grid whose every vertex is a representative jittered
// within its cell (the grid square around it), the outline's vertices kept.
Case jittered_grid(int n, double jitter, uint32_t seed) {
  Case c;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  std::vector<uint32_t> id(size_t(n * n));
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const bool outline = x == 0 || y == 0 || x == n - 1 || y == n - 1;
      if (outline) continue;
      id[size_t(y * n + x)] = uint32_t(c.reps.size());
      c.reps.push_back(Vec3(float(x + u(rng)), float(y + u(rng)), 0));
      c.limits.push_back(UnfoldLimit{Bbox{{x - 0.5, y - 0.5, -0.5}, {x + 0.5, y + 0.5, 0.5}}, {0, 0, 1}, 1e-6});
    }
  const uint32_t nreps = uint32_t(c.reps.size());
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const bool outline = x == 0 || y == 0 || x == n - 1 || y == n - 1;
      if (!outline) continue;
      id[size_t(y * n + x)] = nreps + uint32_t(c.kept.size());
      c.kept.push_back(Vec3(float(x), float(y), 0));
    }
  for (int y = 0; y + 1 < n; ++y)
    for (int x = 0; x + 1 < n; ++x) {
      const uint32_t a = id[size_t(y * n + x)], b = id[size_t(y * n + x + 1)], d = id[size_t((y + 1) * n + x)],
                     e = id[size_t((y + 1) * n + x + 1)];
      c.tris.push_back({a, b, e});
      c.tris.push_back({a, e, d});
      c.keys.push_back({0, 0, 1});
      c.keys.push_back({0, 0, 1});
    }
  return c;
}

TEST(Unfold, JitteredGridsUnfoldWithoutNewFoldsOrGaps) {
  const int n = 14;
  uint64_t before_all = 0, after_all = 0;
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    Case c = jittered_grid(n, 0.49, seed);
    std::vector<uint8_t> was_folded(c.tris.size());
    for (size_t t = 0; t < c.tris.size(); ++t) was_folded[t] = c.folded(t);
    Case again = c;
    const UnfoldStats s = c.run();
    before_all += s.folded_before;
    after_all += s.folded_after;
    EXPECT_LE(s.folded_after, s.folded_before) << "seed " << seed;
    EXPECT_EQ(c.live(), c.tris.size() - s.dropped) << "seed " << seed;
    // Nothing upright before turns over.
    for (size_t t = 0; t < c.tris.size(); ++t)
      if (!c.dead[t] && !was_folded[t]) {
        EXPECT_FALSE(c.folded(t)) << "seed " << seed << " triangle " << t;
      }
    // Every representative in its cell and its plane.
    for (size_t v = 0; v < c.reps.size(); ++v) {
      EXPECT_TRUE(c.limits[v].cell.contains(Vec3d(c.reps[v]))) << "seed " << seed;
      EXPECT_EQ(c.reps[v].z, 0.0f);
    }
    // No gaps: the signed areas still sum to the square's (the outline is
    // kept), and where nothing is turned over the triangles cover it once.
    double signed_area = 0, area = 0;
    for (size_t t = 0; t < c.tris.size(); ++t) {
      if (c.dead[t]) continue;
      const Vec3d a = c.pos(c.tris[t][0]), b = c.pos(c.tris[t][1]), d = c.pos(c.tris[t][2]);
      const double z = 0.5 * glm::cross(b - a, d - a).z;
      signed_area += z;
      area += std::abs(z);
    }
    const double square = double(n - 1) * (n - 1);
    EXPECT_NEAR(signed_area, square, 1e-3) << "seed " << seed;
    if (s.folded_after == 0) {
      EXPECT_NEAR(area, square, 1e-3) << "seed " << seed;
    }
    // The same result again (no dependence on anything but the input).
    again.run();
    EXPECT_EQ(again.reps, c.reps);
    EXPECT_EQ(again.tris, c.tris);
    EXPECT_EQ(again.dead, c.dead);
  }
  ASSERT_GT(before_all, 50u) << "the grids must turn triangles over to test anything";
  EXPECT_LT(after_all * 10, before_all) << "fewer than 9 in 10 unfolded";
}

}  // namespace
}  // namespace raylod
