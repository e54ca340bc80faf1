// The representative vertex of a collapsed cell: the point minimising the
// cell's plane quadric (Garland and Heckbert 1997; Lindstrom 2000; method
// eqs. 3 and 4), solved so that it stays defined and inside the cell when the
// quadric is singular or badly conditioned (flat, cylindrical and linear
// clusters, a single vertex, all-equal vertices).
//
// All inputs are in one frame: the frame the quadric was accumulated in
// (relative to StoreHeader::origin for store quadrics). The solve itself runs
// relative to the cell's mean vertex, so its result does not lose digits to
// large absolute coordinates.
#pragma once

#include "core/math.h"
#include "streaming/octree_store.h"

namespace raylod {

// Eigen decomposition of the symmetric 3x3 matrix A of a quadric:
// A = sum_i values[i] * vectors[i] vectors[i]^T, values sorted descending,
// vectors orthonormal (a right-handed frame).
struct SymmetricEigen3 {
  double values[3] = {0, 0, 0};
  Vec3d vectors[3] = {Vec3d(1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, 0, 1)};
};
// Cyclic Jacobi rotations in double; converges quadratically, about 4 sweeps.
SymmetricEigen3 symmetric_eigen(const Quadric& q);

struct QemSolveConfig {
  // Eigenvalues of A below relative_threshold * (largest eigenvalue) are
  // treated as zero (truncated pseudo-inverse). Two unit-weight planes whose
  // normals differ by angle t give eigenvalues 1 + cos t and 1 - cos t, a
  // ratio of about t^2 / 4, so 1e-3 treats normals within about 3.6 degrees
  // as one plane: the intersection of nearly parallel planes is far away and
  // numerically meaningless, and minimising along that direction would pull
  // the vertex out of the cell. Lindstrom (2000) uses the same relative 1e-3.
  double relative_threshold = 1e-3;
};

struct QemSolution {
  Vec3d position{0};   // in the quadric's frame, inside the cell bounds
  int rank = 0;        // eigen directions used (0 = the mean itself)
  bool clamped = false;  // the solve left the cell at every rank and was clamped
};

// Minimises v^T A v - 2 b.v + c around `mean` (which should lie in `cell`):
//   v = mean + sum over kept eigenpairs (u_i . (b - A mean)) / lambda_i u_i.
// If that point leaves the cell, the smallest kept eigenvalue is dropped and
// the solve repeated (down to rank 0, the mean); the result is finally
// clamped to the cell bounds, so it is never NaN, Inf or outside `cell`.
// A non-finite input quadric yields the (clamped) mean.
QemSolution solve_representative_vertex(const Quadric& q, const Vec3d& mean, const Bbox& cell,
                                        const QemSolveConfig& config = {});

// Unit eigenvector of A for the largest eigenvalue, with its largest-magnitude
// component made positive (a deterministic orientation); +Y if A is zero or
// not finite. The fallback normal of a representative vertex whose merged
// normals cancel (e.g. both sides of a thin wall).
Vec3d dominant_normal(const Quadric& q);

}  // namespace raylod
