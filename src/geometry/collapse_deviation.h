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
// Nor folds: sheets facing opposite ways, such as a knife edge (two faces
// meeting at a 0-degree dihedral) or a plate thinner than the cell. Solved
// as one plane (rank 1), the representative lies anywhere along it (at the
// mean of the cell's corners), so the fold's edge moves inwards by up to the
// cell's size while the quadric reports no deviation across it. `folded`
// says so, and the cut treats such a cell as it treats a rim. The test,
// from the sums the store keeps: with A = sum w n n^T, its largest eigenpair
// (lambda, e) and s = sum w n, normals all on one side of the plane (n.e >=
// 0) give s.e = sum w (n.e) >= sum w (n.e)^2 = lambda, since |n.e| <= 1; so
// |s.e| < lambda means that some of the cell's area faces the other way.
// Where s sums the faces' own normals (a mesh without normals:
// NodeNormals::Faces) the inequality is exact and any such area counts,
// however small (the underside of a knife edge on ABC's abc5.stl, 5% of its
// cell's area, hid in the margin that follows). Smooth input normals
// (summed in s, where A has the face normals) need a margin of 10% of
// lambda, so that a one-sided patch is not flagged.
//
// With two or three directions solved, opposite sheets that meet at one
// exact edge (a wedge) put the representative on that edge. A sheet that
// curls away from the edge (a groove leaving a face tangentially, as at the
// concave end of abc5.stl's plate) pins it only weakly across the edge: the
// least-squares point lies inside the edge by far more than the quadric's
// deviation (a groove of radius 2 over 0.3 rad: 0.23 against 0.017), by
// about sqrt(12 Q(v) / lambda_w) along the weakest direction solved,
// lambda_w (an arc of radius R over a small turn T, uniformly weighted:
// 3RT/8 against 0.335 RT; 0.8 to 1.1 times it over the arcs and facet
// counts tried). Twice that is taken into `position` for such cells.
#pragma once

#include <span>

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
  // The normal error at a triangle's far end: a triangle that crosses the
  // cell and runs on far beyond it (a long strip of a cylinder's
  // tessellation) interpolates the representative's normal, the mean of the
  // cell's, over its whole length, where near the cell the interpolated
  // normal follows the surface (`normal`). The mean is off the normal the
  // corner had by up to the spread of the cell's normals: from the mean
  // resultant length r, a cap's half-angle 2 sqrt(1 - r); across a crease,
  // whose sides keep their own normals, the curvature across the cell,
  // 8 position / side (kappa s on a sphere); the smaller of the two.
  double far_normal = 0;  // radians
  Vec3d representative{0};  // where the collapse puts the cell's vertex (the cell's frame)
};

// What NodeRecord::normal_sum sums: the faces' own normals (a store built
// from a mesh without normals) or the input's vertex normals.
enum class NodeNormals { Faces, Input };
inline NodeNormals node_normals_of(const StoreHeader& header) {
  return header.has_normals ? NodeNormals::Input : NodeNormals::Faces;
}

// The half-angle of the spherical cap the node's normals spread over, from
// their mean resultant length r (above): 2 sqrt(1 - r) (at most 2), without
// solving the quadric. Over the cell's side it estimates the surface's
// curvature; across a crease it grows with the crease's angle instead
// (weighted by the sides' areas: a 90-degree crease gives 1.01 with areas 4
// and 2, 1.08 with equal ones), not with any curvature. 0 for an empty node.
double normal_spread_angle(const NodeRecord& node);

// `cell` in the quadric's frame (relative to StoreHeader::origin for store
// nodes); side = the cell's edge length.
CollapseDeviation collapse_deviation(const NodeRecord& node, const Bbox& cell, NodeNormals normals,
                                     const QemSolveConfig& config = {});

// The cell's quadric weighs its triangles by area, so where a few large
// triangles cross the cell (the fan of slivers that tessellates a flat CAD
// face) they outweigh many small ones that the collapse moves far (a small
// round beside that face, which the representative, held to the face's
// plane, flattens): the RMS distance hides them. The cell's descendants
// weigh only what lies in them. This returns the largest RMS distance from
// `representative` (the cell's frame) of the planes of any one of
// `descendants` (nodes of the cell's subtree, same frame): a part of the
// cell whose own triangles all lie about that far from the representative.
// On a curved patch that is at most the patch's chord error (a descendant
// at the patch's edge, its planes about a sagitta away), so
// collapse_deviation's estimate there stands; on a flat face, a crease or a
// corner every descendant's planes pass through the representative (0).
double descendant_deviation(std::span<const NodeRecord> descendants, const Vec3d& representative);

}  // namespace raylod
