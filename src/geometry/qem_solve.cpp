// Robust QEM representative vertex: truncated eigen decomposition of A around
// the cell's mean vertex (Lindstrom, "Out-of-Core Simplification of Large
// Polygonal Models", SIGGRAPH 2000, section 3: pseudo-inverse with a relative
// singular value threshold; method eqs. 3-4).
#include "geometry/qem_solve.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace raylod {
namespace {

using M3 = double[3][3];

bool quadric_is_finite(const Quadric& q) {
  const double v[] = {q.a00, q.a01, q.a02, q.a11, q.a12, q.a22, q.b0, q.b1, q.b2};
  for (double x : v) if (!std::isfinite(x)) return false;
  return true;
}

Vec3d apply_a(const Quadric& q, const Vec3d& v) {
  return {q.a00 * v.x + q.a01 * v.y + q.a02 * v.z,
          q.a01 * v.x + q.a11 * v.y + q.a12 * v.z,
          q.a02 * v.x + q.a12 * v.y + q.a22 * v.z};
}

// A' = P^T A P and V' = V P for the Jacobi rotation P in the (p, r) plane
// chosen so that A'[p][r] = 0 (Numerical Recipes eqs. 11.1.8-11.1.18).
void jacobi_rotate(M3& a, M3& v, int p, int r) {
  const double apr = a[p][r];
  const double theta = (a[r][r] - a[p][p]) / (2.0 * apr);
  double t;
  if (std::abs(theta) > 1e150) {
    t = 0.5 / theta;  // theta^2 would overflow; t ~ 1/(2 theta)
  } else {
    t = (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
  }
  const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
  double ap[3], ar[3];
  for (int k = 0; k < 3; ++k) { ap[k] = a[k][p]; ar[k] = a[k][r]; }
  // Columns: A P
  for (int k = 0; k < 3; ++k) { a[k][p] = c * ap[k] - s * ar[k]; a[k][r] = s * ap[k] + c * ar[k]; }
  // Rows: P^T (A P)
  for (int k = 0; k < 3; ++k) {
    const double pk = a[p][k], rk = a[r][k];
    a[p][k] = c * pk - s * rk;
    a[r][k] = s * pk + c * rk;
  }
  a[p][r] = a[r][p] = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double vp = v[k][p], vr = v[k][r];
    v[k][p] = c * vp - s * vr;
    v[k][r] = s * vp + c * vr;
  }
}

}  // namespace

SymmetricEigen3 symmetric_eigen(const Quadric& q) {
  M3 a = {{q.a00, q.a01, q.a02}, {q.a01, q.a11, q.a12}, {q.a02, q.a12, q.a22}};
  M3 v = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  SymmetricEigen3 out;
  if (!quadric_is_finite(q)) return out;  // zero values, identity frame
  // Scaled to a largest entry of 1, so that the squares below neither
  // underflow (areas of 1e-170) nor overflow (1e160): either ended the sweeps
  // before the first and returned the diagonal as the eigenvalues. The
  // eigenvalues are scaled back; the vectors do not depend on the scale.
  double scale = 0;
  for (auto& row : a) for (double x : row) scale = std::max(scale, std::abs(x));
  if (!(scale > 0)) return out;
  for (auto& row : a) for (double& x : row) x /= scale;
  double norm2 = 0;
  for (auto& row : a) for (double x : row) norm2 += x * x;
  for (int sweep = 0; sweep < 64 && norm2 > 0; ++sweep) {
    const double off2 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if (off2 <= 1e-32 * norm2) break;
    for (auto [p, r] : {std::pair{0, 1}, std::pair{0, 2}, std::pair{1, 2}})
      if (a[p][r] != 0.0) jacobi_rotate(a, v, p, r);
  }
  int order[3] = {0, 1, 2};
  std::sort(order, order + 3, [&](int i, int j) { return a[i][i] > a[j][j]; });
  for (int i = 0; i < 3; ++i) {
    out.values[i] = a[order[i]][order[i]] * scale;
    out.vectors[i] = glm::normalize(Vec3d(v[0][order[i]], v[1][order[i]], v[2][order[i]]));
  }
  out.vectors[2] = glm::cross(out.vectors[0], out.vectors[1]);  // right-handed
  return out;
}

QemSolution solve_representative_vertex(const Quadric& q, const Vec3d& mean, const Bbox& cell,
                                        const QemSolveConfig& config) {
  QemSolution out;
  const Vec3d clamp_lo = cell.empty() ? mean : cell.lo, clamp_hi = cell.empty() ? mean : cell.hi;
  auto clamp = [&](const Vec3d& p) { return glm::clamp(p, clamp_lo, clamp_hi); };
  if (!is_finite(mean)) {
    out.position = cell.empty() ? Vec3d(0) : cell.center();
    out.clamped = true;
    return out;
  }
  out.position = clamp(mean);
  out.clamped = out.position != mean;
  if (!quadric_is_finite(q)) return out;

  const SymmetricEigen3 e = symmetric_eigen(q);
  const double lmax = e.values[0];
  if (!(lmax > 0)) return out;
  // Solve A x = b - A mean in the eigenbasis, relative to the mean (the local
  // origin): the residual r is small where the mean is already near the
  // planes, so large coordinates cancel before the division.
  const Vec3d r = Vec3d(q.b0, q.b1, q.b2) - apply_a(q, mean);
  int rank = 0;
  Vec3d step[3];
  for (int i = 0; i < 3; ++i) {
    if (!(e.values[i] > config.relative_threshold * lmax)) break;
    step[i] = (glm::dot(e.vectors[i], r) / e.values[i]) * e.vectors[i];
    rank = i + 1;
  }
  // The best point of the highest rank that stays in the cell (a small
  // tolerance keeps solutions that round onto the cell's faces); dropping the
  // weakest direction first keeps the strongest planes satisfied.
  // The residual r carries the rounding of b and of A mean, about eps times
  // the coordinates' size times lmax, and the step along direction k divides
  // it by values[k - 1]: a corner that lies exactly on a cell's face (CAD
  // dimensions on the octree's grid) can come out outside by that much at
  // deep levels, and was then solved at a lower rank, a good part of a cell
  // away. The tolerance grows with it.
  const double extent = cell.empty() ? 0.0 : std::max({cell.extent().x, cell.extent().y, cell.extent().z});
  const double size = std::max({max_abs(mean), cell.empty() ? 0.0 : max_abs(cell.lo), cell.empty() ? 0.0 : max_abs(cell.hi)});
  for (int k = rank; k >= 1; --k) {
    const double tol =
        cell.empty() ? 0.0 : 1e-9 * extent + 64 * std::numeric_limits<double>::epsilon() * size * lmax / e.values[k - 1];
    Vec3d v = mean;
    for (int i = 0; i < k; ++i) v += step[i];
    if (!is_finite(v)) continue;
    const bool inside = cell.empty() || (glm::all(glm::greaterThanEqual(v, cell.lo - tol)) &&
                                         glm::all(glm::lessThanEqual(v, cell.hi + tol)));
    if (inside) {
      out.position = clamp(v);
      out.rank = k;
      out.clamped = false;
      return out;
    }
  }
  // Every solution of rank >= 1 left the cell: fall back to the (clamped) mean.
  if (rank > 0) out.clamped = true;
  return out;
}

Vec3d dominant_normal(const Quadric& q) {
  const SymmetricEigen3 e = symmetric_eigen(q);
  if (!(e.values[0] > 0) || !is_finite(e.vectors[0])) return Vec3d(0, 1, 0);
  Vec3d n = e.vectors[0];
  int k = 0;
  for (int i = 1; i < 3; ++i) if (std::abs(n[i]) > std::abs(n[k])) k = i;
  return n[k] < 0 ? -n : n;
}

}  // namespace raylod
