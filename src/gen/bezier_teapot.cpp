// Tessellation of Newell's Bezier teapot (Newell 1975; data in
// teapot_patches.h). A bicubic patch is P(s, t) = sum_ij B_i(s) B_j(t) P_ij
// with the cubic Bernstein basis B; its normal is dP/ds x dP/dt.
//
// Crack-free seams. Two patches that share an edge share its 4 control points,
// possibly in reverse order, and sample it at the same parameters (same grid).
// The edge point is the cubic curve through those 4 points, and we make its
// floating-point evaluation symmetric so that both patches get the same bits:
//  * parameters come from integers, t = b/n and 1-t = (n-b)/n, so reversing the
//    edge swaps the two values exactly;
//  * B1 = 3 (t u) u and B2 = 3 (t u) t, so reversal swaps B0<->B3 and B1<->B2;
//  * the sum is (B0 P0 + B3 P3) + (B1 P1 + B2 P2), invariant under that swap;
//  * on an edge the other direction's basis is exactly (1, 0, 0, 0), and
//    1 x + 0 y = x, so the tensor product reduces to the same curve sum
//    (zeros are made positive at the end so -0 and +0 cannot differ).
// This relies on no FMA contraction (the x86-64 baseline has no FMA and the
// build uses ISO C++, where GCC does not contract across statements).
#include "gen/bezier_teapot.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "gen/teapot_patches.h"

namespace raylod {
namespace {

using teapot_data::kPatchCount;
using teapot_data::kPatches;
using teapot_data::kPoints;

// Patches whose dP/ds x dP/dt points into the teapot. With Newell's rows (s)
// running from top to bottom (or centre outwards) and t turning clockwise
// seen from above, that is every patch; tests/gen/teapot_test.cpp casts rays
// from each patch along its normal to check that all now face outward.
constexpr bool kInward[kPatchCount] = {
    true, true, true, true,   true, true, true, true,   true, true, true, true,   // rim, body
    true, true, true, true,   true, true, true, true,                           // handle, spout
    true, true, true, true,   true, true, true, true,                           // lid
    true, true, true, true};                                                    // bottom

Vec3d control_point(int patch, int row, int col) {
  const double* p = kPoints[kPatches[patch][4 * row + col]];
  return Vec3d(p[0], p[1], p[2]);
}

// Newell's z-up frame to raylod's y-up frame: a rotation about x by -90 deg.
Vec3d to_y_up(const Vec3d& v) { return Vec3d(v.x, v.z, -v.y); }

// Symmetric Bernstein sum, see the file comment.
inline Vec3d combine(const double w[4], const Vec3d& p0, const Vec3d& p1, const Vec3d& p2, const Vec3d& p3) {
  return (w[0] * p0 + w[3] * p3) + (w[1] * p1 + w[2] * p2);
}

bool row_collapsed(int patch, int row) {
  const int* idx = &kPatches[patch][4 * row];
  for (int c = 1; c < 4; ++c)
    for (int k = 0; k < 3; ++k)
      if (kPoints[idx[c]][k] != kPoints[idx[0]][k]) return false;
  return true;
}

struct PatchEval {
  Vec3d p, ds, dt, dst;
};

}  // namespace

uint64_t teapot_triangle_count(uint32_t r, uint32_t c) {
  return 64ull * r * c - 8ull * c;
}

TeapotPlan plan_teapot(uint64_t target) {
  struct Candidate {
    uint32_t r, c;
    uint64_t n;
    double err, aspect;
  };
  std::vector<Candidate> candidates{{1, 1, teapot_triangle_count(1, 1), 0, 0}};
  candidates[0].err = std::abs(double(candidates[0].n) - double(target));
  // r c ~ target / 64 with r / c within [1/2, 2].
  const uint32_t c_max = uint32_t(std::sqrt(double(target) / 32.0)) + 2;
  for (uint32_t c = 1; c <= c_max; ++c) {
    const double r_real = (double(target) + 8.0 * c) / (64.0 * c);
    for (double rr : {std::floor(r_real), std::ceil(r_real)}) {
      if (rr < 1) continue;
      const uint32_t r = uint32_t(rr);
      if (r > 2 * c || c > 2 * r) continue;
      const uint64_t n = teapot_triangle_count(r, c);
      candidates.push_back({r, c, n, std::abs(double(n) - double(target)), std::abs(std::log(double(r) / c))});
    }
  }
  const Candidate* best = &pick_squarest_resolution(candidates, target);
  TeapotPlan plan{best->r, best->c, best->n, 0};
  plan.vertices = BezierTeapot(plan).vertex_count();
  return plan;
}

BezierTeapot::BezierTeapot(const TeapotPlan& plan) : plan_(plan) {
  assert(plan.row_segments >= 1 && plan.col_segments >= 1);
  for (int p = 0; p < kPatchCount; ++p) {
    GridPiece g;
    g.rows = plan.row_segments + 1;
    g.cols = plan.col_segments + 1;
    g.pole_first = row_collapsed(p, 0);
    g.pole_last = row_collapsed(p, 3);
    g.flip = kInward[p];
    // A 1-segment grid with two poles would have no area; Newell's data has none.
    assert(!(g.pole_first && g.pole_last));
    pieces_.push_back(g);
  }
  col_basis_.reserve(plan.col_segments + 1);
  for (uint32_t b = 0; b <= plan.col_segments; ++b) col_basis_.push_back(bernstein(b, plan.col_segments));
}

// Cubic Bernstein weights and derivatives at t, with u = 1 - t passed in so
// that callers can compute it exactly: (n - i) / n is exact where 1 - i / n
// is not, and that keeps patch seams bitwise identical from both sides.
BezierTeapot::Basis BezierTeapot::bernstein_tu(double t, double u) {
  const double m = t * u;
  Basis r;
  r.b[0] = u * u * u;
  r.b[1] = 3.0 * m * u;
  r.b[2] = 3.0 * m * t;
  r.b[3] = t * t * t;
  r.d[0] = -3.0 * u * u;
  r.d[1] = 3.0 * u * (u - 2.0 * t);
  r.d[2] = 3.0 * t * (2.0 * u - t);
  r.d[3] = 3.0 * t * t;
  return r;
}

BezierTeapot::Basis BezierTeapot::bernstein(uint32_t i, uint32_t n) {
  return bernstein_tu(double(i) / double(n), double(n - i) / double(n));
}

BezierTeapot::Basis BezierTeapot::bernstein(double t) { return bernstein_tu(t, 1.0 - t); }

namespace {

// Column curves at s (C_j = sum_i B_i(s) P_ij and their s-derivatives E_j),
// then the t direction.
PatchEval eval_patch(int patch, const double bs[4], const double dbs[4], const double bt[4], const double dbt[4]) {
  Vec3d c[4], e[4];
  for (int j = 0; j < 4; ++j) {
    const Vec3d p0 = control_point(patch, 0, j), p1 = control_point(patch, 1, j);
    const Vec3d p2 = control_point(patch, 2, j), p3 = control_point(patch, 3, j);
    c[j] = combine(bs, p0, p1, p2, p3);
    e[j] = combine(dbs, p0, p1, p2, p3);
  }
  PatchEval r;
  r.p = combine(bt, c[0], c[1], c[2], c[3]);
  r.ds = combine(bt, e[0], e[1], e[2], e[3]);
  r.dt = combine(dbt, c[0], c[1], c[2], c[3]);
  r.dst = combine(dbt, e[0], e[1], e[2], e[3]);
  return r;
}

// dP/ds x dP/dt, unless it (nearly) vanishes: where a row collapses, dP/dt = 0
// and dP/dt ~ (s - s_pole) d2P/dsdt, so the normal's limit is
// +-(dP/ds x d2P/dsdt). Returns a zero vector if both vanish.
Vec3d raw_normal(const PatchEval& e, int pole_side) {
  if (pole_side != 0) return double(pole_side) * glm::cross(e.ds, e.dst);
  return glm::cross(e.ds, e.dt);
}

bool degenerate(const Vec3d& n, const PatchEval& e) {
  const double scale = glm::length(e.ds) * glm::length(e.dt);
  return !(glm::length(n) > 1e-9 * std::max(scale, 1e-300)) || glm::length(n) < 1e-14;
}

}  // namespace

void BezierTeapot::evaluate(int patch, double s, double t, Vec3d& position, Vec3d& normal) const {
  const Basis bs = bernstein(s), bt = bernstein(t);
  const PatchEval e = eval_patch(patch, bs.b, bs.d, bt.b, bt.d);
  const int pole_side = (s == 0.0 && pieces_[patch].pole_first) ? 1 : (s == 1.0 && pieces_[patch].pole_last) ? -1 : 0;
  Vec3d n = raw_normal(e, pole_side);
  for (double delta = 1e-7; degenerate(n, e) && delta < 1e-2; delta *= 100) {
    // Not a collapsed row, but a vanishing derivative: take the normal a tiny
    // step towards the patch centre.
    const Basis bs2 = bernstein(s + delta * (0.5 - s)), bt2 = bernstein(t + delta * (0.5 - t));
    n = raw_normal(eval_patch(patch, bs2.b, bs2.d, bt2.b, bt2.d), 0);
  }
  if (kInward[patch]) n = -n;
  position = to_y_up(e.p) + Vec3d(0.0);
  normal = to_y_up(glm::normalize(n));
}

void BezierTeapot::eval_row(size_t piece, uint32_t row, std::span<Vec3> positions, std::span<Vec3> normals) const {
  const GridPiece& g = pieces_[piece];
  const int patch = int(piece);
  const Basis bs = bernstein(row, plan_.row_segments);
  const bool pole = (row == 0 && g.pole_first) || (row + 1 == g.rows && g.pole_last);
  if (pole) {
    // All control points of the row coincide: the position is that point
    // exactly, and the normal the limit at the middle of the collapsed edge
    // (for Newell's lid and base it is the vertical axis for every t).
    Vec3d p, n;
    evaluate(patch, row == 0 ? 0.0 : 1.0, 0.5, p, n);
    p = to_y_up(control_point(patch, row == 0 ? 0 : 3, 0)) + Vec3d(0.0);
    positions[0] = Vec3(p);
    normals[0] = Vec3(n);
    return;
  }
  // Column curves for this row, shared by every vertex of the row.
  Vec3d c[4], e[4];
  for (int j = 0; j < 4; ++j) {
    const Vec3d p0 = control_point(patch, 0, j), p1 = control_point(patch, 1, j);
    const Vec3d p2 = control_point(patch, 2, j), p3 = control_point(patch, 3, j);
    c[j] = combine(bs.b, p0, p1, p2, p3);
    e[j] = combine(bs.d, p0, p1, p2, p3);
  }
  const double sign = kInward[patch] ? -1.0 : 1.0;
  for (uint32_t b = 0; b < g.cols; ++b) {
    const Basis& bt = col_basis_[b];
    const Vec3d p = combine(bt.b, c[0], c[1], c[2], c[3]);
    const Vec3d ds = combine(bt.b, e[0], e[1], e[2], e[3]);
    const Vec3d dt = combine(bt.d, c[0], c[1], c[2], c[3]);
    Vec3d n = glm::cross(ds, dt);
    const double len = glm::length(n);
    if (!(len > 1e-9 * glm::length(ds) * glm::length(dt)) || len < 1e-14) {
      Vec3d q;
      evaluate(patch, double(row) / plan_.row_segments, double(b) / plan_.col_segments, q, n);
      normals[b] = Vec3(n);
    } else {
      normals[b] = Vec3(to_y_up(n * (sign / len)));
    }
    positions[b] = Vec3(to_y_up(p) + Vec3d(0.0));
  }
}

}  // namespace raylod
