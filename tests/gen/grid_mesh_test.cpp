// Grid pieces: counts and the exact triangles of tiny grids.
#include <map>

#include "gen/grid_mesh.h"
#include "gen_test_util.h"

namespace raylod {
namespace {

std::vector<uint32_t> all_indices(const GridPiece& g, uint64_t base = 0) {
  std::vector<uint32_t> out;
  grid_band_indices(g, base, 0, g.rows - 1, out);
  return out;
}

TEST(GridMesh, PlainGridTwoByThree) {
  // Vertices 0 1 2 / 3 4 5: two quads, each split along (k,c)-(k+1,c+1).
  const GridPiece g{2, 3, false, false, false, false};
  EXPECT_EQ(grid_vertex_count(g), 6u);
  EXPECT_EQ(grid_triangle_count(g), 4u);
  EXPECT_EQ(all_indices(g), (std::vector<uint32_t>{0, 3, 4, 0, 4, 1, 1, 4, 5, 1, 5, 2}));
  EXPECT_EQ(all_indices(g, 10), (std::vector<uint32_t>{10, 13, 14, 10, 14, 11, 11, 14, 15, 11, 15, 12}));
}

TEST(GridMesh, FlipReversesWinding) {
  const GridPiece g{2, 2, false, false, false, true};
  EXPECT_EQ(all_indices(g), (std::vector<uint32_t>{0, 3, 2, 0, 1, 3}));
}

TEST(GridMesh, PolesBecomeFans) {
  // Pole 0, row 1..3, pole 4 (cols 3, no wrap): 2 fan triangles at each end.
  const GridPiece g{3, 3, false, true, true, false};
  EXPECT_EQ(grid_vertex_count(g), 5u);
  EXPECT_EQ(grid_triangle_count(g), 4u);
  EXPECT_EQ(grid_band_triangles(g, 0), 2u);
  EXPECT_EQ(grid_band_triangles(g, 1), 2u);
  EXPECT_EQ(all_indices(g), (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 1, 4, 2, 2, 4, 3}));
}

TEST(GridMesh, WrappedGridWithPolesIsClosedAndOriented) {
  // A closed sphere-like grid: every directed edge appears exactly once and
  // its reverse exactly once (watertight, consistently oriented), V - E + F = 2.
  for (uint32_t rows : {3u, 4u, 9u}) {
    for (uint32_t cols : {3u, 5u, 16u}) {
      const GridPiece g{rows, cols, true, true, true, false};
      const auto idx = all_indices(g);
      ASSERT_EQ(idx.size() / 3, grid_triangle_count(g));
      std::map<std::pair<uint32_t, uint32_t>, int> directed;
      for (size_t t = 0; t < idx.size(); t += 3)
        for (int k = 0; k < 3; ++k) ++directed[{idx[t + k], idx[t + (k + 1) % 3]}];
      for (const auto& [e, n] : directed) {
        EXPECT_EQ(n, 1);
        EXPECT_EQ(directed.count({e.second, e.first}), 1u);
      }
      const int64_t v = int64_t(grid_vertex_count(g)), e = int64_t(directed.size() / 2), f = int64_t(idx.size() / 3);
      EXPECT_EQ(v - e + f, 2) << rows << "x" << cols;
    }
  }
}

TEST(GridMesh, BandRangesConcatenate) {
  const GridPiece g{7, 5, true, true, false, false};
  std::vector<uint32_t> pieces;
  grid_band_indices(g, 3, 0, 2, pieces);
  grid_band_indices(g, 3, 2, 5, pieces);
  grid_band_indices(g, 3, 5, 6, pieces);
  EXPECT_EQ(pieces, all_indices(g, 3));
  uint64_t sum = 0;
  for (uint32_t b = 0; b + 1 < g.rows; ++b) sum += grid_band_triangles(g, b);
  EXPECT_EQ(sum, grid_triangle_count(g));
}

}  // namespace
}  // namespace raylod
