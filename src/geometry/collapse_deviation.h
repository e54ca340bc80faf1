// How far collapsing one octree cell to its representative vertex moves the
// surface, bounded from the cell's quadric alone (no triangle is read): the
// deviation-bounded cut (probe.h) compares it with the footprint of the rays
// that see the cell.
//
// Position. The quadric Q = sum_i w_i (n_i . v - d_i)^2 over the planes of
// the cell's triangles (weights: area) at the representative v = argmin Q
// gives the area-weighted RMS distance e = sqrt(Q(v) / W), W = trace(A) = the
// total weight. On a spherical patch (tangent planes, area uniform in the
// cosine of the polar angle) e = sagitta / sqrt(12) exactly to first order,
// so position = sqrt(12) e is the chord error of the patch: the largest
// distance between the collapsed surface and the input, on curved regions.
// Flat regions (one plane) and creases and corners (two or three planes the
// representative lies on) give 0: they collapse without moving the surface,
// and their crease-split normals (crease_normals.h) keep them sharp.
//
// Normal. A collapse keeps each side's mean normal at the representative and
// interpolates across the larger triangles; on a sphere the interpolated
// normal on a chord is exactly the normal of the point above it, so the error
// at a hit is the curvature times how far the hit moved along the surface:
// kappa * position (times tan of the incidence angle, taken as 1). Two
// estimates of it, and the smaller is used:
//   - from the cell's side s, if the patch fits the cell: on the sphere
//     kappa = 8 sagitta / s^2, so 8 (position / s)^2; too large when the
//     cell's triangles reach far outside it (cells smaller than the input's
//     triangles);
//   - from the spread of the cell's normals: with the mean resultant length
//     r = |area-weighted normal sum| / area, a spherical cap of half-angle a
//     has 1 - r = a^2 / 4 and kappa * sagitta = a^2 / 2 = 2 (1 - r); too
//     large at creases, where the spread is not curvature (and where the
//     first estimate is 0).
// A mirror turns a tilt t into a 2t turn of the reflected ray, glass its
// transmitted ray by Refraction::tilt_gain * t (probe.h weighs each turn as
// the renderer weighs the ray and compares it with ||dD||).
//
// Not seen by a quadric: open boundaries (a hole's rim in a flat plate has
// one plane and deviation 0). The store flags the cells that hold a rim
// vertex (OctreeStore::touches_boundary), and the cut lets such a cell
// collapse only while the whole cell is within the tolerance (probe.h).
//
// Nor folds: sheets facing opposite ways that the solve takes for one plane
// (rank 1), such as a knife edge (two faces meeting at a 0-degree dihedral)
// or a plate thinner than the cell. The representative then lies anywhere
// along that plane (at the mean of the cell's corners), so the fold's edge
// moves inwards by up to the cell's size while the quadric reports no
// deviation across it. `folded` says so, and the cut treats such a cell as
// it treats a rim. The test, from the sums the store keeps: with A = sum w n
// n^T, its largest eigenpair (lambda, e) and s = sum w n, normals all on
// one side of the plane (n.e >= 0) give s.e = sum w (n.e) >= sum w (n.e)^2 =
// lambda, since |n.e| <= 1; so |s.e| < lambda means that some of the cell's
// area faces the other way. A margin of 10% of lambda keeps smooth input
// normals (summed in s, where A has the face normals) from flagging a
// one-sided patch.
#pragma once

#include "core/math.h"
#include "geometry/qem_solve.h"
#include "streaming/octree_store.h"

namespace raylod {

struct CollapseDeviation {
  double position = 0;  // same units as the cell (store units)
  double normal = 0;    // radians
  bool folded = false;  // opposite-facing sheets solved as one plane (above)
  // Sheets meeting at a crease or corner that the solve puts the
  // representative on exactly (no deviation), while the cell's normals spread
  // (from_spread over 0.05 rad, ten times the curvature estimate).
  bool crease = false;
};

// `cell` in the quadric's frame (relative to StoreHeader::origin for store
// nodes); side = the cell's edge length.
CollapseDeviation collapse_deviation(const NodeRecord& node, const Bbox& cell, const QemSolveConfig& config = {});

}  // namespace raylod
