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
#include <vector>

namespace raylod {

// Two grid points, the lexicographically smaller first.
using GridEdge = std::array<uint32_t, 6>;

struct GridEdgeHash {
  size_t operator()(const GridEdge& e) const {
    // Three independent multiplies (no serial chain), then a fold that
    // brings the high bits down to the low ones a power-of-two table uses.
    const uint64_t w0 = e[0] | uint64_t(e[1]) << 32, w1 = e[2] | uint64_t(e[3]) << 32, w2 = e[4] | uint64_t(e[5]) << 32;
    uint64_t h = (w0 * 0x9e3779b97f4a7c15ull) ^ (w1 * 0xc2b2ae3d27d4eb4full) ^ (w2 * 0x165667b19e3779f9ull);
    h ^= h >> 32;
    h *= 0xd6e8feb86659fd93ull;
    return size_t(h ^ (h >> 32));
  }
};

// Reusable storage for find_open_edges (one per worker).
struct OpenEdgeScratch {
  std::vector<uint32_t> slots;     // position hash table: 1 + position index, 0 = empty
  std::vector<uint32_t> position;  // vertex -> position index
  std::vector<uint32_t> points;    // 3 grid coordinates per position
  std::vector<uint32_t> neighbour; // kFan per position: the larger end of edges from it
  std::vector<uint8_t> uses;       // kFan per position: how often that edge was seen (2 = twice or more)
  std::vector<uint8_t> fan;        // per position: neighbours listed
  std::vector<std::pair<uint32_t, uint32_t>> overflow;  // edges from positions with a full list
};

// The edges of a page's triangles used by exactly one triangle, appended to
// `out` (the same order for the same input). The page is given as the page
// encoder has it (page_codec.h): `vertex_keys` holds 4 words per distinct
// corner (3 grid coordinates, then the normal code, ignored here: corners
// split at a crease are one position), `corner_vertex` 3 corners per
// triangle. Degenerate edges (equal end points) are not edges.
void find_open_edges(std::span<const uint32_t> vertex_keys, std::span<const uint32_t> corner_vertex,
                     OpenEdgeScratch& scratch, std::vector<GridEdge>& out);

// Matches the open edges of the pages, given in any fixed order: an edge
// that two pages report is interior. What stays is open in the whole mesh
// (or used an odd number of times past two: a non-manifold edge, which is
// flagged like a rim; a T-junction's crack is open too). Pending edges take
// about 64 bytes each; the build caps them (octree_build.cpp).
class OpenEdgeMatcher {
 public:
  void add(std::span<const GridEdge> page_open_edges);
  size_t size() const { return count_; }                // edges pending
  std::vector<GridEdge> open() const;                   // the pending edges, sorted
  template <class F>
  void for_each(F&& f) const {
    for (const GridEdge& e : slots_)
      if (e != kEmpty) f(e);
  }
  size_t peak() const { return peak_; }  // most edges pending at once
  void clear() {  // and free the memory
    std::vector<GridEdge>().swap(slots_);
    count_ = 0;
  }

 private:
  // Linear probing without tombstones (an erase shifts the run after it
  // back); never a real edge: its two ends are equal.
  static constexpr GridEdge kEmpty{~0u, ~0u, ~0u, ~0u, ~0u, ~0u};
  void toggle(const GridEdge& e);
  void grow();
  std::vector<GridEdge> slots_;
  size_t count_ = 0, peak_ = 0;
};

}  // namespace raylod
