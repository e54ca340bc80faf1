// Indexed meshes made of parametric grids, the shape of every CAD
// tessellation `raylod gen` writes: a Bezier patch sampled on a (u, v) grid,
// a surface of revolution sampled on (profile, angle).
//
// A GridPiece is a row-major grid of vertices. Its first and/or last row may
// collapse to a single "pole" vertex (the degenerate edge of a Bezier patch,
// the axis point of a surface of revolution); the ring of quads next to a pole
// becomes a fan of triangles, so no zero-area triangle is ever emitted.
// Columns may wrap (the last column joins the first), which closes a surface of
// revolution without a seam. Pieces are laid out one after another in the
// vertex array; nothing is shared between pieces (seams between Bezier patches
// are duplicated vertices whose positions are bitwise equal, see
// bezier_teapot.h).
//
// Winding: a quad between vertex rows k, k+1 and columns c, c+1 is split along
// its (k, c)-(k+1, c+1) diagonal into triangles whose geometric normal is
// dP/drow x dP/dcol; GridPiece::flip reverses both triangles. Evaluators must
// return vertex normals on the same side (outward for closed shapes).
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "core/math.h"

namespace raylod {

struct GridPiece {
  uint32_t rows = 0;         // vertex rows, poles included (>= 2; >= 3 with two poles)
  uint32_t cols = 0;         // vertices per regular row (>= 2; >= 3 if wrap)
  bool wrap = false;         // column cols-1 connects back to column 0
  bool pole_first = false;   // row 0 is a single vertex
  bool pole_last = false;    // row rows-1 is a single vertex
  bool flip = false;         // reverse the winding of every triangle
};

// Vertices in vertex row `row` of `piece` (1 for a pole row).
inline uint32_t grid_row_vertices(const GridPiece& g, uint32_t row) {
  return (row == 0 && g.pole_first) || (row + 1 == g.rows && g.pole_last) ? 1u : g.cols;
}
uint64_t grid_vertex_count(const GridPiece& g);
// Quads (or fan triangles) around one band between two consecutive rows.
inline uint32_t grid_quads_per_band(const GridPiece& g) { return g.wrap ? g.cols : g.cols - 1; }
// Triangles in band `band` (between vertex rows band and band+1).
uint32_t grid_band_triangles(const GridPiece& g, uint32_t band);
uint64_t grid_triangle_count(const GridPiece& g);
// Index of the first vertex of vertex row `row` within the piece.
uint64_t grid_row_offset(const GridPiece& g, uint32_t row);

// Appends the triangles of bands [band_begin, band_end) as 3 vertex indices
// each, offset by `base` (the index of the piece's first vertex in the mesh).
void grid_band_indices(const GridPiece& g, uint64_t base, uint32_t band_begin, uint32_t band_end,
                       std::vector<uint32_t>& out);

// A mesh of grid pieces whose vertices can be evaluated one row at a time, in
// any order and from any thread (eval_row must be const and thread-safe).
class GridSurface {
 public:
  virtual ~GridSurface() = default;
  virtual const std::vector<GridPiece>& pieces() const = 0;
  // Writes the grid_row_vertices(piece, row) positions and unit normals of one
  // vertex row. The result depends only on (piece, row): never on the caller's
  // threading, so output files are byte-identical whatever the thread count.
  virtual void eval_row(size_t piece, uint32_t row, std::span<Vec3> positions, std::span<Vec3> normals) const = 0;

  uint64_t vertex_count() const;
  uint64_t triangle_count() const;
};

// Picks a tessellation resolution from candidates that each carry `err`
// (|triangles - target|) and `aspect` (|log| of the parameter cells' aspect
// ratio): the squarest among those within 0.05% of the target (or of the
// closest count, if none is that close), since near-square parameter cells
// give better-shaped triangles. candidates must not be empty.
template <class Candidate>
const Candidate& pick_squarest_resolution(const std::vector<Candidate>& candidates, uint64_t target) {
  double min_err = 1e300;
  for (const auto& k : candidates) min_err = std::min(min_err, k.err);
  const double tolerance = std::max(min_err, 5e-4 * double(target));
  const Candidate* best = nullptr;
  for (const auto& k : candidates)
    if (k.err <= tolerance && (!best || k.aspect < best->aspect || (k.aspect == best->aspect && k.err < best->err)))
      best = &k;
  return *best;
}

}  // namespace raylod
