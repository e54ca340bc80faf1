#include "probe/cut_balance.h"

#include <algorithm>

namespace raylod {

namespace {

// Index of `code` among the sorted codes, or -1.
int64_t find_code(const std::vector<uint64_t>& codes, uint64_t code) {
  auto it = std::lower_bound(codes.begin(), codes.end(), code);
  return it != codes.end() && *it == code ? int64_t(it - codes.begin()) : -1;
}

struct Cell {
  int level;
  uint64_t code;
};

}  // namespace

uint64_t balance_cut(const std::vector<std::vector<uint64_t>>& codes, std::vector<std::vector<char>>& collapsed) {
  const int Q = int(codes.size()) - 1;
  if (Q < 2) return 0;
  // Collapsed flags are closed downwards (a collapsed node's descendants are
  // collapsed), and splitting keeps them so. So a cell of level L touches a
  // cut cell two or more levels coarser exactly when, for one of its 26
  // neighbours at level L, the deepest node at level L - 2 or above that
  // holds it is collapsed (a node missing below it is empty space inside
  // that cut cell's box).
  std::vector<Cell> work;
  for (const CellKey& k : cut_cells(codes, collapsed)) work.push_back({int(k.level), k.code});
  uint64_t splits = 0;
  while (!work.empty()) {
    const Cell c = work.back();
    work.pop_back();
    const int L = c.level;
    const int g = L - 2;  // a neighbour region collapsed at this level or above is too coarse
    if (g < 0) continue;
    uint32_t x, y, z;
    morton_decode(c.code, x, y, z);
    const int64_t side = int64_t(1) << L;
    const uint64_t own = c.code >> (3 * (L - g));  // not collapsed: c is a cut cell
    // The 26 neighbours' ancestors at level g: at most 8 distinct, mostly `own`.
    uint64_t seen[27];
    int nseen = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int64_t nx = int64_t(x) + dx, ny = int64_t(y) + dy, nz = int64_t(z) + dz;
          if (nx < 0 || ny < 0 || nz < 0 || nx >= side || ny >= side || nz >= side) continue;
          const uint64_t a = morton_encode(uint32_t(nx), uint32_t(ny), uint32_t(nz)) >> (3 * (L - g));
          if (a == own || std::find(seen, seen + nseen, a) != seen + nseen) continue;
          seen[nseen++] = a;
          for (;;) {
            // The deepest node holding the region at level g or above: its
            // cut cell's box reaches the neighbour if it is collapsed.
            int t = g;
            int64_t index = -1;
            for (; t >= 0; --t)
              if ((index = find_code(codes[size_t(t)], a >> (3 * (g - t)))) >= 0) break;
            if (t < 0 || !collapsed[size_t(t)][size_t(index)]) break;
            // Split the cut cell above it (its children become cut cells),
            // until no cell that coarse covers the region.
            while (t > 0) {
              const int64_t parent = find_code(codes[size_t(t) - 1], codes[size_t(t)][size_t(index)] >> 3);
              if (parent < 0 || !collapsed[size_t(t) - 1][size_t(parent)]) break;
              --t;
              index = parent;
            }
            collapsed[size_t(t)][size_t(index)] = 0;
            ++splits;
            const uint64_t top = codes[size_t(t)][size_t(index)];
            const std::vector<uint64_t>& next = codes[size_t(t) + 1];
            for (auto it = std::lower_bound(next.begin(), next.end(), top << 3); it != next.end() && (*it >> 3) == top; ++it)
              work.push_back({t + 1, *it});
          }
        }
  }
  return splits;
}

std::vector<char> flagged_parents(const std::vector<uint64_t>& codes, const std::vector<uint64_t>& parents,
                                  const std::vector<char>& parent_flags) {
  std::vector<char> flagged(codes.size(), 0);
  size_t j = 0;  // parents walked alongside (both sorted)
  for (size_t i = 0; i < codes.size(); ++i) {
    while (j < parents.size() && parents[j] < (codes[i] >> 3)) ++j;
    flagged[i] = j < parents.size() && parents[j] == (codes[i] >> 3) && parent_flags[j];
  }
  return flagged;
}

std::vector<CellKey> cut_cells(const std::vector<std::vector<uint64_t>>& codes,
                               const std::vector<std::vector<char>>& collapsed) {
  std::vector<CellKey> cells;
  for (size_t L = 0; L < codes.size(); ++L) {
    const std::vector<char> inside =
        L > 0 ? flagged_parents(codes[L], codes[L - 1], collapsed[L - 1]) : std::vector<char>(codes[L].size(), 0);
    for (size_t i = 0; i < codes[L].size(); ++i)
      if (collapsed[L][i] && !inside[i]) cells.push_back(CellKey{uint32_t(L), codes[L][i]});
  }
  return cells;
}

}  // namespace raylod
