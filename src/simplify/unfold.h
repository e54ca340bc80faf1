// Unfolding turned-over triangles by sliding representatives (after the
// collapse, before the output is indexed).
//
// Vertex clustering places each representative at its cell's quadric
// minimum, without regard to the triangles around it; where neighbouring
// cells' representatives are so placed that a triangle spanning them faces
// against its input triangle, the surface folds over itself there: three
// layers within the collapse's deviation of each other. On an opaque part
// two-sided shading hides the turned-over triangle, but the layers shadow
// each other and the camera sees dark dots (the pump cover's close-ups
// showed 8 to 20). Refining the cell (fold passes, collapse.h) removes
// them at a third of the reduction on CAD parts.
//
// Here the corners of turned-over triangles move instead, in rounds, each
// in a fixed order (the result does not depend on the thread count):
//   * a slide: a representative moves within its cell and (to within its
//     allowance) its quadric's dominant plane to a point where every
//     triangle around it faces as its input triangle did, at least
//     kUnfoldMinHeight of its opposite edge high or, if thinner now (CAD
//     slivers), half as high as it is (alternating projections onto those
//     half-spaces);
//   * where no such point exists (on the pump cover, 9 in 10: the fold is in
//     the clustered mesh's connectivity, not in one vertex), a merge: an
//     edge of the turned-over triangle collapses, a representative onto the
//     other corner, if the edge's link is a manifold edge's (no triangle
//     doubled or faced by its reverse) and every triangle left around it is
//     then upright by the same measure. Merges remove the triangles on the
//     edge: the mesh only loses triangles.
// Only a vertex whose triangles close around it moves (not one on an open
// outline, which a move would shift). A move is made only if it moves the surface off the plane of each
// triangle around the moved vertex, as it was, by at most the vertex's
// allowance: kUnfoldDeviationFactor times the deviation the cut allowed its
// cell, sqrt(12) times its RMS distance from the cell's planes
// (collapse_deviation.h). On a smooth surface that deviation grows with the
// square of the cell's side, so 4 is what a merge of two neighbouring cells
// into one of twice the side costs; a flat cell gets kUnfoldFlatAllowance of
// its side, for rounding. A vertex may move again in a later round (at
// most kUnfoldRounds), each move judged on its own.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "core/math.h"

namespace raylod {

inline constexpr double kUnfoldMinHeight = 0.05;      // of the opposite edge's length
inline constexpr int kUnfoldRounds = 3;
inline constexpr double kUnfoldDeviationFactor = 4;   // times the cell's deviation
inline constexpr double kUnfoldFlatAllowance = 1e-4;  // of the cell's side, at least

// Where a representative may go.
struct UnfoldLimit {
  Bbox cell;                 // it stays inside (world)
  Vec3d plane_normal{0};     // unit: it moves within the plane through it across this (0: anywhere)
  double allowance = 0;      // largest move of the surface off the planes of its triangles (world)
};

struct UnfoldStats {
  uint64_t folded_before = 0;  // live triangles turned over against their (non-zero) input normal
  uint64_t folded_after = 0;   // the same count after unfolding
  uint64_t moved = 0;          // representatives slid
  uint64_t merged = 0;         // representatives merged into a neighbour
  uint64_t dropped = 0;        // triangles those merges removed
  uint64_t peak_bytes = 0;     // the working tables (proportional to the folds, not the mesh)
};

// What unfolding changed besides positions and the triangles' ids.
struct UnfoldResult {
  std::vector<uint32_t> dead;  // triangles merges removed, sorted
  // Each corner (3 t + k) a merge gave another vertex, with the vertex it
  // had before the first such merge, sorted: where its new vertex has no
  // normal within the crease angle of its face (a merge across a crease),
  // it keeps that vertex's.
  std::vector<std::pair<uint64_t, uint32_t>> renamed;
  std::vector<uint32_t> slid;  // representatives slid, sorted (a sample taken at the old position is stale)
};

// The float nearest v that lies in [lo, hi] if one within an ulp does: the
// output mesh is float, and rounding must not push a vertex out of its cell.
float float_inside(double v, double lo, double hi);

// Whether triangle (a, b, c) faces against the unit input normal `key`
// (or has no area). A zero key (an input triangle without area) faces
// nothing: unfold never counts it turned over, and only asks it to keep
// some area.
inline bool faces_against(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& key) {
  return !(glm::dot(glm::cross(b - a, c - a), key) > 0);
}

// tris: provisional vertex ids, the first rep_pos.size() being
// representatives and the rest kept vertices (kept_pos); keys: per triangle,
// its input triangle's unit normal (zero without area). Moves rep_pos[v] and
// renames triangle corners for the v that movable(v) allows (not a cell
// output as its one vertex), within limit(v) (asked only of the corners of
// turned-over triangles). Each representative slides or merges at most
// once per round; each move is judged against the surface as it stands.
UnfoldStats unfold_representatives(std::span<std::array<uint32_t, 3>> tris, std::span<const Vec3> keys,
                                   std::span<Vec3> rep_pos, std::span<const Vec3> kept_pos,
                                   const std::function<bool(uint32_t)>& movable,
                                   const std::function<UnfoldLimit(uint32_t)>& limit, UnfoldResult& out);

}  // namespace raylod
