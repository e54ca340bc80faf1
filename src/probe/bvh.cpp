// Median-split BVH over boxes (see bvh.h).
#include "probe/bvh.h"

#include <algorithm>
#include <numeric>

namespace raylod {

Bvh build_bvh(std::span<const Bbox> boxes, uint32_t leaf_size) {
  Bvh bvh;
  if (boxes.empty()) return bvh;
  leaf_size = std::max<uint32_t>(1, leaf_size);
  bvh.order.resize(boxes.size());
  std::iota(bvh.order.begin(), bvh.order.end(), 0u);
  bvh.nodes.reserve(2 * boxes.size() / leaf_size + 1);
  bvh.nodes.push_back({});
  struct Task { uint32_t node, begin, end; };
  std::vector<Task> stack{{0, 0, uint32_t(boxes.size())}};
  while (!stack.empty()) {
    const Task task = stack.back();
    stack.pop_back();
    Bbox box, centroids;
    for (uint32_t i = task.begin; i < task.end; ++i) {
      box.expand(boxes[bvh.order[i]]);
      centroids.expand(boxes[bvh.order[i]].center());
    }
    bvh.nodes[task.node].box = box;
    const uint32_t n = task.end - task.begin;
    const Vec3d ext = centroids.extent();
    if (n <= leaf_size || std::max({ext.x, ext.y, ext.z}) <= 0) {
      bvh.nodes[task.node].first = task.begin;
      bvh.nodes[task.node].count = n;
      continue;
    }
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const uint32_t mid = task.begin + n / 2;
    // Ties broken by index so that the tree does not depend on the sort's internals.
    std::nth_element(bvh.order.begin() + task.begin, bvh.order.begin() + mid, bvh.order.begin() + task.end,
                     [&](uint32_t a, uint32_t b) {
                       const double ca = boxes[a].lo[axis] + boxes[a].hi[axis];
                       const double cb = boxes[b].lo[axis] + boxes[b].hi[axis];
                       return ca != cb ? ca < cb : a < b;
                     });
    const uint32_t left = uint32_t(bvh.nodes.size());
    bvh.nodes.push_back({});
    bvh.nodes.push_back({});
    bvh.nodes[task.node].first = left;
    bvh.nodes[task.node].count = 0;
    stack.push_back({left + 1, mid, task.end});
    stack.push_back({left, task.begin, mid});
  }
  return bvh;
}

RayBoxPrecomp ray_box_precomp(const Vec3d& origin, const Vec3d& direction) {
  RayBoxPrecomp r;
  r.origin = origin;
  for (int k = 0; k < 3; ++k) {
    // A zero component becomes a huge finite inverse, so 0 * inv stays 0 (no NaN).
    const double d = direction[k] != 0 ? direction[k] : 1e-300;
    r.inv_dir[k] = 1.0 / d;
    if (!std::isfinite(r.inv_dir[k])) r.inv_dir[k] = std::copysign(1e300, d);
  }
  return r;
}

bool intersect_box(const Bbox& box, const RayBoxPrecomp& r, double tmin, double tmax, double& tnear) {
  double t0 = tmin, t1 = tmax;
  for (int k = 0; k < 3; ++k) {
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
