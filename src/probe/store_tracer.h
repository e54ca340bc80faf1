// Ray intersection against the full-resolution triangles of an OctreeStore
// (method step A2 at out-of-core scale). Pages are visited front to back
// through a BVH over the pages' bounding boxes; a page is read through the
// PageCache only when the ray reaches its box before the nearest hit so far.
// Triangles are intersected with the watertight test of Woop, Benthin and
// Wald (JCGT 2013) in double, so rays through shared edges and vertices do
// not slip through, whatever the coordinates' magnitude.
#pragma once

#include <array>
#include <cstdint>
#include <limits>

#include "core/status.h"
#include "probe/bvh.h"
#include "probe/page_cache.h"
#include "streaming/octree_store.h"

namespace raylod {

// A triangle of the store: page index and index inside the page.
struct TriangleRef {
  uint32_t page = UINT32_MAX;
  uint32_t triangle = 0;
  bool valid() const { return page != UINT32_MAX; }
  bool operator==(const TriangleRef&) const = default;
};

struct TriangleHit {
  double t = std::numeric_limits<double>::infinity();  // in units of the ray's direction
  TriangleRef ref;
  double b1 = 0, b2 = 0;           // barycentric weights of corners 1 and 2
  std::array<Vec3d, 3> p{};        // the triangle's corners (store coordinates)
  std::array<Vec3d, 3> n{};        // its vertex normals, if has_normals
  bool has_normals = false;
  bool found() const { return ref.valid(); }
};

struct TraceCounters {
  uint64_t rays = 0;
  uint64_t page_visits = 0;       // pages whose triangles were tested
  uint64_t triangle_tests = 0;
};

// The watertight ray/triangle test (Woop et al. 2013) in double. On a hit in
// (tmin, tmax) returns true with t and the barycentrics of b and c.
bool intersect_triangle(const Vec3d& origin, const Vec3d& direction, const Vec3d& a, const Vec3d& b, const Vec3d& c,
                        double tmin, double tmax, double& t, double& b1, double& b2);

class StoreTracer {
 public:
  StoreTracer(const OctreeStore& store, PageCache& cache);

  // Nearest hit of origin + t * direction for t in (tmin, tmax), skipping the
  // triangle `skip` (the one a secondary ray leaves from). direction need not
  // be unit length. Fails only if a page cannot be read (corrupt store).
  Status intersect(const Vec3d& origin, const Vec3d& direction, double tmin, double tmax, TriangleRef skip,
                   TriangleHit& hit, TraceCounters* counters = nullptr) const;

  const OctreeStore& store() const { return store_; }
  // Bounds of all pages (store coordinates).
  const Bbox& bounds() const { return bounds_; }

 private:
  const OctreeStore& store_;
  PageCache& cache_;
  std::vector<Bbox> page_boxes_;
  Bvh page_bvh_;
  Bbox bounds_;
};

}  // namespace raylod
