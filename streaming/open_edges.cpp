// Open boundary edges by counting (see open_edges.h).
#include "streaming/open_edges.h"

#include <algorithm>
#include <bit>

namespace raylod {

void find_open_edges(std::span<const uint32_t> corners, OpenEdgeScratch& scratch, std::vector<GridEdge>& out) {
  const size_t triangles = corners.size() / 9;
  if (triangles == 0) return;
  // Open addressing, at most half full.
  const size_t size = std::bit_ceil(std::max<size_t>(16, 6 * triangles));
  scratch.table.assign(size, {});
  const GridEdgeHash hash;
  auto point = [&](size_t t, int k) { return &corners[9 * t + 3 * size_t(k)]; };
  for (size_t t = 0; t < triangles; ++t)
    for (int k = 0; k < 3; ++k) {
      const uint32_t* a = point(t, k);
      const uint32_t* b = point(t, (k + 1) % 3);
      if (std::equal(a, a + 3, b)) continue;
      if (std::lexicographical_compare(b, b + 3, a, a + 3)) std::swap(a, b);
      const GridEdge e{a[0], a[1], a[2], b[0], b[1], b[2]};
      for (size_t i = hash(e) & (size - 1);; i = (i + 1) & (size - 1)) {
        OpenEdgeScratch::Slot& s = scratch.table[i];
        if (s.count == 0) {
          s.edge = e;
          s.count = 1;
          break;
        }
        if (s.edge == e) {
          ++s.count;
          break;
        }
      }
    }
  // First-use order: scan the triangles again and report each open edge once.
  for (size_t t = 0; t < triangles; ++t)
    for (int k = 0; k < 3; ++k) {
      const uint32_t* a = point(t, k);
      const uint32_t* b = point(t, (k + 1) % 3);
      if (std::equal(a, a + 3, b)) continue;
      if (std::lexicographical_compare(b, b + 3, a, a + 3)) std::swap(a, b);
      const GridEdge e{a[0], a[1], a[2], b[0], b[1], b[2]};
      for (size_t i = hash(e) & (size - 1);; i = (i + 1) & (size - 1)) {
        OpenEdgeScratch::Slot& s = scratch.table[i];
        if (s.edge != e) continue;
        if (s.count == 1) out.push_back(e);
        s.count = 0xffffffffu;  // reported (or interior): not again
        break;
      }
    }
}

void OpenEdgeMatcher::add(std::span<const GridEdge> page_open_edges) {
  for (const GridEdge& e : page_open_edges)
    if (pending_.erase(e) == 0) pending_.insert(e);
  peak_ = std::max(peak_, pending_.size());
}

}  // namespace raylod
