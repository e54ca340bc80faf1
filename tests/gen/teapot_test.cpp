// The Bezier teapot: triangle count formula, classic dimensions, normals
// (unit, outward, consistent with winding, converging to face normals), and
// bitwise identical seams between patches.
#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "gen/bezier_teapot.h"
#include "gen/teapot_patches.h"
#include "gen_test_util.h"

namespace raylod {
namespace {

using test::grid_to_mesh;

TEST(TeapotPlan, TriangleCountFormula) {
  // 24 regular patches x 2 r c + 8 pole patches x (2 r - 1) c.
  EXPECT_EQ(teapot_triangle_count(1, 1), 56u);
  EXPECT_EQ(teapot_triangle_count(4, 4), 24u * 32 + 8u * 28);
  EXPECT_EQ(teapot_triangle_count(10, 7), 24u * 140 + 8u * 133);
  for (auto [r, c] : {std::pair{1u, 1u}, {3u, 5u}, {8u, 8u}, {17u, 12u}}) {
    const TeapotPlan plan{r, c, 0, 0};
    const BezierTeapot teapot(plan);
    EXPECT_EQ(teapot.triangle_count(), teapot_triangle_count(r, c)) << r << "x" << c;
    // Vertices: regular patches (r+1)(c+1), pole patches 1 + r (c+1).
    EXPECT_EQ(teapot.vertex_count(), 24ull * (r + 1) * (c + 1) + 8ull * (1 + r * (c + 1)));
  }
}

TEST(TeapotPlan, HitsRequestedCountClosely) {
  for (uint64_t target : {1000ull, 2500ull, 10000ull, 123457ull, 1000000ull, 10000000ull, 30000000ull, 50000000ull}) {
    const TeapotPlan plan = plan_teapot(target);
    EXPECT_EQ(plan.triangles, teapot_triangle_count(plan.row_segments, plan.col_segments));
    const double rel = std::abs(double(plan.triangles) - double(target)) / double(target);
    EXPECT_LT(rel, target >= 100000 ? 0.002 : 0.03) << target;
    EXPECT_LE(plan.row_segments, 2 * plan.col_segments);
    EXPECT_LE(plan.col_segments, 2 * plan.row_segments);
  }
}

TEST(Teapot, ClassicDimensionsYUp) {
  const BezierTeapot teapot(plan_teapot(200000));
  const auto m = grid_to_mesh(teapot);
  Bbox b;
  for (const Vec3& p : m.positions) b.expand(p);
  // Newell's data: base at 0, lid knob top at 3.15, handle back at x = -3,
  // spout tip at x ~ 3.434 (the spout's last patch row), depth +-2 (body).
  EXPECT_NEAR(b.lo.y, 0.0, 1e-6);
  EXPECT_NEAR(b.hi.y, 3.15, 1e-6);
  EXPECT_NEAR(b.lo.x, -3.0, 1e-6);
  EXPECT_NEAR(b.hi.x, 3.434, 0.005);
  EXPECT_NEAR(b.lo.z, -2.0, 1e-6);
  EXPECT_NEAR(b.hi.z, 2.0, 1e-6);
}

TEST(Teapot, NormalsAreUnitAndAgreeWithWinding) {
  const auto m = grid_to_mesh(BezierTeapot(plan_teapot(20000)));
  for (size_t i = 0; i < m.normals.size(); ++i) {
    ASSERT_TRUE(is_finite(m.normals[i])) << i;
    ASSERT_NEAR(glm::length(m.normals[i]), 1.0f, 1e-5f) << i;
  }
  size_t agree = 0, degenerate = 0;
  for (size_t t = 0; t < m.triangles(); ++t) {
    const Vec3d fn = face_normal(test::corner(m, t, 0), test::corner(m, t, 1), test::corner(m, t, 2));
    if (fn == Vec3d(0)) { ++degenerate; continue; }
    int ok = 0;
    for (int k = 0; k < 3; ++k) ok += glm::dot(fn, Vec3d(m.normals[m.indices[3 * t + k]])) > 0;
    agree += ok == 3;
  }
  EXPECT_EQ(degenerate, 0u);  // poles are fans, not zero-area triangles
  EXPECT_GE(double(agree) / double(m.triangles()), 0.999);
}

TEST(Teapot, VertexNormalsConvergeToFaceNormals) {
  // Mean angle between each face normal and its vertices' analytic normals
  // shrinks with the tessellation (it is O(h)), and is small when fine.
  double previous = 1e9;
  for (uint64_t target : {5000ull, 50000ull, 500000ull}) {
    const auto m = grid_to_mesh(BezierTeapot(plan_teapot(target)));
    double sum = 0;
    size_t n = 0;
    for (size_t t = 0; t < m.triangles(); ++t) {
      const Vec3d fn = face_normal(test::corner(m, t, 0), test::corner(m, t, 1), test::corner(m, t, 2));
      for (int k = 0; k < 3; ++k) {
        sum += std::acos(std::clamp(glm::dot(fn, Vec3d(m.normals[m.indices[3 * t + k]])), -1.0, 1.0));
        ++n;
      }
    }
    const double mean_deg = sum / double(n) * 180.0 / M_PI;
    EXPECT_LT(mean_deg, previous * 0.5) << target;
    previous = mean_deg;
  }
  EXPECT_LT(previous, 1.0);
}

TEST(Teapot, EveryPatchFacesOutward) {
  // Rays cast from points on each patch along the normal: outside, a ray
  // crosses the (nearly closed) teapot an even number of times. Newell's
  // teapot is not watertight (the lid sits loosely in the rim, the spout and
  // handle pierce the body), so a few rays per patch may mislead; an inward
  // patch would make almost all of its rays odd.
  const BezierTeapot teapot(plan_teapot(20000));
  const auto mesh = grid_to_mesh(teapot);
  const Vec3d jitter(0.0123, 0.0077, -0.0091);
  for (int patch = 0; patch < teapot_data::kPatchCount; ++patch) {
    int even = 0, total = 0;
    for (int i = 1; i <= 5; ++i) {
      for (int j = 1; j <= 5; ++j) {
        Vec3d p, n;
        teapot.evaluate(patch, i / 6.0, j / 6.0, p, n);
        const Vec3d d = glm::normalize(n + jitter);
        even += test::count_crossings(mesh, p + 0.01 * n, d) % 2 == 0;
        ++total;
      }
    }
    EXPECT_GE(even, total * 2 / 3) << "patch " << patch << ": " << even << " of " << total << " rays go outward";
  }
}

TEST(Teapot, PoleNormalsAreVertical) {
  const BezierTeapot teapot(plan_teapot(5000));
  for (size_t p = 0; p < teapot.pieces().size(); ++p) {
    const GridPiece& g = teapot.pieces()[p];
    if (!g.pole_first) continue;
    Vec3 pos, nrm;
    teapot.eval_row(p, 0, std::span<Vec3>(&pos, 1), std::span<Vec3>(&nrm, 1));
    // Lid top (y = 3.15) faces up, the base centre (y = 0) faces down.
    EXPECT_EQ(pos.x, 0.0f);
    EXPECT_EQ(pos.z, 0.0f);
    EXPECT_TRUE(pos.y == 0.0f || pos.y == 3.15f) << pos.y;
    EXPECT_NEAR(nrm.y, pos.y > 1 ? 1.0f : -1.0f, 1e-6f) << "patch " << p;
  }
  EXPECT_EQ(std::count_if(teapot.pieces().begin(), teapot.pieces().end(), [](auto& g) { return g.pole_first; }), 8);
}

TEST(Teapot, NormalIsContinuousIntoThePoles) {
  // At a collapsed row dP/dt = 0; the limit normal used there must be the
  // limit of the ordinary normal dP/ds x dP/dt as s -> 0, for every t.
  const BezierTeapot teapot(plan_teapot(5000));
  int poles = 0;
  for (int patch = 0; patch < teapot_data::kPatchCount; ++patch) {
    if (!teapot.pieces()[patch].pole_first) continue;
    ++poles;
    for (double t : {0.0, 0.3, 0.5, 1.0}) {
      Vec3d p0, n0, p1, n1, p2, n2;
      teapot.evaluate(patch, 0.0, t, p0, n0);
      teapot.evaluate(patch, 1e-6, t, p1, n1);
      teapot.evaluate(patch, 1e-3, t, p2, n2);
      ASSERT_TRUE(is_finite(n0));
      EXPECT_NEAR(glm::length(n0), 1.0, 1e-12);
      EXPECT_GT(glm::dot(n0, n1), 1.0 - 1e-9) << "patch " << patch << " t " << t;
      EXPECT_GT(glm::dot(n0, n2), 0.999) << "patch " << patch << " t " << t;
      EXPECT_NEAR(std::abs(n0.y), 1.0, 1e-12);  // lid top and base are flat at the centre
    }
  }
  EXPECT_EQ(poles, 8);
}

// The samples of one boundary edge of a patch, in increasing parameter order.
std::vector<Vec3> edge_samples(const BezierTeapot& teapot, int patch, int edge) {
  const GridPiece& g = teapot.pieces()[patch];
  std::vector<Vec3> out;
  auto row = [&](uint32_t r) {
    std::vector<Vec3> pos(grid_row_vertices(g, r)), nrm(pos.size());
    teapot.eval_row(patch, r, pos, nrm);
    return pos;
  };
  if (edge == 0 || edge == 1) {  // rows s = 0 and s = 1
    auto r = row(edge == 0 ? 0 : g.rows - 1);
    if (r.size() == 1) r.assign(g.cols, r[0]);
    return r;
  }
  for (uint32_t r = 0; r < g.rows; ++r) out.push_back(edge == 2 ? row(r).front() : row(r).back());
  return out;
}

TEST(Teapot, SharedPatchEdgesAreBitwiseIdentical) {
  // Edges are identified by their 4 control point coordinates (Newell's data
  // repeats some points under different indices), in either direction.
  using Key = std::vector<double>;
  auto edge_key = [](int patch, int edge) {
    Key k;
    for (int i = 0; i < 4; ++i) {
      const int row = edge == 0 ? 0 : edge == 1 ? 3 : i, col = edge == 2 ? 0 : edge == 3 ? 3 : i;
      const double* p = teapot_data::kPoints[teapot_data::kPatches[patch][4 * row + col]];
      k.insert(k.end(), p, p + 3);
    }
    return k;
  };
  auto reversed = [](Key k) {
    Key r;
    for (int i = 3; i >= 0; --i) r.insert(r.end(), k.begin() + 3 * i, k.begin() + 3 * i + 3);
    return r;
  };
  for (uint64_t target : {3000ull, 40000ull}) {
    const BezierTeapot teapot(plan_teapot(target));
    std::map<Key, std::pair<int, int>> seen;
    int shared = 0;
    for (int p = 0; p < teapot_data::kPatchCount; ++p) {
      for (int e = 0; e < 4; ++e) {
        const Key k = edge_key(p, e);
        bool reverse = false;
        auto it = seen.find(k);
        if (it == seen.end()) { it = seen.find(reversed(k)); reverse = true; }
        if (it == seen.end()) { seen[k] = {p, e}; continue; }
        auto a = edge_samples(teapot, it->second.first, it->second.second);
        auto b = edge_samples(teapot, p, e);
        if (reverse) std::reverse(b.begin(), b.end());
        ASSERT_EQ(a.size(), b.size());
        for (size_t i = 0; i < a.size(); ++i)
          ASSERT_EQ(std::memcmp(&a[i], &b[i], sizeof(Vec3)), 0)
              << "patch " << it->second.first << " edge " << it->second.second << " vs patch " << p << " edge " << e
              << " sample " << i;
        ++shared;
      }
    }
    // Rim, body and lid rings (4 + 8 + 8 side seams, 4 + 4 ring-to-ring seams
    // and 4 body-to-base), handle and spout tubes (2 + 2 each, plus 2 + 2
    // between their halves), poles excluded: at least 40 shared edges.
    EXPECT_GE(shared, 40);
  }
}

}  // namespace
}  // namespace raylod
