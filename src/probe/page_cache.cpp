// LRU page cache (see page_cache.h).
#include "probe/page_cache.h"

#include <algorithm>

namespace raylod {

size_t Page::bytes() const {
  return sizeof(Page) + positions.capacity() * sizeof(Vec3) + normal_codes.capacity() * sizeof(uint32_t) +
         index.capacity() * sizeof(uint32_t) + nodes.capacity() * sizeof(PageNode);
}

Page make_page(PageMesh& mesh, PageScratch& scratch) {
  Page page;
  const size_t n = mesh.size();
  // With scratch kept from the page before, only the page's own arrays are
  // new memory.
  std::vector<Bbox>& boxes = scratch.boxes;
  Bvh& bvh = scratch.bvh;
  boxes.assign(n, Bbox{});
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) boxes[i].expand(mesh.positions[mesh.index[3 * i + size_t(k)]]);
  build_bvh(boxes, 8, bvh, scratch.bvh_scratch);
  // Triangles in leaf order, so that leaves index them directly.
  page.index.resize(3 * n);
  for (size_t i = 0; i < n; ++i) {
    const size_t src = bvh.order[i];
    for (int k = 0; k < 3; ++k) page.index[3 * i + size_t(k)] = mesh.index[3 * src + size_t(k)];
  }
  page.positions.swap(mesh.positions);
  if (mesh.normal_codes.size() == page.positions.size()) page.normal_codes.swap(mesh.normal_codes);
  page.positions.shrink_to_fit();  // decoded in place: capacity may exceed the count
  page.normal_codes.shrink_to_fit();
  page.nodes.resize(bvh.nodes.size());
  for (size_t i = 0; i < bvh.nodes.size(); ++i) {
    const BvhNode& b = bvh.nodes[i];
    PageNode& p = page.nodes[i];
    for (int k = 0; k < 3; ++k) {
      // Exact: the bounds are of float corners.
      p.lo[k] = float(b.box.lo[k]);
      p.hi[k] = float(b.box.hi[k]);
    }
    p.first = b.first;
    p.count = b.count;
  }
  return page;
}

PageCache::PageCache(uint64_t capacity_bytes) : capacity_(capacity_bytes ? capacity_bytes : UINT64_MAX) {}

StatusOr<std::shared_ptr<const Page>> PageCache::get(const OctreeStore& store, uint32_t index) {
  const Key key{&store, index};
  std::unique_lock lock(mutex_);
  if (auto it = entries_.find(key); it != entries_.end()) {
    ++counters_.hits;
    if (it->second.page) {
      lru_.splice(lru_.begin(), lru_, it->second.lru);
      return it->second.page;
    }
    std::shared_future<Result> pending = it->second.loading;
    lock.unlock();
    return pending.get();  // another thread is reading it
  }
  ++counters_.misses;
  std::promise<Result> promise;
  entries_[key].loading = promise.get_future().share();
  lock.unlock();

  Result result = Status::ok();
  uint64_t bytes_read = 0;
  if (index >= store.pages().size()) {
    result = Status::error("page " + std::to_string(index) + " does not exist");
  } else {
    PageScratch& scratch = scratch_.local();
    PageMesh& mesh = scratch.mesh;  // decoded; its vertices move into the page
    Status s = store.read_page(index, mesh);
    if (!s) {
      result = s;  // names the store file and the page
    } else {
      bytes_read = store.pages()[index].bytes;  // as stored (compact), not as decoded
      result = std::shared_ptr<const Page>(std::make_shared<Page>(make_page(mesh, scratch)));
    }
  }

  lock.lock();
  promise.set_value(result);
  auto it = entries_.find(key);
  if (!result) {
    entries_.erase(it);  // not cached: a later request reports the error again
    return result;
  }
  Entry& e = it->second;
  e.page = result.value();
  e.loading = {};
  e.bytes = e.page->bytes();
  lru_.push_front(key);
  e.lru = lru_.begin();
  counters_.pages_read += 1;
  counters_.bytes_read += bytes_read;
  counters_.resident_bytes += e.bytes;
  counters_.peak_bytes = std::max(counters_.peak_bytes, counters_.resident_bytes);
  evict_locked();
  return result;
}

void PageCache::evict_locked() {
  while (counters_.resident_bytes > capacity_ && lru_.size() > 1) {
    const Key victim = lru_.back();
    lru_.pop_back();
    auto it = entries_.find(victim);
    counters_.resident_bytes -= it->second.bytes;
    entries_.erase(it);
    ++counters_.evictions;
  }
}

void PageCache::release_scratch() { scratch_.clear(); }

uint64_t PageCache::scratch_bytes() const {
  uint64_t bytes = 0;
  for (const PageScratch& s : scratch_) {
    bytes += s.mesh.positions.capacity() * sizeof(Vec3) + s.mesh.normal_codes.capacity() * sizeof(uint32_t) +
             s.mesh.index.capacity() * sizeof(uint32_t) +
             s.boxes.capacity() * sizeof(Bbox) + s.bvh.bytes() +
             (s.bvh_scratch.keys.capacity() + s.bvh_scratch.sort_tmp.capacity()) * sizeof(uint32_t) +
             s.bvh_scratch.ranges.capacity() * sizeof(BvhScratch::Range);
  }
  return bytes;
}

uint64_t PageCache::capacity() const {
  std::lock_guard lock(mutex_);
  return capacity_;
}

uint64_t PageCache::resident_bytes() const {
  std::lock_guard lock(mutex_);
  return counters_.resident_bytes;
}

void PageCache::set_capacity(uint64_t capacity_bytes) {
  std::lock_guard lock(mutex_);
  capacity_ = capacity_bytes ? capacity_bytes : UINT64_MAX;
  evict_locked();
}

void PageCache::clear() {
  std::lock_guard lock(mutex_);
  // Pages being loaded stay (their loaders finish them); loaded ones go.
  for (const Key& key : lru_) {
    auto it = entries_.find(key);
    counters_.resident_bytes -= it->second.bytes;
    entries_.erase(it);
  }
  lru_.clear();
}

PageCacheCounters PageCache::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace raylod
