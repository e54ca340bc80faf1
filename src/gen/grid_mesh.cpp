#include "gen/grid_mesh.h"

#include <cassert>

namespace raylod {

uint64_t grid_vertex_count(const GridPiece& g) {
  const uint64_t regular = g.rows - uint32_t(g.pole_first) - uint32_t(g.pole_last);
  return regular * g.cols + uint32_t(g.pole_first) + uint32_t(g.pole_last);
}

uint32_t grid_band_triangles(const GridPiece& g, uint32_t band) {
  const uint32_t q = grid_quads_per_band(g);
  const bool fan = (band == 0 && g.pole_first) || (band + 2 == g.rows && g.pole_last);
  return fan ? q : 2 * q;
}

uint64_t grid_triangle_count(const GridPiece& g) {
  const uint64_t q = grid_quads_per_band(g);
  const uint64_t bands = g.rows - 1;
  const uint64_t fans = uint32_t(g.pole_first) + uint32_t(g.pole_last);
  return 2 * q * (bands - fans) + q * fans;
}

uint64_t grid_row_offset(const GridPiece& g, uint32_t row) {
  if (row == 0) return 0;
  const uint64_t first = g.pole_first ? 1 : g.cols;
  return first + uint64_t(row - 1) * g.cols;
}

void grid_band_indices(const GridPiece& g, uint64_t base, uint32_t band_begin, uint32_t band_end,
                       std::vector<uint32_t>& out) {
  assert(band_end <= g.rows - 1);
  const uint32_t q = grid_quads_per_band(g);
  auto emit = [&](uint64_t a, uint64_t b, uint64_t c) {
    if (g.flip) std::swap(b, c);
    out.push_back(uint32_t(base + a));
    out.push_back(uint32_t(base + b));
    out.push_back(uint32_t(base + c));
  };
  for (uint32_t band = band_begin; band < band_end; ++band) {
    const uint64_t r0 = grid_row_offset(g, band), r1 = grid_row_offset(g, band + 1);
    const bool top_pole = band == 0 && g.pole_first;
    const bool bottom_pole = band + 2 == g.rows && g.pole_last;
    for (uint32_t c = 0; c < q; ++c) {
      const uint32_t c1 = c + 1 == g.cols ? 0 : c + 1;  // wraps only when g.wrap
      // Quad (k,c) (k,c1) (k+1,c1) (k+1,c): triangles (k,c)(k+1,c)(k+1,c1) and
      // (k,c)(k+1,c1)(k,c1), normal along dP/drow x dP/dcol. At a pole the two
      // vertices of the collapsed row coincide and one triangle vanishes.
      if (top_pole) {
        emit(r0, r1 + c, r1 + c1);
      } else if (bottom_pole) {
        emit(r0 + c, r1, r0 + c1);
      } else {
        emit(r0 + c, r1 + c, r1 + c1);
        emit(r0 + c, r1 + c1, r0 + c1);
      }
    }
  }
}

uint64_t GridSurface::vertex_count() const {
  uint64_t n = 0;
  for (const auto& g : pieces()) n += grid_vertex_count(g);
  return n;
}

uint64_t GridSurface::triangle_count() const {
  uint64_t n = 0;
  for (const auto& g : pieces()) n += grid_triangle_count(g);
  return n;
}

}  // namespace raylod
