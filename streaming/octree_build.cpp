// `raylod build` core: streams a mesh into the disk-backed octree store
// (method step A1 at out-of-core scale; quadrics after Lindstrom, "Out-of-core
// simplification of large polygonal models", SIGGRAPH 2000, METHOD.md eq. 4;
// cells after Luebke and Erikson, SIGGRAPH 1997).
//
// Pass 1 streams the mesh for its bounds, its triangle count and a bounded,
// deterministic sample of triangles. From the sample the plan estimates the
// occupied cells per level and picks
//   - quadric_depth: the deepest level (<= --max-depth) whose node table fits
//     in half of what --memory-limit leaves after the reader's vertex table
//     and the batches in flight (a quarter goes to the run buffer), and whose
//     parent level still has fewer nodes than half the vertices (deeper
//     levels hold single vertices and cluster nothing), and
//   - page_level: the deepest level whose occupied cells still hold about
//     page_triangles (default 4096) triangles on average, so a page is a
//     few hundred KiB: large enough for sequential reads, small enough that a
//     probe touching a region reads little else. It is independent of
//     quadric_depth (usually shallower).
// Pass 2 streams the mesh again. Batches are processed in parallel: each
// corner of each triangle adds the triangle's plane quadric (unit normal = the
// normalised average of the three vertex normals where the file has them, else
// the face normal; weight = area / 3 per corner, so a triangle whose corners
// share a cell adds its area once and the quadric does not depend on
// tessellation density) to the cell of that vertex at quadric_depth, into a
// batch-local table in corner order. Batch tables are merged into the global
// table in batch order, so every floating-point sum has the same order for any
// thread count. If the global table would outgrow its budget (the estimate was
// low) it is coarsened by one level, which is exact: a parent's quadric is the
// sum of its children's. Triangles are appended to a run buffer; a full
// buffer is counting-sorted by page and written as one run to an unlinked
// temporary file. Finally every page is assembled from its segments in the
// runs (in input order), checksummed and written, followed by the node table
// (levels above quadric_depth by summing children), the page table and the
// header; the file is fsynced and renamed into place (AtomicOutput).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <tuple>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <deque>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>

#include <tbb/concurrent_queue.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/info.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>

#include "core/progress.h"
#include "core/fault_point.h"
#include "core/memory_budget.h"
#include "core/ordered_pipeline.h"
#include "core/parallelism.h"
#include "core/system.h"
#include "streaming/octree_format.h"
#include "streaming/octree_store.h"
#include "streaming/open_edges.h"
#include "streaming/page_codec.h"

namespace raylod {
namespace {

using namespace store_format;

// Bytes of memory one leaf node costs while building: the record, its hash
// slot(s) with growth slack, and its share of the parent levels (1/3 on
// surfaces) built at the end.
constexpr uint64_t kBytesPerLeafNode = 192;
constexpr uint64_t kSampleTriangles = 1 << 17;

// Inline here: the merge is the build's hottest loop.
inline void add_quadric(Quadric& q, const Quadric& r) {
  q.a00 += r.a00; q.a01 += r.a01; q.a02 += r.a02;
  q.a11 += r.a11; q.a12 += r.a12; q.a22 += r.a22;
  q.b0 += r.b0; q.b1 += r.b1; q.b2 += r.b2;
  q.c += r.c;
}

void add_node(NodeRecord& a, const NodeRecord& b) {
  add_quadric(a.quadric, b.quadric);
  a.vertex_sum += b.vertex_sum;
  a.normal_sum += b.normal_sum;
  a.corner_count += b.corner_count;
}

// Open-addressing table from Morton code to a dense vector of NodeRecords
// (linear probing, slots hold index + 1, load factor <= 1/2).
class NodeTable {
 public:
  std::vector<NodeRecord> nodes;

  NodeRecord& upsert(uint64_t code) { return nodes[index(code)]; }
  // Index of the node with this code in `nodes`, inserted if new (stable).
  size_t index(uint64_t code) {
    if (2 * (nodes.size() + 1) > slots_.size()) grow();
    size_t i = slot_of(code);
    for (;;) {
      uint32_t s = slots_[i];
      if (s == 0) {
        slots_[i] = uint32_t(nodes.size() + 1);
        nodes.push_back(NodeRecord{});
        nodes.back().code = code;
        return nodes.size() - 1;
      }
      if (nodes[s - 1].code == code) return s - 1;
      i = (i + 1) & mask_;
    }
  }
  void clear() {
    nodes.clear();
    std::fill(slots_.begin(), slots_.end(), 0u);
  }
  void release_index() { std::vector<uint32_t>().swap(slots_); mask_ = 0; }
  // Replaces every code by its parent's, merging siblings (in code order).
  void coarsen() {
    std::sort(nodes.begin(), nodes.end(), [](const NodeRecord& a, const NodeRecord& b) { return a.code < b.code; });
    size_t out = 0;
    for (size_t i = 0; i < nodes.size(); ++i) {
      const uint64_t parent = nodes[i].code >> 3;
      if (out > 0 && nodes[out - 1].code == parent) {
        add_node(nodes[out - 1], nodes[i]);
      } else {
        nodes[out] = nodes[i];
        nodes[out].code = parent;
        ++out;
      }
    }
    nodes.resize(out);
    std::fill(slots_.begin(), slots_.end(), 0u);
    for (size_t k = 0; k < nodes.size(); ++k) {
      size_t i = slot_of(nodes[k].code);
      while (slots_[i]) i = (i + 1) & mask_;
      slots_[i] = uint32_t(k + 1);
    }
  }

 private:
  size_t slot_of(uint64_t code) const { return size_t((code * 0x9E3779B97F4A7C15ull) >> 20) & mask_; }
  void grow() {
    size_t n = std::max<size_t>(1024, 2 * slots_.size());
    slots_.assign(n, 0u);
    mask_ = n - 1;
    for (size_t k = 0; k < nodes.size(); ++k) {
      size_t i = slot_of(nodes[k].code);
      while (slots_[i]) i = (i + 1) & mask_;
      slots_[i] = uint32_t(k + 1);
    }
  }
  std::vector<uint32_t> slots_;
  size_t mask_ = 0;
};

// Morton code -> dense page id in first-seen order.
class PageIds {
 public:
  std::vector<uint64_t> codes;
  uint32_t id(uint64_t code) {
    if (2 * (codes.size() + 1) > slots_.size()) grow();
    size_t i = slot_of(code);
    for (;;) {
      uint32_t s = slots_[i];
      if (s == 0) {
        slots_[i] = uint32_t(codes.size() + 1);
        codes.push_back(code);
        return uint32_t(codes.size() - 1);
      }
      if (codes[s - 1] == code) return s - 1;
      i = (i + 1) & mask_;
    }
  }

 private:
  size_t slot_of(uint64_t code) const { return size_t((code * 0x9E3779B97F4A7C15ull) >> 20) & mask_; }
  void grow() {
    size_t n = std::max<size_t>(256, 2 * slots_.size());
    slots_.assign(n, 0u);
    mask_ = n - 1;
    for (size_t k = 0; k < codes.size(); ++k) {
      size_t i = slot_of(codes[k]);
      while (slots_[i]) i = (i + 1) & mask_;
      slots_[i] = uint32_t(k + 1);
    }
  }
  std::vector<uint32_t> slots_;
  size_t mask_ = 0;
};

// Cell coordinate along one axis. root_size is a power of two, so the
// division by the cell size is exact scaling and equals OctreeStore::cell_of.
inline uint32_t cell_coord(double v, double lo, double inv_cell, uint32_t max_coord) {
  double t = std::floor((v - lo) * inv_cell);
  return t <= 0 ? 0u : t >= double(max_coord) ? max_coord : uint32_t(t);
}

struct Grid {
  Vec3d lo{0};
  double inv_cell = 1;
  uint32_t max_coord = 0;
  Grid(const Vec3d& root_lo, double root_size, int level)
      : lo(root_lo), inv_cell(double(uint64_t(1) << level) / root_size), max_coord(uint32_t((uint64_t(1) << level) - 1)) {}
  uint64_t code(const Vec3d& p) const {
    return morton_encode(cell_coord(p.x, lo.x, inv_cell, max_coord), cell_coord(p.y, lo.y, inv_cell, max_coord),
                         cell_coord(p.z, lo.z, inv_cell, max_coord));
  }
};

// ---------------------------------------------------------------------------
// A TBB pipeline over one pass of a reader: serial read, parallel work,
// serial in-order consume. Tokens are recycled, so memory is ntokens batches.
struct TokenBase {
  TriangleBatch batch;
  uint64_t first = 0;  // global index of the batch's first triangle
  Status error;
};

template <class Token, class Work, class Consume>
Status run_pass(MeshReader& reader, size_t ntokens, Work work, Consume consume) {
  std::vector<std::unique_ptr<Token>> pool;
  tbb::concurrent_queue<Token*> free_tokens;
  for (size_t i = 0; i < ntokens; ++i) {
    pool.push_back(std::make_unique<Token>());
    free_tokens.push(pool.back().get());
  }
  std::mutex status_mutex;
  Status status;
  std::atomic<bool> failed{false};
  auto fail = [&](Status s) {
    std::lock_guard lock(status_mutex);
    if (status.is_ok()) status = std::move(s);
    failed = true;
  };
  uint64_t next_first = 0;
  bool at_end = false;
  tbb::parallel_pipeline(
      ntokens,
      tbb::make_filter<void, Token*>(tbb::filter_mode::serial_in_order,
                                     [&](tbb::flow_control& fc) -> Token* {
                                       Token* t = nullptr;
                                       if (failed || at_end) {
                                         fc.stop();
                                         return nullptr;
                                       }
                                       if (!free_tokens.try_pop(t)) {  // not expected: ntokens bound the flight
                                         pool.push_back(std::make_unique<Token>());
                                         t = pool.back().get();
                                       }
                                       auto more = reader.next(t->batch);
                                       if (!more.is_ok() || !*more) {
                                         if (!more.is_ok()) fail(more.status());
                                         at_end = true;
                                         free_tokens.push(t);
                                         fc.stop();
                                         return nullptr;
                                       }
                                       t->first = next_first;
                                       t->error = Status::ok();
                                       next_first += t->batch.size();
                                       return t;
                                     }) &
          tbb::make_filter<Token*, Token*>(tbb::filter_mode::parallel,
                                           [&](Token* t) {
                                             if (!failed) work(*t);
                                             return t;
                                           }) &
          tbb::make_filter<Token*, void>(tbb::filter_mode::serial_in_order, [&](Token* t) {
            if (!failed) {
              Status s = t->error.is_ok() ? consume(*t) : t->error;
              if (!s.is_ok()) fail(std::move(s));
            }
            free_tokens.push(t);
          }));
  return status;
}

Status check_batch(const TriangleBatch& b, bool has_normals, const std::string& name, uint64_t first) {
  if (b.positions.size() % 3 != 0) return Status::error(name + ": reader returned a partial triangle");
  if (has_normals && b.normals.size() != b.positions.size())
    return Status::error(name + ": triangles " + std::to_string(first) + "..: normals missing in a batch");
  if (!has_normals && !b.normals.empty())
    return Status::error(name + ": normals appeared in a mesh whose header declares none");
  return {};
}

// ---------------------------------------------------------------------------
// Pass 1: bounds, count, and every stride-th triangle as a sample.
struct Scan {
  Bbox bounds;
  uint64_t triangles = 0;
  bool has_normals = false;
  Vec3d mesh_origin{0};      // the reader's local origin (MeshHeader::origin)
  uint64_t vertex_hint = 0;  // declared vertex count (0 = unknown)
  uint64_t reader_bytes = 0; // what the reader may keep resident (its vertex table)
  uint64_t stride = 1;
  std::vector<Vec3> sample;  // 3 corners per sampled triangle
};

struct ScanToken : TokenBase {
  Vec3 lo, hi;
};

StatusOr<Scan> scan_pass(MeshReader& reader, size_t ntokens) {
  Scan scan;
  scan.has_normals = reader.header().has_normals;
  scan.mesh_origin = reader.header().origin;
  scan.vertex_hint = reader.header().format == MeshFormat::Stl ? 0 : reader.header().vertex_count;
  // Indexed readers keep a memory-mapped vertex table whose touched pages
  // count as resident (12 bytes per position, 12 per normal). The binary PLY
  // reader drops its mapping after every 64 MiB of face data; a bare read of
  // the 30M-triangle teapot peaks at ~190 MiB, so for it we assume 192 MiB
  // (more only for meshes whose faces jump around the vertex table). STL
  // streams whole triangles.
  scan.reader_bytes = scan.vertex_hint * (scan.has_normals ? 24 : 12);
  if (reader.header().format == MeshFormat::Ply && reader.header().encoding.rfind("binary", 0) == 0)
    scan.reader_bytes = std::min<uint64_t>(scan.reader_bytes, 192ull << 20);
  const std::string name = reader.path().string();
  Progress progress("bounds", reader.header().face_count, "triangles");
  Status s = run_pass<ScanToken>(
      reader, ntokens,
      [&](ScanToken& t) {
        t.error = check_batch(t.batch, scan.has_normals, name, t.first);
        Vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
        bool finite = true;
        for (const Vec3& p : t.batch.positions) {
          lo = glm::min(lo, p);
          hi = glm::max(hi, p);
          finite &= is_finite(p);
        }
        if (!finite && t.error.is_ok()) {
          for (size_t i = 0; i < t.batch.positions.size(); ++i)
            if (!is_finite(t.batch.positions[i])) {
              t.error = Status::error(name + ": triangle " + std::to_string(t.first + i / 3) +
                                      " has a non-finite coordinate");
              break;
            }
        }
        t.lo = lo;
        t.hi = hi;
      },
      [&](ScanToken& t) -> Status {
        const size_t n = t.batch.size();
        if (n == 0) return {};
        scan.bounds.expand(t.lo);
        scan.bounds.expand(t.hi);
        // Every stride-th triangle; when the sample is full, keep every other
        // sampled triangle and double the stride (deterministic).
        uint64_t g = (t.first + scan.stride - 1) / scan.stride * scan.stride;
        for (; g < t.first + n; g += scan.stride) {
          const Vec3* p = &t.batch.positions[3 * (g - t.first)];
          scan.sample.insert(scan.sample.end(), p, p + 3);
          if (scan.sample.size() / 3 >= 2 * kSampleTriangles) {
            size_t out = 0;
            for (size_t k = 0; k < scan.sample.size() / 3; k += 2)
              for (int c = 0; c < 3; ++c) scan.sample[out++] = scan.sample[3 * k + c];
            scan.sample.resize(out);
            scan.stride *= 2;
            g = g / scan.stride * scan.stride;  // next multiple of the new stride follows
          }
        }
        scan.triangles += n;
        progress.advance(n);
        return {};
      });
  progress.finish();
  RAYLOD_RETURN_IF_ERROR(s);
  if (scan.triangles == 0) return Status::error(name + ": empty mesh (no triangles)");
  // Every coordinate is a float, but corners at -3e38 and +3e38 are further
  // apart than a float can say: the stages after the build subtract positions
  // in float (Draco's quantisation range among them, which then crashes).
  const Vec3d ext = scan.bounds.extent();
  for (int axis = 0; axis < 3; ++axis) {
    if (ext[axis] > double(std::numeric_limits<float>::max())) {
      char what[160];
      std::snprintf(what, sizeof what, ": the mesh spans %g along %c (from %g to %g), more than the float range (about 3.4e38)",
                    ext[axis], "xyz"[axis], scan.bounds.lo[axis], scan.bounds.hi[axis]);
      return Status::error(name + what);
    }
  }
  return scan;
}

// Bytes one triangle takes as float soup (batches), and on the grid (runs:
// 3 x 3 grid coordinates, and 3 normal codes).
inline uint64_t soup_triangle_bytes(bool has_normals) { return has_normals ? 72 : 36; }
inline uint64_t run_triangle_bytes(bool has_normals) { return has_normals ? 48 : 36; }

// ---------------------------------------------------------------------------
struct Plan {
  Vec3d origin{0}, root_lo{0};
  double root_size = 1;
  int quadric_depth = 0, page_level = 0;
  uint64_t max_nodes = 0;      // leaf nodes the global table may hold
  uint64_t run_triangles = 0;  // triangles per sorted run
  uint64_t budget_bytes = 0;   // what the plan expects to be resident at most
  uint64_t memory_limit = 0;   // the build's (UINT64_MAX: none)
  uint64_t overhead = 0;       // bytes resident besides the node table and the runs
  int max_depth = 0;           // --max-depth, capped
  double vertices = 0;         // estimated distinct vertices
  PageGrid grid;               // positions are quantised on it as they are read (page_codec.h)
  std::vector<double> est_nodes;
};

// The memory plan reserves room for this many batches in flight whatever the
// thread count (fewer threads use fewer), so the store does not depend on it.
constexpr size_t kPlanTokens = 8;

// Bytes for the node table under a memory limit: half of what the limit
// leaves after `overhead`, at least a tenth of the limit.
uint64_t node_budget_for(uint64_t memory_limit, uint64_t overhead) {
  const double avail = memory_limit > overhead ? double(memory_limit - overhead) : 0.0;
  return uint64_t(std::max(0.5 * avail, 0.1 * double(memory_limit)));
}
// Leaf nodes the global table may hold under a memory limit.
uint64_t max_nodes_for(uint64_t memory_limit, uint64_t overhead) {
  return std::max<uint64_t>(64, node_budget_for(memory_limit, overhead) / kBytesPerLeafNode);
}

// The plan's quadric depth for a node cap: the deepest level whose estimated
// node table fits with a 25% margin and whose parent level still merges
// vertices (below the level where cells hold about two vertices on average,
// levels add nodes but little clustering; Luebke and Erikson stop splitting
// at a single vertex). Both conditions hold for a prefix of levels.
bool level_fits(const Plan& plan, int level, uint64_t max_nodes) {
  return plan.est_nodes[size_t(level)] * 1.25 <= double(max_nodes) &&
         plan.est_nodes[size_t(level) - 1] < 0.5 * plan.vertices;
}
int plan_depth_for(const Plan& plan, uint64_t max_nodes) {
  int depth = 0;
  for (int l = 1; l <= plan.max_depth; ++l)
    if (level_fits(plan, l, max_nodes)) depth = l;
  return depth;
}

// The smallest memory limit whose node cap reaches `nodes` (max_nodes_for is
// non-decreasing in the limit).
uint64_t limit_for_nodes(uint64_t nodes, uint64_t overhead) {
  if (max_nodes_for(1, overhead) >= nodes) return 1;
  uint64_t lo = 1, hi = uint64_t(1) << 62;
  if (max_nodes_for(hi, overhead) < nodes) return UINT64_MAX;
  while (hi - lo > 1) {
    const uint64_t mid = lo + (hi - lo) / 2;
    (max_nodes_for(mid, overhead) >= nodes ? hi : lo) = mid;
  }
  return hi;
}

// The memory limits under which a fresh build makes the same store as this
// one, built under `memory_limit` (StoreHeader::reuse_limit_lo/hi): the plan
// picks the same depth and binning never coarsens (which happens once the
// table holds max_nodes and another node arrives, so max_nodes must exceed
// the final count). A store coarsened while binning is reused only under its
// own limit.
std::pair<uint64_t, uint64_t> reuse_limits(const Plan& plan, int depth, uint64_t leaf_nodes, uint64_t memory_limit) {
  if (depth != plan.quadric_depth) return {memory_limit, memory_limit};
  uint64_t need = leaf_nodes + 1;
  if (depth > 0) need = std::max(need, uint64_t(std::ceil(plan.est_nodes[size_t(depth)] * 1.25)));
  // min: the build's own limit is inside, whatever the rounding at the edges.
  const uint64_t lo = std::min(limit_for_nodes(need, plan.overhead), memory_limit);
  uint64_t hi = UINT64_MAX;
  const int next = depth + 1;
  if (next <= plan.max_depth && plan.est_nodes[size_t(depth)] < 0.5 * plan.vertices) {
    // The next level would qualify once its estimate fits.
    const uint64_t deeper = uint64_t(std::ceil(plan.est_nodes[size_t(next)] * 1.25));
    const uint64_t at = limit_for_nodes(deeper, plan.overhead);
    hi = at == UINT64_MAX ? UINT64_MAX : std::max(at - 1, memory_limit);
  }
  return {lo, hi};
}

// Estimated occupied cells per level from sampled points: exact where the
// sample is the whole input; else trusted while cells hold >= 8 sampled
// points on average, and grown 4x per level below (surfaces), capped by the
// number of points the input has.
std::vector<double> estimate_cells(std::vector<uint64_t> codes21, bool complete, double cap) {
  std::sort(codes21.begin(), codes21.end());
  std::vector<double> est(kMaxLevel + 1, 1);
  const double s = double(codes21.size());
  for (uint32_t level = 0; level <= kMaxLevel; ++level) {
    const int shift = 3 * int(kMaxLevel - level);
    double distinct = 0;
    for (size_t i = 0; i < codes21.size(); ++i)
      if (i == 0 || (codes21[i] >> shift) != (codes21[i - 1] >> shift)) ++distinct;
    if (complete || distinct <= s / 8 || level == 0)
      est[level] = distinct;
    else
      est[level] = std::max(distinct, 4 * est[level - 1]);
    est[level] = std::min(est[level], std::max(cap, distinct));
  }
  return est;
}

Plan make_plan(const Scan& scan, const StoreOptions& options, uint64_t memory_limit) {
  Plan plan;
  plan.origin = scan.bounds.center();
  const Vec3d ext = scan.bounds.extent();
  const double extent = std::max({ext.x, ext.y, ext.z});
  // A power-of-two side makes cell sizes exact and cell lookups exact scalings.
  plan.root_size = extent > 0 ? std::exp2(std::ceil(std::log2(extent * (1 + 1e-9)))) : 1.0;
  plan.root_lo = plan.origin - Vec3d(0.5 * plan.root_size);

  const Grid grid(plan.root_lo, plan.root_size, int(kMaxLevel));
  std::vector<uint64_t> corners, centroids;
  corners.reserve(scan.sample.size());
  centroids.reserve(scan.sample.size() / 3);
  for (size_t i = 0; i + 2 < scan.sample.size(); i += 3) {
    Vec3d a(scan.sample[i]), b(scan.sample[i + 1]), c(scan.sample[i + 2]);
    corners.push_back(grid.code(a));
    corners.push_back(grid.code(b));
    corners.push_back(grid.code(c));
    centroids.push_back(grid.code((a + b + c) / 3.0));
  }
  const bool complete = scan.stride == 1;
  const double corner_cap = double(scan.vertex_hint ? std::min(scan.vertex_hint, 3 * scan.triangles) : 3 * scan.triangles);
  plan.est_nodes = estimate_cells(std::move(corners), complete, corner_cap);
  const auto est_pages = estimate_cells(std::move(centroids), complete, double(scan.triangles));

  // Memory: the reader's vertex table and the in-flight batches (each token
  // holds a batch, its local node table and page codes, ~3 batches' bytes)
  // come first; of the rest, half goes to the node table and a quarter to
  // the run buffer, leaving a margin for the allocator and the sample.
  const uint64_t token_bytes = 3 * 65536 * (soup_triangle_bytes(scan.has_normals) + 8) +
                               65536 * run_triangle_bytes(scan.has_normals);
  const uint64_t overhead = scan.reader_bytes + (48ull << 20) + kPlanTokens * token_bytes;
  const double avail = memory_limit > overhead ? double(memory_limit - overhead) : 0.0;
  const uint64_t node_budget = node_budget_for(memory_limit, overhead);
  plan.overhead = overhead;
  plan.max_nodes = max_nodes_for(memory_limit, overhead);
  plan.max_depth = std::min(options.max_depth, int(kMaxLevel));
  plan.vertices = plan.est_nodes[kMaxLevel];
  plan.quadric_depth = plan_depth_for(plan, plan.max_nodes);
  plan.grid = page_grid(plan.root_lo, plan.root_size, page_grid_bits(plan.quadric_depth));
  plan.page_level = 0;
  for (int l = 1; l <= int(kMaxLevel); ++l)
    if (double(scan.triangles) / est_pages[size_t(l)] >= double(std::max<uint32_t>(1, options.page_triangles)))
      plan.page_level = l;

  // min(max()) rather than std::clamp: above 5 GiB the lower bound passes
  // the upper one (std::clamp's precondition), and the upper one wins.
  const uint64_t run_bytes = std::min<uint64_t>(
      std::max<uint64_t>(uint64_t(0.25 * avail), std::max<uint64_t>(1 << 20, memory_limit / 20)), 256ull << 20);
  plan.run_triangles = std::max<uint64_t>(1024, run_bytes / (run_triangle_bytes(scan.has_normals) + 8));
  plan.budget_bytes = overhead + node_budget + run_bytes;
  plan.memory_limit = memory_limit;
  return plan;
}

// ---------------------------------------------------------------------------
// Sorted runs of page-grouped triangles in an unlinked temporary file. Each
// page's piece of a run (a segment) is encoded as a page (page_codec.h, about
// a quarter of the grid words' bytes), in parallel; the final page assembly
// decodes a page's segments back to grid words and encodes the whole page.
class RunFile {
 public:
  // A page's piece of one run: bytes at `offset` in block `block`.
  struct Segment {
    uint32_t block;
    uint32_t offset;
    uint32_t count;  // triangles
    uint32_t bytes;
  };

  RunFile(bool has_normals, uint64_t capacity, const PageGrid& grid)
      : normals_(has_normals), capacity_(capacity), grid_(grid) {}
  ~RunFile() {
    if (fd_ >= 0) ::close(fd_);
  }

  Status open(const std::filesystem::path& beside) {
    path_ = beside.parent_path() / temporary_stem(beside.filename().string());
    path_ += ".runs-" + std::to_string(::getpid());
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd_ < 0) return Status::error(path_.string() + ": cannot create temporary file: " + std::strerror(errno));
    ::unlink(path_.c_str());  // vanishes with the process, whatever happens
    positions_.reserve(9 * capacity_);
    if (normals_) normals_data_.reserve(3 * capacity_);
    page_of_.reserve(capacity_);
    return {};
  }

  // Appends n triangles: 9 grid coordinates each, and 3 normal codes each if
  // the mesh has normals.
  Status append(const uint32_t* positions, const uint32_t* normals, size_t n, const std::vector<uint32_t>& page_ids,
                size_t num_pages) {
    size_t done = 0;
    while (done < n) {
      size_t take = std::min<size_t>(n - done, capacity_ - page_of_.size());
      positions_.insert(positions_.end(), positions + 9 * done, positions + 9 * (done + take));
      if (normals_) normals_data_.insert(normals_data_.end(), normals + 3 * done, normals + 3 * (done + take));
      page_of_.insert(page_of_.end(), page_ids.begin() + long(done), page_ids.begin() + long(done + take));
      done += take;
      if (page_of_.size() == capacity_) RAYLOD_RETURN_IF_ERROR(flush(num_pages));
    }
    return {};
  }

  // Counting sort of the buffered triangles by page (stable: input order
  // within a page); each page's segment is encoded (in parallel) and the
  // segments are gathered in page order into 8 MiB blocks. A block stays in
  // memory while the runs held fit hold_limit (set_hold_limit), else it is
  // written to the file in one sequential write.
  Status flush(size_t num_pages) {
    const size_t n = page_of_.size();
    if (n == 0) return {};
    // The arrays below are members kept from flush to flush (and the
    // encoders' per thread): fresh ones every run were new memory each time,
    // zeroed by the kernel page by page.
    std::vector<uint32_t>& start = flush_start_;
    std::vector<uint32_t>& order = flush_order_;
    std::vector<uint32_t>& fill = flush_fill_;
    std::vector<uint32_t>& present = flush_present_;
    start.assign(num_pages + 1, 0);
    for (uint32_t p : page_of_) ++start[p + 1];
    for (size_t p = 0; p < num_pages; ++p) start[p + 1] += start[p];
    order.resize(n);
    fill.assign(start.begin(), start.end() - 1);
    for (size_t i = 0; i < n; ++i) order[fill[page_of_[i]]++] = uint32_t(i);
    if (segments_.size() < num_pages) segments_.resize(num_pages);
    present.clear();
    for (size_t p = 0; p < num_pages; ++p)
      if (start[p] != start[p + 1]) present.push_back(uint32_t(p));
    std::vector<std::vector<uint8_t>> encoded(present.size());  // freed as copied: held runs take the room
    tbb::parallel_for(tbb::blocked_range<size_t>(0, present.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
      FlushScratch& scratch = flush_scratch_.local();
      PageEncoder& encoder = scratch.encoder;
      std::vector<uint32_t>& q = scratch.positions;
      std::vector<uint32_t>& codes = scratch.codes;
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const uint32_t p = present[i];
        q.clear();
        codes.clear();
        for (uint32_t k = start[p]; k != start[p + 1]; ++k) {
          q.insert(q.end(), &positions_[9 * size_t(order[k])], &positions_[9 * size_t(order[k])] + 9);
          if (normals_) codes.insert(codes.end(), &normals_data_[3 * size_t(order[k])], &normals_data_[3 * size_t(order[k])] + 3);
        }
        encode_page(q, codes, grid_, encoder, encoded[i]);
      }
    });
    for (size_t i = 0; i < present.size(); ++i) {
      const uint32_t p = present[i];
      if (encoded[i].size() > kBlockBytes) {
        // One segment larger than a block: a block of its own.
        RAYLOD_RETURN_IF_ERROR(seal());
      } else if (staging_.size() + encoded[i].size() > kBlockBytes) {
        RAYLOD_RETURN_IF_ERROR(seal());
      }
      if (encoded[i].size() > UINT32_MAX) return Status::error(path_.string() + ": a run segment over 4 GiB");
      segments_[p].push_back(Segment{uint32_t(blocks_.size()), uint32_t(staging_.size()), start[p + 1] - start[p],
                                     uint32_t(encoded[i].size())});
      ++staging_segments_;
      staging_.insert(staging_.end(), encoded[i].begin(), encoded[i].end());
      std::vector<uint8_t>().swap(encoded[i]);
    }
    RAYLOD_RETURN_IF_ERROR(seal());
    positions_.clear();
    normals_data_.clear();
    page_of_.clear();
    return {};
  }

  // Encoded run bytes this run file may keep in memory from now on; blocks
  // past it are written to the file (the oldest first).
  Status set_hold_limit(uint64_t bytes) {
    hold_limit_ = bytes;
    for (size_t b = 0; b < blocks_.size() && held_ > hold_limit_; ++b)
      if (!blocks_[b].bytes.empty()) RAYLOD_RETURN_IF_ERROR(spill(blocks_[b]));
    return {};
  }

  // Copies a segment's bytes into `out` (from memory or the file). Safe to
  // call from several threads for different segments; a held block is freed
  // when its last segment has been read.
  Status read(const Segment& seg, std::vector<uint8_t>& out) {
    Block& b = blocks_[seg.block];
    out.resize(seg.bytes);
    if (b.in_memory) {
      std::memcpy(out.data(), b.bytes.data() + seg.offset, seg.bytes);
      if (b.unread.fetch_sub(1) == 1) std::vector<uint8_t>().swap(b.bytes);
      return {};
    }
    return pread_all(fd_, out.data(), seg.bytes, b.file_offset + seg.offset, path_);
  }

  const std::filesystem::path& path() const { return path_; }
  uint64_t file_bytes() const { return offset_; }  // written to the file
  uint64_t held_peak() const { return held_peak_; }
  // segments()[page id]: the page's pieces, one per run that holds any of it.
  std::vector<std::vector<Segment>>& segments() { return segments_; }
  void release_buffers() {
    std::vector<uint32_t>().swap(positions_);
    std::vector<uint32_t>().swap(normals_data_);
    std::vector<uint32_t>().swap(page_of_);
    std::vector<uint8_t>().swap(staging_);
    std::vector<uint32_t>().swap(flush_start_);
    std::vector<uint32_t>().swap(flush_order_);
    std::vector<uint32_t>().swap(flush_fill_);
    std::vector<uint32_t>().swap(flush_present_);
    flush_scratch_.clear();
  }

 private:
  static constexpr size_t kBlockBytes = 8 << 20;

  struct Block {
    std::vector<uint8_t> bytes;      // while held in memory
    uint64_t file_offset = 0;        // once written
    bool in_memory = false;
    std::atomic<uint32_t> unread{0};  // segments not read yet (held blocks)
    Block() = default;
    Block(Block&& o) noexcept
        : bytes(std::move(o.bytes)), file_offset(o.file_offset), in_memory(o.in_memory), unread(o.unread.load()) {}
  };

  // Closes the block being gathered: held if it fits, else written.
  Status seal() {
    if (staging_.empty()) return {};
    Block b;
    b.unread = staging_segments_;
    staging_segments_ = 0;
    if (held_ + staging_.size() <= hold_limit_) {
      held_ += staging_.size();
      held_peak_ = std::max(held_peak_, held_);
      b.bytes.swap(staging_);
      b.in_memory = true;
      staging_.reserve(kBlockBytes);
      blocks_.push_back(std::move(b));
      return {};
    }
    RAYLOD_RETURN_IF_ERROR(pwrite_all(fd_, staging_.data(), staging_.size(), offset_, path_));
    b.file_offset = offset_;
    offset_ += staging_.size();
    staging_.clear();
    blocks_.push_back(std::move(b));
    return {};
  }

  Status spill(Block& b) {
    RAYLOD_RETURN_IF_ERROR(pwrite_all(fd_, b.bytes.data(), b.bytes.size(), offset_, path_));
    b.file_offset = offset_;
    offset_ += b.bytes.size();
    held_ -= b.bytes.size();
    std::vector<uint8_t>().swap(b.bytes);
    b.in_memory = false;
    return {};
  }

  bool normals_;
  uint64_t capacity_;
  PageGrid grid_;
  std::filesystem::path path_;
  int fd_ = -1;
  uint64_t offset_ = 0;
  uint64_t hold_limit_ = 0, held_ = 0, held_peak_ = 0;
  std::vector<uint32_t> positions_, normals_data_;
  std::vector<uint8_t> staging_;
  uint32_t staging_segments_ = 0;
  std::vector<uint32_t> page_of_;
  // flush's arrays, kept between runs (release_buffers frees them).
  struct FlushScratch {
    PageEncoder encoder;
    std::vector<uint32_t> positions, codes;
  };
  std::vector<uint32_t> flush_start_, flush_order_, flush_fill_, flush_present_;
  tbb::enumerable_thread_specific<FlushScratch> flush_scratch_;
  std::deque<Block> blocks_;
  std::vector<std::vector<Segment>> segments_;
};

// ---------------------------------------------------------------------------
// Pass 2 per batch: corners into a batch-local table at the initial depth,
// and the page of each triangle (the cell of its centroid at page_level).
// Octahedral codes of recently seen normals (direct-mapped by the normal's
// bits): an indexed mesh repeats each vertex normal in about six nearby
// corners, and encoding is a quarter of the binning's time without it.
struct NormalCodeCache {
  static constexpr size_t kSize = 4096;
  uint32_t bits[kSize][3];
  uint32_t code[kSize];
  Vec3 decoded[kSize];
  NormalCodeCache() { std::memset(bits, 0xff, sizeof bits); }  // a NaN: never a reader's normal
  // The code of n, and its decoded normal in `out`.
  uint32_t encode(const Vec3& n, Vec3& out) {
    uint32_t b[3];
    std::memcpy(b, &n.x, 12);
    const size_t slot = size_t((b[0] * 0x9E3779B1u) ^ (b[1] * 0x85EBCA77u) ^ (b[2] * 0xC2B2AE3Du)) >> 20 & (kSize - 1);
    if (std::memcmp(bits[slot], b, 12) != 0) {
      std::memcpy(bits[slot], b, 12);
      code[slot] = encode_octahedral(n);
      decoded[slot] = decode_octahedral(code[slot]);
    }
    out = decoded[slot];
    return code[slot];
  }
};

struct BinToken : TokenBase {
  std::vector<uint32_t> grid_positions;  // 9 per triangle
  std::vector<uint32_t> normal_codes;    // 3 per triangle, if the mesh has normals
  std::unique_ptr<NormalCodeCache> normal_cache = std::make_unique<NormalCodeCache>();
  NodeTable local;
  std::vector<uint64_t> page_codes;
  std::vector<uint32_t> page_ids;
  uint64_t grid_merged = 0;  // triangles two of whose distinct corners the grid made one
};

void bin_batch(BinToken& t, const Plan& plan, int depth, bool has_normals) {
  const Grid cells(plan.root_lo, plan.root_size, depth);
  const Grid pages(plan.root_lo, plan.root_size, plan.page_level);
  const size_t n = t.batch.size();
  t.local.clear();
  t.page_codes.resize(n);
  uint64_t last_code = UINT64_MAX;
  size_t last = 0;
  // Every corner onto the grid first: the store holds the quantised mesh,
  // so quadrics, sums and pages are computed from what read_page returns.
  t.grid_positions.resize(9 * n);
  t.normal_codes.resize(has_normals ? 3 * n : 0);
  t.grid_merged = 0;
  for (size_t i = 0; i < n; ++i) {
    const Vec3 in[3] = {t.batch.positions[3 * i], t.batch.positions[3 * i + 1], t.batch.positions[3 * i + 2]};
    for (size_t c = 3 * i; c < 3 * i + 3; ++c) {
      quantise_position(t.batch.positions[c], plan.grid, &t.grid_positions[3 * c]);
      t.batch.positions[c] = grid_position(&t.grid_positions[3 * c], plan.grid);
      if (has_normals) t.normal_codes[c] = t.normal_cache->encode(t.batch.normals[c], t.batch.normals[c]);
    }
    const uint32_t* q = &t.grid_positions[9 * i];
    auto same = [&](int a, int b) { return q[3 * a] == q[3 * b] && q[3 * a + 1] == q[3 * b + 1] && q[3 * a + 2] == q[3 * b + 2]; };
    t.grid_merged += (same(0, 1) && in[0] != in[1]) || (same(1, 2) && in[1] != in[2]) || (same(0, 2) && in[0] != in[2]);
  }
  for (size_t i = 0; i < n; ++i) {
    const Vec3d p[3] = {Vec3d(t.batch.positions[3 * i]), Vec3d(t.batch.positions[3 * i + 1]),
                        Vec3d(t.batch.positions[3 * i + 2])};
    const Vec3d cross = glm::cross(p[1] - p[0], p[2] - p[0]);
    const double twice_area = glm::length(cross);
    Vec3d normal = twice_area > 0 ? cross / twice_area : Vec3d(0);
    if (has_normals) {
      const Vec3d sum = Vec3d(t.batch.normals[3 * i]) + Vec3d(t.batch.normals[3 * i + 1]) +
                        Vec3d(t.batch.normals[3 * i + 2]);
      const double len = glm::length(sum);
      if (len > kCancelledNormalSum) normal = sum / len;  // opposing normals: keep the face normal
    }
    const double weight = twice_area / 6.0;  // area / 3 per corner
    // quadric_from_plane(normal, x, weight) for the three corners, sharing A.
    const Vec3d wn = weight * normal;
    const double a00 = wn.x * normal.x, a01 = wn.x * normal.y, a02 = wn.x * normal.z;
    const double a11 = wn.y * normal.y, a12 = wn.y * normal.z, a22 = wn.z * normal.z;
    for (int k = 0; k < 3; ++k) {
      const Vec3d x = p[k] - plan.origin;
      const uint64_t code = cells.code(p[k]);
      if (code != last_code) {  // corners of a triangle often share a cell
        last_code = code;
        last = t.local.index(code);
      }
      NodeRecord& node = t.local.nodes[last];
      if (weight > 0) {
        const double nx = glm::dot(normal, x);
        Quadric& q = node.quadric;
        q.a00 += a00; q.a01 += a01; q.a02 += a02; q.a11 += a11; q.a12 += a12; q.a22 += a22;
        q.b0 += wn.x * nx; q.b1 += wn.y * nx; q.b2 += wn.z * nx;
        q.c += weight * nx * nx;
      }
      node.vertex_sum += x;
      node.normal_sum += weight * (has_normals ? Vec3d(t.batch.normals[3 * i + k]) : normal);
      ++node.corner_count;
    }
    t.page_codes[i] = pages.code((p[0] + p[1] + p[2]) / 3.0);
  }
}

struct Binned {
  std::vector<NodeRecord> leaves;  // sorted by code, at `depth`
  int depth = 0;
  PageIds pages;
  std::vector<uint64_t> page_counts;  // by page id
  uint64_t triangles = 0;
  uint64_t grid_merged = 0;  // BinToken::grid_merged, summed
};

Status bin_pass(MeshReader& reader, size_t ntokens, const Plan& plan, bool has_normals, uint64_t expected,
                RunFile& runs, Binned& out) {
  const std::string name = reader.path().string();
  NodeTable global;
  // Virtual until touched, but sized by the data too: a limit of terabytes
  // must not become a reservation of terabytes.
  global.nodes.reserve(size_t(std::min<uint64_t>(plan.max_nodes, 3 * expected + 64)));
  int depth = plan.quadric_depth;
  // Sorted runs stay in memory while the limit has room for them beside
  // what is resident now: the plan's overhead, the run buffer (with its
  // sorting arrays) and the node table as it grows (held runs are written
  // out, the oldest first, as it takes their room). A tenth of the limit is
  // kept free for the allocator.
  const double run_buffer = 1.5 * double(plan.run_triangles) * double(run_triangle_bytes(has_normals) + 8);
  auto hold_limit = [&](size_t nodes) {
    const double room = 0.9 * double(plan.memory_limit) - double(plan.overhead) - run_buffer -
                        double(nodes) * double(kBytesPerLeafNode);
    return room <= 0 ? uint64_t(0) : room >= 1.8e19 ? UINT64_MAX : uint64_t(room);
  };
  RAYLOD_RETURN_IF_ERROR(runs.set_hold_limit(hold_limit(0)));
  Progress progress("binning", expected, "triangles");
  Status s = run_pass<BinToken>(
      reader, ntokens,
      [&](BinToken& t) {
        t.error = check_batch(t.batch, has_normals, name, t.first);
        if (t.error.is_ok()) bin_batch(t, plan, plan.quadric_depth, has_normals);
      },
      [&](BinToken& t) -> Status {
        // Merge in batch order, coarsening when the table is full.
        for (const NodeRecord& r : t.local.nodes) {
          if (global.nodes.size() >= plan.max_nodes && depth > 0) {
            global.coarsen();
            --depth;
          }
          add_node(global.upsert(r.code >> (3 * (plan.quadric_depth - depth))), r);
        }
        t.page_ids.resize(t.page_codes.size());
        for (size_t i = 0; i < t.page_codes.size(); ++i) {
          const uint32_t id = out.pages.id(t.page_codes[i]);
          if (id >= out.page_counts.size()) out.page_counts.push_back(0);
          ++out.page_counts[id];
          t.page_ids[i] = id;
        }
        out.triangles += t.batch.size();
        out.grid_merged += t.grid_merged;
        if (out.triangles > expected)
          return Status::error(name + ": the mesh yielded more triangles than in the first pass (changed while building?)");
        RAYLOD_RETURN_IF_ERROR(runs.set_hold_limit(hold_limit(global.nodes.size())));
        RAYLOD_RETURN_IF_ERROR(runs.append(t.grid_positions.data(), t.normal_codes.data(), t.batch.size(), t.page_ids,
                                           out.pages.codes.size()));
        progress.advance(t.batch.size());
        return {};
      });
  progress.finish();
  RAYLOD_RETURN_IF_ERROR(s);
  if (out.triangles != expected)
    return Status::error(name + ": the mesh yielded " + std::to_string(out.triangles) + " triangles, the first pass " +
                         std::to_string(expected) + " (changed while building?)");
  RAYLOD_RETURN_IF_ERROR(runs.flush(out.pages.codes.size()));
  runs.release_buffers();
  global.release_index();
  std::sort(global.nodes.begin(), global.nodes.end(),
            [](const NodeRecord& a, const NodeRecord& b) { return a.code < b.code; });
  out.leaves = std::move(global.nodes);
  out.depth = depth;
  return {};
}

// The leaves (at `depth`, sorted by code) that hold an end of an open edge.
// Pages hand their open edges over in order; an edge waits for the page on
// the other side of it. Past `cap` pending edges matching stops: the pending
// ones are flagged as they are, and so is every later page's open edge. An
// interior edge across two pages then flags its leaves too: more cells kept,
// never a rim missed; the memory stays bounded for meshes with very many
// open edges (a soup of separate triangles has three each).
struct BoundaryFlags {
  std::span<const NodeRecord> leaves;
  int depth = 0;
  PageGrid grid;
  size_t cap = 0;
  std::vector<uint8_t> flags;
  OpenEdgeMatcher matcher;
  bool capped = false;
  uint64_t flagged_edges = 0;  // edges flagged without a match (past the cap, or at the end)

  BoundaryFlags(std::span<const NodeRecord> l, int d, const PageGrid& g, size_t c)
      : leaves(l), depth(d), grid(g), cap(c), flags(l.size(), 0) {}

  void add(std::span<const GridEdge> edges) {
    if (capped) {
      for (const GridEdge& e : edges) flag_edge(e);
      return;
    }
    matcher.add(edges);
    if (matcher.size() > cap) {
      flush();
      capped = true;
    }
  }
  void flush() {
    matcher.for_each([&](const GridEdge& e) { flag_edge(e); });
    matcher.clear();
  }

 private:
  void flag_code(uint64_t code) {
    auto it = std::lower_bound(leaves.begin(), leaves.end(), code,
                               [](const NodeRecord& n, uint64_t c) { return n.code < c; });
    if (it != leaves.end() && it->code == code) flags[size_t(it - leaves.begin())] = 1;
  }
  // The leaf of the grid point, and the leaf OctreeStore::cell_of finds for
  // the float a page decodes it to (rounding can put a point on a cell face
  // into the cell below): both, if they differ.
  void flag_point(const uint32_t* g) {
    const int shift = grid.bits - depth;
    const uint32_t max_cell = (uint32_t(1) << depth) - 1;
    auto cell = [&](uint32_t v) { return std::min(v >> shift, max_cell); };  // the far face belongs to the last cell
    flag_code(morton_encode(cell(g[0]), cell(g[1]), cell(g[2])));
    flag_code(cell_in_cube(Vec3d(grid_position(g, grid)), grid.lo, std::ldexp(grid.step, grid.bits), depth).code);
  }
  void flag_edge(const GridEdge& e) {
    flag_point(&e[0]);
    flag_point(&e[3]);
    ++flagged_edges;
  }
};

// One page in flight through write_pages.
struct PageToken {
  std::vector<uint32_t> positions, normals;  // grid coordinates, normal codes
  std::vector<uint8_t> segment;              // one run segment's bytes
  std::vector<uint8_t> bytes;
  PageEncoder encoder;
  Bbox bounds;
  uint32_t checksum = 0;  // of `bytes`
  std::vector<GridEdge> open_edges;  // edges of one triangle of this page (open_edges.h)
  OpenEdgeScratch edge_scratch;
};

// Reads page `id`'s segments back from the runs (input order) and encodes it.
Status encode_run_page(RunFile& runs, bool has_normals, const PageGrid& grid, uint32_t id, PageToken& t) {
  t.positions.clear();
  t.normals.clear();
  for (const auto& seg : runs.segments()[id]) {
    RAYLOD_RETURN_IF_ERROR(runs.read(seg, t.segment));
    Status s = decode_page_grid(t.segment, grid, t.positions, t.normals);
    if (!s.is_ok() || t.positions.size() % 9 != 0 || (has_normals && t.normals.size() * 3 != t.positions.size()))
      return Status::error(runs.path().string() + ": a run segment does not decode (the temporary file changed?): " +
                           s.message());
  }
  t.bounds = encode_page(t.positions, t.normals, grid, t.encoder, t.bytes);
  t.checksum = crc32c(t.bytes.data(), t.bytes.size());
  t.open_edges.clear();
  find_open_edges(t.encoder.keys, t.encoder.index, t.edge_scratch, t.open_edges);
  // A page far above the usual size leaves large tables: free them.
  if (t.edge_scratch.slots.size() > (size_t(1) << 22)) t.edge_scratch = OpenEdgeScratch{};
  return {};
}

// Pages in code order: each is read back from its run segments and encoded
// in parallel (page_codec.h), then written in order, one after another from
// data_offset; its open edges go to `boundary` in the same order. Returns
// the end offset of the page data.
StatusOr<uint64_t> write_pages(int fd, const std::filesystem::path& out_path, RunFile& runs, const Binned& binned,
                               bool has_normals, const PageGrid& grid, uint64_t data_offset, size_t ntokens,
                               std::vector<PageInfo>& pages, BoundaryFlags& boundary) {
  const size_t num_pages = binned.pages.codes.size();
  std::vector<uint32_t> order(num_pages);
  for (size_t i = 0; i < num_pages; ++i) order[i] = uint32_t(i);
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return binned.pages.codes[a] < binned.pages.codes[b]; });
  for (uint32_t id : order)
    if (binned.page_counts[id] > UINT32_MAX / 3)
      return Status::error(out_path.string() + ": a page would hold more than 2^32 corners");
  uint64_t offset = data_offset;
  Progress progress("pages", binned.triangles, "triangles");
  pages.clear();
  pages.reserve(num_pages);
  Status written = ordered_pipeline<PageToken>(
      num_pages, ntokens,
      [&](PageToken& t, size_t i) { return encode_run_page(runs, has_normals, grid, order[i], t); },
      [&](PageToken& t, size_t i) -> Status {
        RAYLOD_RETURN_IF_ERROR(pwrite_all(fd, t.bytes.data(), t.bytes.size(), offset, out_path));
        PageInfo info;
        info.code = binned.pages.codes[order[i]];
        info.offset = offset;
        info.triangle_count = uint32_t(binned.page_counts[order[i]]);
        info.checksum = t.checksum;
        info.bounds = t.bounds;
        info.bytes = t.bytes.size();
        offset += t.bytes.size();
        pages.push_back(info);
        boundary.add(t.open_edges);
        progress.advance(info.triangle_count);
        if (pages.size() == std::max<size_t>(1, num_pages / 2)) fault_point("build.pages");
        return {};
      });
  progress.finish();
  RAYLOD_RETURN_IF_ERROR(written);
  if (pages.size() != num_pages) return Status::error(out_path.string() + ": internal error: pages were lost");
  return offset;
}

}  // namespace

uint64_t resolved_memory_limit(const StoreOptions& options) {
  return options.memory_limit ? options.memory_limit : UINT64_MAX;
}

std::string describe_memory_limit(uint64_t memory_limit) {
  return memory_limit ? format_bytes(memory_limit) : "no limit";
}

std::string describe_position_grid(double step, const Bbox& bounds, const Vec3d& mesh_origin) {
  const Vec3d lo = bounds.lo + mesh_origin, hi = bounds.hi + mesh_origin;
  char text[320];
  std::snprintf(text, sizeof text,
                "the store's position grid (points %.3g apart, set by the mesh's bounding box from (%.6g, %.6g, %.6g) "
                "to (%.6g, %.6g, %.6g), %.3g across)",
                step, lo.x, lo.y, lo.z, hi.x, hi.y, hi.z, std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}));
  return text;
}

namespace {

std::string grid_merged_warning(uint64_t merged, uint64_t triangles, const Scan& scan, double step) {
  // One in a hundred, or one at all in a small mesh: the grid follows the
  // bounding box, so a few vertices far from the rest (a stray coordinate
  // in a CAD export) make it too coarse for everything else.
  if (merged == 0 || merged * 100 < triangles) return "";
  return std::to_string(merged) + " of " + std::to_string(triangles) + " triangles lose a corner to " +
         describe_position_grid(step, scan.bounds, scan.mesh_origin) +
         ": if the part is far smaller than that box, a few vertices lie far from the rest";
}

}  // namespace

StatusOr<BuildReport> build_store_from_stream(const MeshStreamOpener& open, const SourceFingerprint& source,
                                              const std::filesystem::path& store_path, const StoreOptions& options,
                                              const std::function<StatusOr<uint64_t>()>& source_hash) {
  const auto t0 = std::chrono::steady_clock::now();
  if (options.max_depth < 0 || options.max_depth > int(kMaxLevel))
    return Status::error("--max-depth must be between 0 and " + std::to_string(kMaxLevel));
  const uint64_t memory_limit = resolved_memory_limit(options);
  if (memory_limit < kMinMemoryLimit) return Status::error("--memory-limit must be at least 1M");
  const size_t concurrency = size_t(ambient_parallelism());
  const size_t ntokens = std::clamp<size_t>(2 * concurrency, 2, 8);

  // Pass 1.
  RAYLOD_ASSIGN_OR_RETURN(auto reader1, open());
  RAYLOD_ASSIGN_OR_RETURN(Scan scan, scan_pass(*reader1, ntokens));
  reader1.reset();
  auto now = [] { return std::chrono::steady_clock::now(); };
  auto since = [](auto t) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count(); };
  BuildReport report;
  report.scan_seconds = since(t0);
  auto t1 = now();
  const Plan plan = make_plan(scan, options, memory_limit);

  // Pass 2.
  auto runs_owner = std::make_unique<RunFile>(scan.has_normals, plan.run_triangles, plan.grid);
  RunFile& runs = *runs_owner;
  RAYLOD_RETURN_IF_ERROR(runs.open(store_path));
  Binned binned;
  {
    RAYLOD_ASSIGN_OR_RETURN(auto reader2, open());
    if (reader2->header().has_normals != scan.has_normals)
      return Status::error(reader2->path().string() + ": changed while building (normals appeared or vanished)");
    if (reader2->header().origin != scan.mesh_origin)
      return Status::error(reader2->path().string() + ": changed while building (its first vertex moved)");
    RAYLOD_RETURN_IF_ERROR(bin_pass(*reader2, ntokens, plan, scan.has_normals, scan.triangles, runs, binned));
  }
  const std::vector<NodeRecord>& leaves = binned.leaves;
  const std::vector<uint64_t> level_counts = level_counts_of(leaves, binned.depth);
  report.bin_seconds = since(t1);
  fault_point("build.binned");
  auto t2 = now();

  StoreHeader header;
  header.source_path = source.path;
  header.source_bytes = source.bytes;
  header.source_mtime_ns = source.mtime_ns;
  header.source_hash = source.hash;
  if (source_hash) {
    RAYLOD_ASSIGN_OR_RETURN(header.source_hash, source_hash());
  }
  header.options = options;
  header.triangle_count = scan.triangles;
  header.has_normals = scan.has_normals;
  header.mesh_origin = scan.mesh_origin;
  header.origin = plan.origin;
  header.root_lo = plan.root_lo;
  header.root_size = plan.root_size;
  header.quadric_depth = binned.depth;
  header.page_level = plan.page_level;
  header.grid_bits = plan.grid.bits;
  header.bounds = scan.bounds;
  header.coarsened = binned.depth < plan.quadric_depth;
  std::tie(header.reuse_limit_lo, header.reuse_limit_hi) =
      reuse_limits(plan, binned.depth, leaves.size(), memory_limit);

  Layout layout;
  uint64_t nodes = 0;
  for (uint64_t c : level_counts) {
    layout.level_counts.push_back(c);
    nodes += c;
  }
  layout.page_count = binned.pages.codes.size();
  const uint64_t header_bytes = encode_header(header, layout).size();
  layout.node_table_offset = align_up(header_bytes, 64);
  layout.node_table_bytes = nodes * sizeof(NodeRecord);
  layout.page_table_offset = align_up(layout.node_table_offset + layout.node_table_bytes, 64);
  layout.data_offset = align_up(layout.page_table_offset + layout.page_count * sizeof(PageInfo), 4096);

  AtomicOutput output(store_path);
  const auto& tmp = output.temp_path();
  int fd = ::open(tmp.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status::error(store_path.string() + ": cannot create: " + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};

  std::vector<PageInfo> pages;
  // Pending open edges take about 64 bytes each: at most a 64th of the
  // memory limit (at least 64k, at most 4M of them).
  const size_t edge_cap = size_t(std::clamp<uint64_t>(memory_limit / 64 / 64, uint64_t(1) << 16, uint64_t(1) << 22));
  BoundaryFlags boundary_flags(leaves, binned.depth, plan.grid, edge_cap);
  RAYLOD_ASSIGN_OR_RETURN(const uint64_t data_end, write_pages(fd, tmp, runs, binned, scan.has_normals, plan.grid,
                                                               layout.data_offset, ntokens, pages, boundary_flags));
  boundary_flags.flush();
  report.open_edges = boundary_flags.flagged_edges;
  report.open_edges_peak = boundary_flags.matcher.peak();
  report.open_edges_capped = boundary_flags.capped;
  report.runs_written = runs.file_bytes();
  report.runs_held_peak = runs.held_peak();
  const std::vector<uint8_t> boundary = std::move(boundary_flags.flags);
  layout.data_bytes = data_end - layout.data_offset;
  // Closing the unlinked runs file frees its blocks and page cache (about a
  // second per 2 GiB here); it is part of the cost of building.
  runs_owner.reset();
  {
    // The node table, the leaves first, then each level above summed from
    // the one below it (held only while the next is summed). The CRC runs
    // over the table in file order, root level first: each level's CRC is
    // taken as it is written and the levels' CRCs are combined in file
    // order afterwards (crc32c_combine), instead of reading the table back.
    std::vector<uint64_t> level_begin(1, 0);
    for (uint64_t c : level_counts) level_begin.push_back(level_begin.back() + c);
    std::vector<uint32_t> level_crc(level_counts.size(), 0);
    auto write_level = [&](int level, std::span<const NodeRecord> records) -> Status {
      if (records.size() != level_counts[size_t(level)])
        return Status::error(store_path.string() + ": internal error: level " + std::to_string(level) + " has " +
                             std::to_string(records.size()) + " nodes, not " + std::to_string(level_counts[size_t(level)]));
      level_crc[size_t(level)] = crc32c(records.data(), records.size_bytes());
      return pwrite_all(fd, records.data(), records.size_bytes(),
                        layout.node_table_offset + level_begin[size_t(level)] * sizeof(NodeRecord), tmp);
    };
    RAYLOD_RETURN_IF_ERROR(write_level(binned.depth, leaves));
    std::vector<NodeRecord> below;
    for (int level = binned.depth - 1; level >= 0; --level) {
      std::vector<NodeRecord> above = sum_parent_level(level + 1 == binned.depth ? std::span<const NodeRecord>(leaves)
                                                                                 : std::span<const NodeRecord>(below));
      RAYLOD_RETURN_IF_ERROR(write_level(level, above));
      below = std::move(above);
    }
    below = {};
    uint32_t crc = 0;  // of no bytes
    for (size_t level = 0; level < level_counts.size(); ++level)
      crc = crc32c_combine(crc, level_crc[level], level_counts[level] * sizeof(NodeRecord));
    layout.node_table_crc = crc;
  }
  {  // The boundary list: the flagged leaves' codes, after the page data.
    std::vector<uint64_t> codes;
    for (size_t i = 0; i < leaves.size(); ++i)
      if (boundary[i]) codes.push_back(leaves[i].code);
    layout.boundary_offset = align_up(data_end, 8);
    layout.boundary_count = codes.size();
    layout.boundary_crc = crc32c(codes.data(), codes.size() * 8);
    layout.file_bytes = layout.boundary_offset + codes.size() * 8;
    RAYLOD_RETURN_IF_ERROR(pwrite_all(fd, codes.data(), codes.size() * 8, layout.boundary_offset, tmp));
  }
  RAYLOD_RETURN_IF_ERROR(pwrite_all(fd, pages.data(), pages.size() * sizeof(PageInfo), layout.page_table_offset, tmp));
  layout.page_table_crc = crc32c(pages.data(), pages.size() * sizeof(PageInfo));
  const std::string head = encode_header(header, layout);
  if (head.size() != header_bytes) return Status::error(store_path.string() + ": internal error: header size changed");
  RAYLOD_RETURN_IF_ERROR(pwrite_all(fd, head.data(), head.size(), 0, tmp));
  if (::ftruncate(fd, off_t(layout.file_bytes)) != 0)
    return Status::error(store_path.string() + ": cannot size the store: " + std::strerror(errno));
  report.write_seconds = since(t2);
  auto t3 = now();
  fault_point("build.before_rename");
  RAYLOD_RETURN_IF_ERROR(output.commit());
  report.commit_seconds = since(t3);

  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  report.triangles = scan.triangles;
  report.peak_rss = peak_rss_bytes();
  report.quadric_depth = binned.depth;
  report.page_level = plan.page_level;
  report.nodes = nodes;
  report.pages = pages.size();
  report.node_table_bytes = nodes * sizeof(NodeRecord);
  report.store_bytes = layout.file_bytes;
  report.source_bytes = source.bytes;
  report.coarsened = header.coarsened;
  if (plan.budget_bytes > memory_limit)
    report.warning = "--memory-limit " + format_bytes(memory_limit) + " is below what the reader's vertex table (" +
                     format_bytes(scan.reader_bytes) + ") and the minimal buffers need (" +
                     format_bytes(plan.budget_bytes) + "); peak memory may exceed it";
  if (const std::string w = grid_merged_warning(binned.grid_merged, scan.triangles, scan, plan.grid.step); !w.empty())
    report.warning += (report.warning.empty() ? "" : "; ") + w;
  return report;
}

}  // namespace raylod
