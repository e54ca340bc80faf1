// Collapse deviation from a cell's quadric (see collapse_deviation.h).
#include "geometry/collapse_deviation.h"

#include <algorithm>
#include <cmath>

namespace raylod {
namespace {

// One-sided normals give |s.e| >= lambda (collapse_deviation.h); below this
// fraction of lambda, part of the cell faces the other way.
constexpr double kFoldMargin = 0.9;

}  // namespace

CollapseDeviation collapse_deviation(const NodeRecord& node, const Bbox& cell, const QemSolveConfig& config) {
  CollapseDeviation d;
  const Quadric& q = node.quadric;
  const double weight = q.a00 + q.a11 + q.a22;
  if (!(weight > 0) || !std::isfinite(weight) || node.corner_count == 0) return d;
  const Vec3d mean = node.vertex_sum / double(node.corner_count);
  const QemSolution s = solve_representative_vertex(q, mean, cell, config);
  // Q(v) is a difference of terms of size W |v|^2 (the store's frame is the
  // mesh centre, so |v| is at most the model size): rounding leaves an error
  // of about 1e-8 of the model size in `position`, clamped at zero.
  const double residual = std::max(0.0, quadric_error(q, s.position));
  d.position = std::sqrt(12.0 * residual / weight);
  // Two estimates of kappa * position (collapse_deviation.h); each is too
  // large in one situation, so the smaller is taken.
  const double side = cell.extent().x;
  const double from_side = side > 0 ? 8.0 * (d.position / side) * (d.position / side) : (d.position > 0 ? M_PI : 0.0);
  const double resultant = std::min(1.0, glm::length(node.normal_sum) / weight);
  const double from_spread = 2.0 * (1.0 - resultant);
  d.normal = std::min({M_PI, from_side, from_spread});
  d.crease = from_spread > 0.05 && from_side < 0.1 * from_spread;
  if (s.rank <= 1) {
    const SymmetricEigen3 e = symmetric_eigen(q);
    d.folded = std::abs(glm::dot(node.normal_sum, e.vectors[0])) < kFoldMargin * e.values[0];
  }
  return d;
}

}  // namespace raylod
