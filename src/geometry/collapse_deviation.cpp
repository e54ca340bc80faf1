// Collapse deviation from a cell's quadric (see collapse_deviation.h).
#include "geometry/collapse_deviation.h"

#include <algorithm>
#include <cmath>

namespace raylod {
namespace {

// One-sided normals give |s.e| >= lambda (collapse_deviation.h); below this
// fraction of lambda, part of the cell faces the other way. Where s sums the
// face normals A is made of, the inequality is exact and the margin only
// absorbs rounding; smooth input normals need room.
constexpr double kFaceFoldMargin = 1.0 - 1e-6;
constexpr double kInputNormalFoldMargin = 0.9;
// How far a fold's edge may move, over sqrt(12 residual / lambda) along the
// weakest direction solved (collapse_deviation.h: 1.12 for a groove leaving
// a face tangentially, 0.8 to 1.1 over the arcs and facet counts tried).
constexpr double kEdgeSafety = 2.0;

// |area-weighted normal sum| / area (collapse_deviation.h); 1 (no spread)
// for an empty node.
double mean_resultant_length(const NodeRecord& node) {
  const double weight = quadric_weight(node.quadric);
  return weight > 0 && std::isfinite(weight) ? std::min(1.0, glm::length(node.normal_sum) / weight) : 1.0;
}

}  // namespace

double normal_spread_angle(const NodeRecord& node) {
  return 2.0 * std::sqrt(1.0 - mean_resultant_length(node));
}

CollapseDeviation collapse_deviation(const NodeRecord& node, const Bbox& cell, NodeNormals normals,
                                     const QemSolveConfig& config) {
  CollapseDeviation d;
  const Quadric& q = node.quadric;
  const double weight = quadric_weight(q);
  if (!(weight > 0) || !std::isfinite(weight) || node.corner_count == 0) return d;
  const Vec3d mean = node.vertex_sum / double(node.corner_count);
  const QemSolution s = solve_representative_vertex(q, mean, cell, config);
  // Q(v) is a difference of terms of size W |v|^2 (the store's frame is the
  // mesh centre, so |v| is at most the model size): rounding leaves an error
  // of about 1e-8 of the model size in `position`, clamped at zero.
  d.representative = s.position;
  const double residual = std::max(0.0, quadric_error(q, s.position));
  d.position = std::sqrt(12.0 * residual / weight);
  // Two estimates of kappa * position (collapse_deviation.h); each is too
  // large in one situation, so the smaller is taken.
  const double side = cell.extent().x;
  const double from_side = side > 0 ? 8.0 * (d.position / side) * (d.position / side) : (d.position > 0 ? M_PI : 0.0);
  const double resultant = mean_resultant_length(node);
  const double from_spread = 2.0 * (1.0 - resultant);
  d.normal = std::min({M_PI, from_side, from_spread});
  d.crease = from_spread > 0.05 && from_side < 0.1 * from_spread;
  const double across = side > 0 ? 8.0 * d.position / side : (d.position > 0 ? M_PI : 0.0);
  d.far_normal = std::min({normal_spread_angle(node), across});
  const SymmetricEigen3 e = symmetric_eigen(q);
  const double margin = normals == NodeNormals::Faces ? kFaceFoldMargin : kInputNormalFoldMargin;
  const bool opposite = std::abs(glm::dot(node.normal_sum, e.vectors[0])) < margin * e.values[0];
  if (s.rank <= 1) {
    d.folded = opposite;
  } else if (opposite && residual > 0) {
    // Opposite sheets whose edge the weaker planes pin (collapse_deviation.h).
    const double weakest = e.values[s.rank - 1];
    if (weakest > 0) d.position = std::max(d.position, kEdgeSafety * std::sqrt(12.0 * residual / weakest));
  }
  return d;
}

double descendant_deviation(std::span<const NodeRecord> descendants, const Vec3d& representative) {
  double worst = 0;
  for (const NodeRecord& n : descendants) {
    const double w = quadric_weight(n.quadric);
    if (!(w > 0) || !std::isfinite(w)) continue;
    worst = std::max(worst, std::sqrt(std::max(0.0, quadric_error(n.quadric, representative)) / w));
  }
  return worst;
}

}  // namespace raylod
