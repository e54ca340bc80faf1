// Open boundary edges of a triangle mesh held as integer grid points (the
// store's quantised positions, page_codec.h): an edge used by exactly one
// triangle is open, the rim of a hole or of an open surface. Edges are
// matched by their end points, so two triangles that share an edge only by
// position (an STL soup, patches tessellated apart) are joined, as the
// collapse joins them. Found page by page (find_open_edges), then matched
// across pages (OpenEdgeMatcher): an edge open within its page but also
// open in one other page is interior.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <unordered_set>
#include <vector>

namespace raylod {

// Two grid points, the lexicographically smaller first.
using GridEdge = std::array<uint32_t, 6>;

struct GridEdgeHash {
  size_t operator()(const GridEdge& e) const {
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (uint32_t v : e) h = (h ^ v) * 0xff51afd7ed558ccdull, h ^= h >> 32;
    return size_t(h);
  }
};

// Reusable storage for find_open_edges (one per worker).
struct OpenEdgeScratch {
  struct Slot {
    GridEdge edge;
    uint32_t count = 0;  // 0 = empty
  };
  std::vector<Slot> table;
};

// The edges of the triangles in `corners` (9 grid coordinates per triangle)
// used by exactly one triangle, appended to `out` in first-use order.
// Degenerate edges (equal end points) are not edges.
void find_open_edges(std::span<const uint32_t> corners, OpenEdgeScratch& scratch, std::vector<GridEdge>& out);

// Matches the open edges of the pages, given in any fixed order: an edge
// that two pages report is interior. What stays is open in the whole mesh.
class OpenEdgeMatcher {
 public:
  void add(std::span<const GridEdge> page_open_edges);
  const std::unordered_set<GridEdge, GridEdgeHash>& open() const { return pending_; }
  size_t peak() const { return peak_; }  // most edges pending at once

 private:
  std::unordered_set<GridEdge, GridEdgeHash> pending_;
  size_t peak_ = 0;
};

}  // namespace raylod
