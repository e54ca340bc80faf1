// A small bounding volume hierarchy over boxes, in double: the page-level
// index of the store tracer (one leaf per page, traversed front to back) and
// the triangle index inside each loaded page.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/math.h"

namespace raylod {

struct BvhNode {
  Bbox box;
  uint32_t first = 0;  // leaf: first index into Bvh::order; inner: index of the left child (right = first + 1)
  uint32_t count = 0;  // items in a leaf; 0 for an inner node
  bool leaf() const { return count > 0; }
};

struct Bvh {
  std::vector<BvhNode> nodes;   // nodes[0] is the root (absent if there are no items)
  std::vector<uint32_t> order;  // item indices, grouped by leaf
  bool empty() const { return nodes.empty(); }
  size_t bytes() const { return nodes.capacity() * sizeof(BvhNode) + order.capacity() * sizeof(uint32_t); }
};

// The build's working arrays, for a caller that builds many BVHs in a row
// (the probe, one per page it reads) and keeps them between builds: fresh
// arrays each time cost a page fault per 4 KiB.
struct BvhScratch {
  struct Range { uint32_t begin, end; };
  std::vector<uint32_t> keys, sort_tmp;
  std::vector<Range> ranges;
};

// A linear BVH: items sorted along a Morton curve of their centres, ranges
// halved down to leaf_size items per leaf. Deterministic for a given input.
Bvh build_bvh(std::span<const Bbox> boxes, uint32_t leaf_size = 4);
// The same into `out` with `scratch`, reusing their arrays' capacity.
void build_bvh(std::span<const Bbox> boxes, uint32_t leaf_size, Bvh& out, BvhScratch& scratch);

// Per-ray constants for the slab test.
struct RayBoxPrecomp {
  Vec3d origin{0};
  Vec3d inv_dir{0};
  // Axes the ray runs parallel to (a zero direction component): the slab
  // holds the whole ray or none of it, whichever side of it the origin is,
  // a face's plane included.
  bool parallel[3] = {false, false, false};
};
RayBoxPrecomp ray_box_precomp(const Vec3d& origin, const Vec3d& direction);

// Slab test: true if the ray enters box within [tmin, tmax]; tnear is the entry distance (>= tmin).
bool intersect_box(const Bbox& box, const RayBoxPrecomp& r, double tmin, double tmax, double& tnear);

}  // namespace raylod
