// The disk-backed octree store written by `raylod build` (method step A1 at
// out-of-core scale). Only the node table with per-node quadrics is held in
// memory; the triangles live in pages on disk, one page per occupied cell of
// the page level, read back on demand (checksummed).
//
// Geometry: the root cell is a cube (root_lo, root_size) around the mesh.
// A cell at level L has side root_size / 2^L and is named by the Morton code
// of its integer coordinates (3*L bits). Every triangle corner is binned into
// the cell containing that vertex (Luebke-Erikson clustering); the quadric of
// a cell is the sum, over corners in it, of the plane quadric of the corner's
// triangle (Lindstrom, eq. 4), with the plane normal the average of the
// triangle's vertex normals where the file has normals, else the face normal.
// Quadrics and sums are in double, relative to `origin` (the mesh centre).
//
// Details a reader of the store can rely on (octree_build.cpp has the why):
//   - root_size is a power of two, so cell sizes are exact and cell_of() is
//     an exact scaling; the root cube is centred on the mesh bounds.
//   - Quadric weights: each corner adds its triangle's plane quadric times
//     area / 3 (a triangle inside one cell adds its area once), with the plane
//     through that corner; normal_sum adds area / 3 times the corner's vertex
//     normal (the face normal if the file has none). Zero-area triangles add
//     no plane but are counted in corner_count and vertex_sum.
//   - quadric_depth is the deepest level <= max_depth whose node table fits the
//     memory limit and whose parent level still merges vertices (cells there
//     hold more than about two vertices on average).
//   - A triangle lives in exactly one page: the page-level cell containing its
//     centroid. Its vertices may lie in neighbouring cells; PageInfo::bounds
//     are the tight bounds of the page's triangles and cover them. Within a
//     page triangles keep their input order. Pages are sorted by code.
//   - Page bytes: indexed vertices, positions quantised on one grid for the
//     whole store (1/4096 of the finest quadric cell or finer up to depth 18,
//     so a decoded position is within 1/8192 of that cell per axis of the
//     input, wherever the model sits) and octahedral normals (streaming/page_codec.h);
//     CRC-32C over the page (crc32c below). read_page gives them back as a
//     float triangle soup in the page's input order.
//   - The store does not depend on the thread count (byte-identical files).
// The file layout is in streaming/octree_format.h.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"
#include "streaming/mesh_reader.h"
#include "streaming/source_record.h"

namespace raylod {

struct PageMesh;     // page_codec.h

// Symmetric 4x4 plane quadric Q = [[A, -b], [-b^T, c]] (eq. 4), A symmetric 3x3.
struct Quadric {
  double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0;
  double b0 = 0, b1 = 0, b2 = 0;
  double c = 0;
};
// Quadric of the plane with unit normal n through point x (relative coordinates), times weight.
Quadric quadric_from_plane(const Vec3d& n, const Vec3d& x, double weight = 1.0);
void quadric_add(Quadric& q, const Quadric& r);
// Sum of squared plane distances of v: v^T A v - 2 b.v + c.
double quadric_error(const Quadric& q, const Vec3d& v);
// Total weight of the planes summed in q: trace(A), since each unit normal
// adds w n n^T (the store weighs by area, so this is the cell's area).
inline double quadric_weight(const Quadric& q) { return q.a00 + q.a11 + q.a22; }

struct CellKey {
  uint32_t level = 0;
  uint64_t code = 0;  // Morton code at `level`
  bool operator==(const CellKey&) const = default;
  auto operator<=>(const CellKey&) const = default;
  CellKey parent() const { return {level - 1, code >> 3}; }
};

// One occupied octree node (levels 0..quadric_depth).
struct NodeRecord {
  uint64_t code = 0;          // Morton code at its level
  Quadric quadric;            // relative to StoreHeader::origin
  Vec3d vertex_sum{0};        // sum of corner positions, relative to origin
  Vec3d normal_sum{0};        // sum of corner normals, area-weighted
  uint64_t corner_count = 0;  // triangle corners binned into this cell
};

// Where the triangles of one page-level cell are on disk.
struct PageInfo {
  uint64_t code = 0;          // Morton code at page_level
  uint64_t offset = 0;        // byte offset of the page in the store file
  uint32_t triangle_count = 0;
  uint32_t checksum = 0;      // of the page bytes
  Bbox bounds;                // tight bounds of the page's triangles as decoded (world coordinates)
  uint64_t bytes = 0;         // encoded size of the page (page_codec.h)
};

struct StoreOptions {
  uint64_t memory_limit = 0;  // bytes the build plans within; 0 = no limit (the deepest useful quadric level)
  int max_depth = 12;         // deepest level that may keep quadrics
  uint32_t page_triangles = 4096;  // target triangles per page (chooses page_level)
};

struct StoreHeader {
  uint32_t version = 1;
  std::string source_path;    // the mesh it was built from
  uint64_t source_bytes = 0, source_mtime_ns = 0, source_hash = 0;
  StoreOptions options;
  uint64_t triangle_count = 0;
  bool has_normals = false;
  // Store coordinates (pages, cells, bounds) are the mesh file's coordinates
  // minus mesh_origin: the reader's local origin (MeshHeader::origin), which
  // is (0, 0, 0) unless the mesh lies far from zero. Whoever places the
  // store in a scene composes its transform with translate(mesh_origin).
  Vec3d mesh_origin{0};
  Vec3d origin{0};            // quadrics and sums are relative to this point (store coordinates)
  Vec3d root_lo{0};           // root cube corner (store coordinates)
  double root_size = 0;       // root cube side
  int quadric_depth = 0;      // deepest level with NodeRecords
  int page_level = 0;         // level whose cells are the pages
  int grid_bits = 20;         // positions are on a grid of root_size / 2^grid_bits (page_codec.h)
  Bbox bounds;                // mesh bounds (store coordinates)
  // Layout facts filled in by OctreeStore::open (not needed to build).
  uint64_t file_bytes = 0;        // whole store file
  uint64_t node_table_bytes = 0;  // all levels' NodeRecords (in the file, mapped on open)
  uint64_t page_data_bytes = 0;   // all pages
  bool coarsened = false;         // quadric_depth was lowered during the build to fit memory_limit
  // The memory limits under which a fresh build of the same mesh and options
  // makes this very store (same depth, same quadrics): a store is reused
  // under any limit in [lo, hi] and rebuilt under any other, so the output
  // never depends on the limit an earlier build happened to use.
  uint64_t reuse_limit_lo = 0, reuse_limit_hi = 0;
};

class OctreeStore {
 public:
  static StatusOr<std::unique_ptr<OctreeStore>> open(const std::filesystem::path& path);
  virtual ~OctreeStore() = default;

  virtual const StoreHeader& header() const = 0;
  // Occupied nodes at `level` (0..quadric_depth), sorted by code.
  virtual std::span<const NodeRecord> level(int level) const = 0;
  // The node with this key, or nullptr if the cell is empty or below quadric_depth.
  virtual const NodeRecord* find(const CellKey& key) const = 0;
  virtual std::span<const PageInfo> pages() const = 0;
  // Whether the cell holds a vertex of an open boundary (a hole's rim, the
  // edge of an open surface: an edge of exactly one triangle, matched by
  // its quantised end points over the whole mesh). A quadric does not see
  // how far collapsing such a cell moves the rim (collapse_deviation.h).
  virtual bool touches_boundary(const CellKey& key) const = 0;
  // Leaves flagged so.
  virtual uint64_t boundary_leaves() const = 0;
  // Reads page i into batch (cleared first); fails with a clear message if
  // its checksum does not match, and then records the mismatch beside the
  // store (record_store_corruption) so that the next build rebuilds it.
  virtual Status read_page(size_t i, TriangleBatch& batch) const = 0;
  // The same indexed, as the page is stored (normals as their codes).
  virtual Status read_page(size_t i, PageMesh& page) const = 0;
  // True once read_page has found a page whose checksum does not match.
  virtual bool found_corruption() const = 0;

  // Cell geometry helpers.
  double cell_size(int level) const { return header().root_size / double(uint64_t(1) << level); }
  double cell_diagonal(int level) const { return cell_size(level) * 1.7320508075688772; }
  CellKey cell_of(const Vec3d& world_point, int level) const;
  Bbox cell_bounds(const CellKey& key) const;
};

// The cell at `level` of the root cube (corner root_lo, side root_size) that
// holds p (clamped into the cube): OctreeStore::cell_of, for a store's header.
CellKey cell_in_cube(const Vec3d& p, const Vec3d& root_lo, double root_size, int level);

// Morton code helpers (3 interleaved 21-bit coordinates).
uint64_t morton_encode(uint32_t x, uint32_t y, uint32_t z);
void morton_decode(uint64_t code, uint32_t& x, uint32_t& y, uint32_t& z);

// Default store path for a mesh: "MESH.raylod" beside the mesh file.
std::filesystem::path default_store_path(const std::filesystem::path& mesh);

struct BuildReport {
  bool reused = false;        // an up-to-date store was already there
  std::string reason;         // why it was (re)built or reused
  double seconds = 0;
  uint64_t triangles = 0;
  uint64_t peak_rss = 0;
  // Filled when built (not reused):
  int quadric_depth = 0, page_level = 0;
  uint64_t nodes = 0, pages = 0;
  uint64_t node_table_bytes = 0;  // memory the quadrics take (all levels)
  uint64_t store_bytes = 0;       // size of the written store file
  uint64_t source_bytes = 0;
  bool coarsened = false;         // quadric_depth had to be lowered during the build
  uint64_t open_edges = 0;        // open boundary edges (edges of one triangle) flagged
  uint64_t open_edges_peak = 0;   // most edges pending a match across pages at once
  bool open_edges_capped = false; // matching stopped at the cap (later pages' open edges flagged unmatched)
  uint64_t runs_written = 0;      // sorted-run bytes written to the temporary file
  uint64_t runs_held_peak = 0;    // most sorted-run bytes kept in memory instead at once
  // Wall time of the phases: pass 1 (bounds), pass 2 (binning and quadrics),
  // page assembly and writing, fsync + rename.
  double scan_seconds = 0, bin_seconds = 0, write_seconds = 0, commit_seconds = 0;
  std::string warning;            // e.g. a memory limit too small to honour
  // Reused: the store as the up-to-date check opened it (checksums of the
  // header and tables verified), so that the caller need not open it again,
  // and the store file's status taken before it was opened.
  std::shared_ptr<OctreeStore> opened;
  FileStatus opened_status;
};
// Builds (or reuses, if up to date for the same mesh and options) the store.
StatusOr<BuildReport> build_store(const std::filesystem::path& mesh, const std::filesystem::path& store,
                                  const StoreOptions& options);
// Same; with force, rebuilds even an up-to-date store (replacing it atomically);
// with verify, an up-to-date store has every page's checksum and its mesh's
// content hash checked and is rebuilt if one does not match. Builds from one mesh are serialised by
// flock() on the mesh file, so concurrent callers build its store once and
// the others reuse it. A build never removes a store: if the mesh changes while it is
// read, the build fails and leaves whatever store was there.
// before_building, if given, is told why just before a build starts.
StatusOr<BuildReport> build_store(const std::filesystem::path& mesh, const std::filesystem::path& store,
                                  const StoreOptions& options, bool force, bool verify = false,
                                  const std::function<void(const std::string& reason)>& before_building = nullptr);
// True if `store` exists, opens, has no corruption record (store_corruption)
// and matches the mesh's size, mtime and content hash. The hash is not read
// again while the store's STORE.checked record vouches for the mesh's file
// status (source_record.h), unless rehash. If current and `opened` is given,
// its `opened` and `opened_status` are set.
bool store_is_current(const std::filesystem::path& mesh, const std::filesystem::path& store,
                      const StoreOptions& options, std::string* reason = nullptr, bool rehash = false,
                      BuildReport* opened = nullptr);

// ---- Lower-level entry points (streaming/octree_build.cpp) ----

// Opens a fresh pass over the input mesh; build_store_from_stream calls it
// once per pass (twice), and every pass must yield the same triangles in the
// same batches. Tests pass in-memory readers; build_store passes open_mesh.
using MeshStreamOpener = std::function<StatusOr<std::unique_ptr<MeshReader>>()>;

// What the store records about the mesh it was built from.
struct SourceFingerprint {
  std::string path;             // absolute path
  uint64_t bytes = 0, mtime_ns = 0, hash = 0;
  FileStatus status;            // the whole status of the file (device, inode, ctime too; source_record.h)
};
// Size, mtime and (if with_hash) content hash (content_hash64 of all bytes).
StatusOr<SourceFingerprint> fingerprint_file(const std::filesystem::path& path, bool with_hash = true);

// The core of `raylod build`: two streaming passes (bounds, then binning and
// quadric accumulation), then pages are assembled from sorted runs and the
// store is written atomically to `store`. Ignores whether a store exists.
// If source_hash is given it is called once, after the passes, for the value
// recorded as the source hash (build_store hashes the file concurrently).
StatusOr<BuildReport> build_store_from_stream(const MeshStreamOpener& open, const SourceFingerprint& source,
                                              const std::filesystem::path& store, const StoreOptions& options,
                                              const std::function<StatusOr<uint64_t>()>& source_hash = nullptr);

// The limit the build plans within: options.memory_limit, or UINT64_MAX for
// 0 (no limit). A store built without a limit records 0.
uint64_t resolved_memory_limit(const StoreOptions& options);
// For messages: "1.00 GiB", or "no limit" for 0.
std::string describe_memory_limit(uint64_t memory_limit);
// "the store's position grid (points STEP apart, set by the mesh's bounding
// box from (..) to (..), S across)", the box in the mesh's own coordinates
// (store bounds plus mesh_origin): what the build's warning and an empty
// simplified mesh say when a few far-away vertices made the grid too coarse.
std::string describe_position_grid(double step, const Bbox& bounds, const Vec3d& mesh_origin);

// ---- Store file helpers (streaming/octree_store.cpp) ----

// True if the file starts with the store magic (for `raylod info`).
bool is_store_file(const std::filesystem::path& path);
// Prints levels, node counts per level, pages, bytes, quadric memory and the
// build options of a store (for `raylod info STORE`).
Status print_store_info(const std::filesystem::path& path, std::FILE* out);

// ---- Corruption records (streaming/octree_store.cpp) ----
//
// A reader that finds a page whose checksum does not match writes STORE.corrupt
// (atomically) naming the page and the store file (device and inode), so that
// the finding outlives the process: store_is_current then says the store is
// stale and `raylod build` / `raylod run` rebuild it. A record left for a
// store file that has since been replaced (another inode) does not apply.

// STORE.corrupt.
std::filesystem::path corruption_record_path(const std::filesystem::path& store);
// Records `what` (e.g. "page 789 (cell 1f3) checksum mismatch") for the store
// file now at `store`.
Status record_store_corruption(const std::filesystem::path& store, const std::string& what);
// What was recorded, if a record exists and applies to the store file now at `store`.
std::optional<std::string> store_corruption(const std::filesystem::path& store);
// Reads every page of the store and checks its checksum (a mismatch is
// recorded as by read_page); returns the number of pages checked, or the
// first failure.
StatusOr<uint64_t> verify_store_pages(const std::filesystem::path& store);

// ---- Checksums (streaming/store_checksum.cpp) ----

// CRC-32C (Castagnoli), hardware-accelerated where SSE4.2 is available.
// Chainable: crc32c(b, crc32c(a)) == crc32c(a then b).
uint32_t crc32c(const void* data, size_t bytes, uint32_t crc = 0);
// crc32c of a then b, from crc32c(a), crc32c(b) and b's length.
uint32_t crc32c_combine(uint32_t crc_a, uint32_t crc_b, uint64_t bytes_b);
// 64-bit content hash (4-lane multiply-rotate, xxh64-style rounds), streaming.
class ContentHasher {
 public:
  void update(const void* data, size_t bytes);
  uint64_t digest() const;
 private:
  uint64_t lanes_[4] = {0x9E3779B185EBCA87ull, 0xC2B2AE3D27D4EB4Full, 0x165667B19E3779F9ull, 0x85EBCA77C2B2AE63ull};
  unsigned char tail_[32] = {};
  size_t tail_bytes_ = 0;
  uint64_t total_ = 0;
};
uint64_t content_hash64(const void* data, size_t bytes);

}  // namespace raylod
