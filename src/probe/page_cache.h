// An LRU cache of store pages (the triangles of one page-level cell each),
// bounded by a memory budget, with a triangle BVH built per page on load.
// Thread-safe: concurrent requests for the same page load it once. What is
// cached never changes a trace's result, only how many pages it reads. Pages
// are handed out as shared_ptr, so an evicted page stays valid for the rays
// still using it; resident memory is the budget plus the pages in use
// (at most one per tracing thread).
#pragma once

#include <cstdint>
#include <future>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

#include "core/status.h"
#include "probe/bvh.h"
#include "streaming/octree_store.h"
#include "streaming/page_codec.h"

namespace raylod {

// A node of a page's triangle BVH, compact: float boxes are exact here
// because the corners are floats. Leaf: triangles [first, first + count).
struct PageNode {
  float lo[3], hi[3];
  uint32_t first = 0;  // leaf: first triangle; inner: left child (right = first + 1)
  uint32_t count = 0;  // 0 for an inner node
  bool leaf() const { return count > 0; }
  Bbox box() const { return Bbox{Vec3d(lo[0], lo[1], lo[2]), Vec3d(hi[0], hi[1], hi[2])}; }
};

// One loaded page, indexed as the store holds it: each page vertex once
// (object space), its normal as an octahedral code (decode_octahedral gives
// exactly the store's normals; 4 bytes instead of 12), three vertex indices
// per triangle in BVH leaf order, and the BVH over the triangles. About 30
// bytes a triangle, where a copy per corner took 56: more pages fit a
// memory limit, and fewer fresh pages are touched building them.
struct Page {
  std::vector<Vec3> positions;         // per vertex
  std::vector<uint32_t> normal_codes;  // per vertex; empty if the store has no normals
  std::vector<uint32_t> index;         // 3 per triangle, in leaf order
  std::vector<PageNode> nodes;
  size_t triangle_count() const { return index.size() / 3; }
  size_t bytes() const;
};

// What building pages needs besides the pages: the decoded page, the
// triangles' boxes, the BVH and its build arrays. Kept between pages by the
// cache (one per thread) and freed when a trace ends.
struct PageScratch {
  PageMesh mesh;
  std::vector<Bbox> boxes;
  Bvh bvh;
  BvhScratch bvh_scratch;
};

// Builds a Page (with its BVH) from a decoded page; takes over `mesh`'s
// vertex arrays (left empty) and uses `scratch`'s arrays for the rest.
Page make_page(PageMesh& mesh, PageScratch& scratch);

struct PageCacheCounters {
  uint64_t pages_read = 0;      // pages read from disk (misses that loaded)
  uint64_t bytes_read = 0;      // page bytes read from disk (encoded, page_codec.h)
  uint64_t hits = 0;            // requests served from memory (or from a load in flight)
  uint64_t misses = 0;          // requests that had to read the page
  uint64_t evictions = 0;
  uint64_t peak_bytes = 0;      // largest resident size of the cache
  uint64_t resident_bytes = 0;  // now
};

class PageCache {
 public:
  // capacity_bytes: memory budget for resident pages (at least one page is
  // always kept, whatever its size); 0 = no limit (no page is evicted).
  explicit PageCache(uint64_t capacity_bytes);

  // The page, from memory or read from the store (checksummed by the store;
  // a corrupt page is an error naming the store and the page, never traced,
  // and OctreeStore::read_page records it in STORE.corrupt for the next build).
  StatusOr<std::shared_ptr<const Page>> get(const OctreeStore& store, uint32_t page);

  PageCacheCounters counters() const;
  uint64_t capacity() const;
  uint64_t resident_bytes() const;
  // A new budget (0 = no limit), evicting least recently used pages down to
  // it; a cache that outlives one trace (a view sequence's) is resized so
  // before every trace and shrunk between them.
  void set_capacity(uint64_t capacity_bytes);
  // Drops every page (a store was reopened: its pages are another file's).
  void clear();
  // Frees what the threads kept for building pages (PageScratch), up to the
  // largest page each read: a trace calls it when it ends, so that none of it
  // stays while later stages work within the memory limit. Not while a
  // trace reads through the cache.
  void release_scratch();
  // What the threads keep for building pages now (capacities, in bytes).
  uint64_t scratch_bytes() const;

 private:
  using Key = std::pair<const OctreeStore*, uint32_t>;
  struct KeyHash {
    size_t operator()(const Key& k) const {
      return std::hash<const void*>()(k.first) ^ (size_t(k.second) * 0x9e3779b97f4a7c15ull);
    }
  };
  using Result = StatusOr<std::shared_ptr<const Page>>;
  struct Entry {
    std::shared_future<Result> loading;  // valid while the page is being read
    std::shared_ptr<const Page> page;    // set once loaded
    std::list<Key>::iterator lru;
    uint64_t bytes = 0;
  };
  void evict_locked();

  uint64_t capacity_;
  mutable std::mutex mutex_;
  std::unordered_map<Key, Entry, KeyHash> entries_;
  std::list<Key> lru_;  // most recently used first; loaded pages only
  tbb::enumerable_thread_specific<PageScratch> scratch_;
  PageCacheCounters counters_;
};

}  // namespace raylod
