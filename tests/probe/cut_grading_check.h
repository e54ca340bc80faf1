// Brute-force checks of a cut's grading (cut_balance.h), shared by the
// balance tests and the probe tests.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <vector>

#include "streaming/octree_store.h"

namespace raylod::test {

// Whether the closed boxes of two cells touch (at a face, an edge or a
// corner, or overlap), in units of the level-Q cells.
inline bool cells_touch(const CellKey& a, const CellKey& b, int Q) {
  uint32_t p[2][3];
  morton_decode(a.code, p[0][0], p[0][1], p[0][2]);
  morton_decode(b.code, p[1][0], p[1][1], p[1][2]);
  const int64_t sa = int64_t(1) << (Q - int(a.level)), sb = int64_t(1) << (Q - int(b.level));
  for (int k = 0; k < 3; ++k) {
    const int64_t alo = p[0][k] * sa, ahi = alo + sa, blo = p[1][k] * sb, bhi = blo + sb;
    if (alo > bhi || blo > ahi) return false;
  }
  return true;
}

// The pairs of cells that touch and whose levels differ by more than one:
// brute force over all pairs. Q: the finest level among them, or deeper.
inline size_t ungraded_pairs(const std::vector<CellKey>& cells, int Q) {
  size_t bad = 0;
  for (size_t a = 0; a < cells.size(); ++a)
    for (size_t b = a + 1; b < cells.size(); ++b)
      bad += std::abs(int(cells[a].level) - int(cells[b].level)) > 1 && cells_touch(cells[a], cells[b], Q);
  return bad;
}

}  // namespace raylod::test
