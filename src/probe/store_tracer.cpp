// Front-to-back page traversal and the watertight triangle test; see
// store_tracer.h.
#include "probe/store_tracer.h"

#include "streaming/page_codec.h"

#include <algorithm>
#include <cmath>
#include <queue>

namespace raylod {

namespace {

// Per-ray constants of the watertight test: the axis permutation that makes
// the direction's largest component z, and the shear that maps it to +z.
struct WatertightRay {
  int kx, ky, kz;
  double sx, sy, sz;
};

WatertightRay watertight_precomp(const Vec3d& d) {
  WatertightRay w;
  const Vec3d a = glm::abs(d);
  w.kz = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
  w.kx = (w.kz + 1) % 3;
  w.ky = (w.kx + 1) % 3;
  if (d[w.kz] < 0) std::swap(w.kx, w.ky);  // keep the winding
  w.sx = d[w.kx] / d[w.kz];
  w.sy = d[w.ky] / d[w.kz];
  w.sz = 1.0 / d[w.kz];
  return w;
}

bool watertight(const WatertightRay& w, const Vec3d& o, const Vec3d& pa, const Vec3d& pb, const Vec3d& pc,
                double tmin, double tmax, double& t, double& b1, double& b2) {
  const Vec3d A = pa - o, B = pb - o, C = pc - o;
  const double ax = A[w.kx] - w.sx * A[w.kz], ay = A[w.ky] - w.sy * A[w.kz];
  const double bx = B[w.kx] - w.sx * B[w.kz], by = B[w.ky] - w.sy * B[w.kz];
  const double cx = C[w.kx] - w.sx * C[w.kz], cy = C[w.ky] - w.sy * C[w.kz];
  double u = cx * by - cy * bx;
  double v = ax * cy - ay * cx;
  double ww = bx * ay - by * ax;
  if (u == 0 || v == 0 || ww == 0) {
    // Edge cases: recompute in long double so that the signs on a shared
    // edge are consistent between the two triangles (Woop et al., sec. 3).
    using L = long double;
    u = double(L(cx) * L(by) - L(cy) * L(bx));
    v = double(L(ax) * L(cy) - L(ay) * L(cx));
    ww = double(L(bx) * L(ay) - L(by) * L(ax));
  }
  if ((u < 0 || v < 0 || ww < 0) && (u > 0 || v > 0 || ww > 0)) return false;
  const double det = u + v + ww;
  if (det == 0) return false;  // ray in the triangle's plane, or a degenerate triangle
  const double az = w.sz * A[w.kz], bz = w.sz * B[w.kz], cz = w.sz * C[w.kz];
  const double tt = u * az + v * bz + ww * cz;
  const double inv = 1.0 / det;
  t = tt * inv;
  if (!(t > tmin && t < tmax)) return false;
  b1 = v * inv;   // weight of b
  b2 = ww * inv;  // weight of c
  return true;
}

}  // namespace

bool intersect_triangle(const Vec3d& origin, const Vec3d& direction, const Vec3d& a, const Vec3d& b, const Vec3d& c,
                        double tmin, double tmax, double& t, double& b1, double& b2) {
  return watertight(watertight_precomp(direction), origin, a, b, c, tmin, tmax, t, b1, b2);
}

StoreTracer::StoreTracer(const OctreeStore& store, PageCache& cache) : store_(store), cache_(cache) {
  const auto pages = store.pages();
  page_boxes_.reserve(pages.size());
  for (const PageInfo& p : pages) {
    Bbox b = p.bounds;
    if (!b.empty()) {
      // The bounds are of float vertices; a relative pad keeps boundary hits.
      const double pad = 1e-12 * (glm::length(b.extent()) + std::max(glm::length(b.lo), glm::length(b.hi)));
      b.lo -= Vec3d(pad);
      b.hi += Vec3d(pad);
    }
    page_boxes_.push_back(b);
    bounds_.expand(b);
  }
  page_bvh_ = build_bvh(page_boxes_, 1);
}

Status StoreTracer::intersect(const Vec3d& origin, const Vec3d& direction, double tmin, double tmax, TriangleRef skip,
                              TriangleHit& hit, TraceCounters* counters) const {
  hit = TriangleHit{};
  if (counters) ++counters->rays;
  if (page_bvh_.empty()) return {};
  const RayBoxPrecomp rb = ray_box_precomp(origin, direction);
  const WatertightRay wr = watertight_precomp(direction);
  double best = tmax;
  const Page* best_page = nullptr;
  std::shared_ptr<const Page> best_page_holder;
  uint32_t best_tri = 0;
  double best_b1 = 0, best_b2 = 0;

  // Pages front to back: a min-heap of BVH nodes by entry distance.
  using Item = std::pair<double, uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
  double t0;
  if (intersect_box(page_bvh_.nodes[0].box, rb, tmin, best, t0)) heap.push({t0, 0});
  std::vector<uint32_t> stack;
  while (!heap.empty()) {
    const auto [tnear, node_index] = heap.top();
    heap.pop();
    if (tnear > best) break;
    const BvhNode& node = page_bvh_.nodes[node_index];
    if (!node.leaf()) {
      for (uint32_t child : {node.first, node.first + 1}) {
        double tc;
        if (intersect_box(page_bvh_.nodes[child].box, rb, tmin, best, tc)) heap.push({tc, child});
      }
      continue;
    }
    for (uint32_t k = 0; k < node.count; ++k) {
      const uint32_t page_index = page_bvh_.order[node.first + k];
      double tp;
      if (!intersect_box(page_boxes_[page_index], rb, tmin, best, tp)) continue;
      auto loaded = cache_.get(store_, page_index);
      if (!loaded) return loaded.status();
      std::shared_ptr<const Page> page = std::move(loaded.value());
      if (counters) ++counters->page_visits;
      if (page->nodes.empty()) continue;
      bool improved = false;
      stack.clear();
      stack.push_back(0);
      while (!stack.empty()) {
        const PageNode& tn = page->nodes[stack.back()];
        stack.pop_back();
        double tb;
        if (!intersect_box(tn.box(), rb, tmin, best, tb)) continue;
        if (!tn.leaf()) {
          stack.push_back(tn.first + 1);
          stack.push_back(tn.first);
          continue;
        }
        for (uint32_t i = 0; i < tn.count; ++i) {
          const uint32_t tri = tn.first + i;
          if (skip.page == page_index && skip.triangle == tri) continue;
          if (counters) ++counters->triangle_tests;
          const uint32_t* vi = &page->index[3 * size_t(tri)];
          double t, b1, b2;
          if (watertight(wr, origin, Vec3d(page->positions[vi[0]]), Vec3d(page->positions[vi[1]]),
                         Vec3d(page->positions[vi[2]]), tmin, best, t, b1, b2)) {
            // Strictly nearer only: on ties (a shared edge) the first triangle
            // in the traversal order wins, which depends on the ray alone.
            best = t;
            best_tri = tri;
            best_b1 = b1;
            best_b2 = b2;
            improved = true;
          }
        }
      }
      if (improved) {
        best_page_holder = page;
        best_page = page.get();
        hit.ref = {page_index, best_tri};
      }
    }
  }
  if (!best_page) return {};
  hit.t = best;
  hit.b1 = best_b1;
  hit.b2 = best_b2;
  const uint32_t* vi = &best_page->index[3 * size_t(best_tri)];
  for (int k = 0; k < 3; ++k) hit.p[k] = Vec3d(best_page->positions[vi[k]]);
  hit.has_normals = !best_page->normal_codes.empty();
  if (hit.has_normals)
    for (int k = 0; k < 3; ++k) hit.n[k] = Vec3d(decode_octahedral(best_page->normal_codes[vi[k]]));
  return {};
}

}  // namespace raylod
