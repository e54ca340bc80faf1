// Median-split BVH over boxes (see bvh.h).
#include "probe/bvh.h"

#include <algorithm>
#include <numeric>

namespace raylod {

namespace {

// 10 bits per axis, interleaved (30-bit Morton code).
uint32_t spread_bits(uint32_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x030000ff;
  v = (v | (v << 8)) & 0x0300f00f;
  v = (v | (v << 4)) & 0x030c30c3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

// Indices 0..n-1 ordered by 30-bit key, ties by index: a stable LSD radix
// sort, 3 passes of 10 bits (the same order as sorting (key, index) pairs,
// at a fraction of the cost for the few thousand items of a page).
void sort_by_key(const std::vector<uint32_t>& keys, std::vector<uint32_t>& order, std::vector<uint32_t>& tmp) {
  const size_t n = keys.size();
  tmp.resize(n);
  order.resize(n);
  std::iota(order.begin(), order.end(), 0u);
  for (int shift = 0; shift < 30; shift += 10) {
    uint32_t count[1025] = {};
    for (uint32_t i : order) ++count[((keys[i] >> shift) & 1023) + 1];
    for (int b = 0; b < 1024; ++b) count[b + 1] += count[b];
    for (uint32_t i : order) tmp[count[(keys[i] >> shift) & 1023]++] = i;
    order.swap(tmp);
  }
}

}  // namespace

// Items are sorted once along a Morton curve of their centres and the tree
// halves index ranges of that order (a linear BVH): one O(n log n) sort and
// O(n) work after it, so that building a page's BVH costs little next to
// reading the page. Boxes are then computed bottom-up.
Bvh build_bvh(std::span<const Bbox> boxes, uint32_t leaf_size) {
  Bvh bvh;
  BvhScratch scratch;
  build_bvh(boxes, leaf_size, bvh, scratch);
  return bvh;
}

void build_bvh(std::span<const Bbox> boxes, uint32_t leaf_size, Bvh& bvh, BvhScratch& scratch) {
  bvh.nodes.clear();
  bvh.order.clear();
  if (boxes.empty()) return;
  leaf_size = std::max<uint32_t>(1, leaf_size);
  const size_t n = boxes.size();
  Bbox centres;
  for (const Bbox& b : boxes) centres.expand(b.center());
  const Vec3d lo = centres.lo, ext = centres.extent();
  const double scale = 1023.0 / std::max({ext.x, ext.y, ext.z, 1e-300});
  std::vector<uint32_t>& keys = scratch.keys;
  keys.resize(n);  // Morton codes; ties keep index order
  for (size_t i = 0; i < n; ++i) {
    const Vec3d q = (boxes[i].center() - lo) * scale;
    keys[i] = spread_bits(uint32_t(q.x)) | (spread_bits(uint32_t(q.y)) << 1) | (spread_bits(uint32_t(q.z)) << 2);
  }
  sort_by_key(keys, bvh.order, scratch.sort_tmp);

  // Top-down: split ranges in halves; children are created after parents.
  using Range = BvhScratch::Range;
  std::vector<Range>& ranges = scratch.ranges;
  ranges.clear();
  bvh.nodes.reserve(2 * n / leaf_size + 1);
  bvh.nodes.push_back({});
  ranges.push_back({0, uint32_t(n)});
  for (size_t i = 0; i < bvh.nodes.size(); ++i) {
    const Range r = ranges[i];
    const uint32_t count = r.end - r.begin;
    if (count <= leaf_size) {
      bvh.nodes[i].first = r.begin;
      bvh.nodes[i].count = count;
      continue;
    }
    const uint32_t mid = r.begin + count / 2;
    bvh.nodes[i].first = uint32_t(bvh.nodes.size());
    bvh.nodes[i].count = 0;
    bvh.nodes.push_back({});
    bvh.nodes.push_back({});
    ranges.push_back({r.begin, mid});
    ranges.push_back({mid, r.end});
  }
  // Bottom-up boxes: every child has a larger index than its parent.
  for (size_t i = bvh.nodes.size(); i-- > 0;) {
    BvhNode& node = bvh.nodes[i];
    Bbox box;
    if (node.leaf()) {
      for (uint32_t k = 0; k < node.count; ++k) box.expand(boxes[bvh.order[node.first + k]]);
    } else {
      box = bvh.nodes[node.first].box;
      box.expand(bvh.nodes[node.first + 1].box);
    }
    node.box = box;
  }
}

RayBoxPrecomp ray_box_precomp(const Vec3d& origin, const Vec3d& direction) {
  RayBoxPrecomp r;
  r.origin = origin;
  for (int k = 0; k < 3; ++k) {
    // A zero component becomes a huge finite inverse, so 0 * inv stays 0 (no NaN).
    r.parallel[k] = direction[k] == 0;
    const double d = direction[k] != 0 ? direction[k] : 1e-300;
    r.inv_dir[k] = 1.0 / d;
    if (!std::isfinite(r.inv_dir[k])) r.inv_dir[k] = std::copysign(1e300, d);
  }
  return r;
}

bool intersect_box(const Bbox& box, const RayBoxPrecomp& r, double tmin, double tmax, double& tnear) {
  double t0 = tmin, t1 = tmax;
  for (int k = 0; k < 3; ++k) {
    // Parallel to the slab: as the huge inverse would have it, except in the
    // plane of the hi face, where (hi - o) * inv = 0 read as leaving at t = 0.
    if (r.parallel[k]) {
      if (r.origin[k] < box.lo[k] || r.origin[k] > box.hi[k]) return false;
      continue;
    }
    double a = (box.lo[k] - r.origin[k]) * r.inv_dir[k];
    double b = (box.hi[k] - r.origin[k]) * r.inv_dir[k];
    if (a > b) std::swap(a, b);
    b *= 1.0 + 1e-15;  // rounding guard (Ize, "Robust BVH ray traversal", JCGT 2013)
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  tnear = t0;
  return t0 <= t1;
}

}  // namespace raylod
