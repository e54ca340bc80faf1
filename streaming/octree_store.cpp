// The octree store file: header encoding, open-time validation, page reads,
// Morton codes and cell geometry, and the `raylod info` printout. The layout
// is described in streaming/octree_format.h; the builder is octree_build.cpp.
#include "streaming/octree_store.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cinttypes>
#include <cstring>
#include <fstream>
#include <sstream>

#include "core/system.h"
#include "streaming/octree_format.h"
#include "streaming/page_codec.h"

namespace raylod {
namespace store_format {
namespace {

class ByteWriter {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const char*>(&v);
    out.append(p, sizeof(T));
  }
  void put_vec(const Vec3d& v) { put(v.x); put(v.y); put(v.z); }
  void put_str(const std::string& s) { put(uint32_t(s.size())); out += s; }
  std::string out;
};

class ByteReader {
 public:
  ByteReader(const char* p, size_t n) : p_(p), end_(p + n) {}
  template <class T>
  bool get(T& v) {
    if (size_t(end_ - p_) < sizeof(T)) return false;
    std::memcpy(&v, p_, sizeof(T));
    p_ += sizeof(T);
    return true;
  }
  bool get_vec(Vec3d& v) { return get(v.x) && get(v.y) && get(v.z); }
  bool get_str(std::string& s) {
    uint32_t n = 0;
    if (!get(n) || size_t(end_ - p_) < n) return false;
    s.assign(p_, n);
    p_ += n;
    return true;
  }
  bool at_end() const { return p_ == end_; }

 private:
  const char* p_;
  const char* end_;
};

}  // namespace

namespace {

void add_node(NodeRecord& a, const NodeRecord& b) {
  quadric_add(a.quadric, b.quadric);
  a.vertex_sum += b.vertex_sum;
  a.normal_sum += b.normal_sum;
  a.corner_count += b.corner_count;
}

}  // namespace

std::vector<uint64_t> level_counts_of(std::span<const NodeRecord> leaves, int depth) {
  std::vector<uint64_t> counts(size_t(depth) + 1, 0);
  counts[size_t(depth)] = leaves.size();
  for (int l = depth - 1; l >= 0; --l) {
    const int shift = 3 * (depth - l);
    for (size_t i = 0; i < leaves.size(); ++i)
      if (i == 0 || (leaves[i].code >> shift) != (leaves[i - 1].code >> shift)) ++counts[size_t(l)];
  }
  return counts;
}

std::vector<NodeRecord> sum_parent_level(std::span<const NodeRecord> children) {
  std::vector<NodeRecord> parents;
  for (const NodeRecord& c : children) {
    if (!parents.empty() && parents.back().code == (c.code >> 3)) {
      add_node(parents.back(), c);
    } else {
      parents.push_back(c);
      parents.back().code = c.code >> 3;
    }
  }
  return parents;
}

bool parents_match(std::span<const NodeRecord> parents, std::span<const NodeRecord> children) {
  size_t p = 0;
  for (size_t i = 0; i < children.size(); ++i) {
    const uint64_t code = children[i].code >> 3;
    if (i > 0 && code == children[i - 1].code >> 3) continue;
    if (p == parents.size() || parents[p].code != code) return false;
    ++p;
  }
  return p == parents.size();
}

std::string encode_header(const StoreHeader& h, const Layout& l) {
  ByteWriter blob;
  blob.put_str(h.source_path);
  blob.put(h.source_bytes); blob.put(h.source_mtime_ns); blob.put(h.source_hash);
  blob.put(h.options.memory_limit); blob.put(int32_t(h.options.max_depth));
  blob.put(int32_t(0));  // was the thread count; the store never depended on it
  blob.put(h.options.page_triangles);
  blob.put(h.triangle_count); blob.put(uint8_t(h.has_normals)); blob.put(uint8_t(h.coarsened));
  blob.put_vec(h.origin); blob.put_vec(h.root_lo); blob.put(h.root_size);
  blob.put(int32_t(h.quadric_depth)); blob.put(int32_t(h.page_level));
  blob.put_vec(h.bounds.lo); blob.put_vec(h.bounds.hi);
  blob.put(uint32_t(l.level_counts.size()));
  for (uint64_t c : l.level_counts) blob.put(c);
  blob.put(l.node_table_offset); blob.put(l.node_table_crc); blob.put(l.node_table_bytes);
  blob.put(l.page_count); blob.put(l.page_table_offset); blob.put(l.page_table_crc);
  blob.put(l.data_offset); blob.put(l.data_bytes);
  blob.put(l.boundary_offset); blob.put(l.boundary_count); blob.put(l.boundary_crc);
  blob.put(l.file_bytes);
  blob.put(h.reuse_limit_lo); blob.put(h.reuse_limit_hi);
  blob.put(int32_t(h.grid_bits));
  blob.put_vec(h.mesh_origin);

  ByteWriter out;
  out.out.append(kMagic, 8);
  out.put(kVersion);
  out.put(uint32_t(blob.out.size()));
  out.out += blob.out;
  out.put(crc32c(out.out.data(), out.out.size()));
  return std::move(out.out);
}

Status pread_all(int fd, void* data, size_t bytes, uint64_t offset, const std::filesystem::path& path) {
  auto* p = static_cast<char*>(data);
  while (bytes > 0) {
    ssize_t r = ::pread(fd, p, std::min<size_t>(bytes, size_t(1) << 30), off_t(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return Status::error(path.string() + ": read failed: " + std::strerror(errno));
    if (r == 0) return Status::error(path.string() + ": unexpected end of file at byte " + std::to_string(offset) +
                                     " (truncated store?)");
    p += r; bytes -= size_t(r); offset += uint64_t(r);
  }
  return {};
}

Status pwrite_all(int fd, const void* data, size_t bytes, uint64_t offset, const std::filesystem::path& path) {
  const auto* p = static_cast<const char*>(data);
  while (bytes > 0) {
    ssize_t r = ::pwrite(fd, p, std::min<size_t>(bytes, size_t(1) << 30), off_t(offset));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return Status::error(path.string() + ": write failed: " + std::strerror(errno));
    p += r; bytes -= size_t(r); offset += uint64_t(r);
  }
  return {};
}

Status read_header(int fd, const std::filesystem::path& path, StoreHeader& h, Layout& l) {
  const std::string name = path.string();
  struct stat st {};
  if (::fstat(fd, &st) != 0) return Status::error(name + ": cannot stat: " + std::strerror(errno));
  const uint64_t size = uint64_t(st.st_size);
  char head[16];
  if (size < sizeof head + 4) return Status::error(name + ": not a raylod store (only " + std::to_string(size) + " bytes)");
  RAYLOD_RETURN_IF_ERROR(pread_all(fd, head, sizeof head, 0, path));
  if (std::memcmp(head, kMagic, 8) != 0) return Status::error(name + ": not a raylod store (bad magic)");
  uint32_t version = 0, blob_bytes = 0;
  std::memcpy(&version, head + 8, 4);
  std::memcpy(&blob_bytes, head + 12, 4);
  if (version != kVersion)
    return Status::error(name + ": store format version " + std::to_string(version) + ", this raylod reads version " +
                         std::to_string(kVersion) + "; rebuild it with `raylod build`");
  if (blob_bytes > (64u << 20) || sizeof head + blob_bytes + 4 > size)
    return Status::error(name + ": truncated store (header says " + std::to_string(blob_bytes) +
                         " header bytes, file has " + std::to_string(size) + ")");
  std::string bytes(sizeof head + blob_bytes + 4, '\0');
  RAYLOD_RETURN_IF_ERROR(pread_all(fd, bytes.data(), bytes.size(), 0, path));
  uint32_t stored_crc = 0;
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - 4, 4);
  if (crc32c(bytes.data(), bytes.size() - 4) != stored_crc)
    return Status::error(name + ": header checksum mismatch (the store is corrupt; rebuild it)");

  ByteReader r(bytes.data() + sizeof head, blob_bytes);
  int32_t max_depth = 0, unused_threads = 0, qd = 0, pl = 0, grid_bits = 0;
  uint8_t normals = 0, coarsened = 0;
  uint32_t levels = 0;
  h = StoreHeader{};
  h.version = version;
  bool ok = r.get_str(h.source_path) && r.get(h.source_bytes) && r.get(h.source_mtime_ns) && r.get(h.source_hash) &&
            r.get(h.options.memory_limit) && r.get(max_depth) && r.get(unused_threads) && r.get(h.options.page_triangles) &&
            r.get(h.triangle_count) && r.get(normals) && r.get(coarsened) && r.get_vec(h.origin) &&
            r.get_vec(h.root_lo) && r.get(h.root_size) && r.get(qd) && r.get(pl) && r.get_vec(h.bounds.lo) &&
            r.get_vec(h.bounds.hi) && r.get(levels);
  if (ok && qd >= 0 && levels == uint32_t(qd) + 1 && levels <= kMaxLevel + 1) {
    l.level_counts.assign(levels, 0);
    for (auto& c : l.level_counts) ok = ok && r.get(c);
  } else {
    ok = false;
  }
  ok = ok && r.get(l.node_table_offset) && r.get(l.node_table_crc) && r.get(l.node_table_bytes) && r.get(l.page_count) &&
       r.get(l.page_table_offset) && r.get(l.page_table_crc) && r.get(l.data_offset) && r.get(l.data_bytes) &&
       r.get(l.boundary_offset) && r.get(l.boundary_count) && r.get(l.boundary_crc) && r.get(l.file_bytes) &&
       r.get(h.reuse_limit_lo) && r.get(h.reuse_limit_hi) && r.get(grid_bits) && r.get_vec(h.mesh_origin) && r.at_end();
  if (!ok || pl < 0 || pl > int(kMaxLevel) || !(h.root_size > 0) || grid_bits < 1 || grid_bits > 30 ||
      !is_finite(h.mesh_origin))
    return Status::error(name + ": malformed store header");
  h.options.max_depth = max_depth;
  h.has_normals = normals != 0;
  h.coarsened = coarsened != 0;
  h.quadric_depth = qd;
  h.page_level = pl;
  h.grid_bits = grid_bits;
  h.file_bytes = l.file_bytes;
  // The header's checksum held, so its file size is the store's: a shorter
  // file was cut off (a copy or download that stopped), whatever else below
  // would then look wrong.
  if (size < l.file_bytes)
    return Status::error(name + ": truncated store (" + std::to_string(size) + " bytes, header says " +
                         std::to_string(l.file_bytes) + ")");
  // Counts and offsets are bounded by the file size before any product or
  // sum, so a header with a valid CRC but absurd numbers cannot wrap past the
  // checks below (and then make load_tables allocate from them).
  uint64_t nodes = 0;
  // Every node takes sizeof(NodeRecord) bytes on disk; a level above holds
  // at most as many nodes as the one below it.
  for (size_t i = l.level_counts.size(); i-- > 0;) {
    const uint64_t c = l.level_counts[i];
    uint64_t cap = i + 1 == l.level_counts.size() ? size / sizeof(NodeRecord) : l.level_counts[i + 1];
    cap = std::min<uint64_t>(cap, uint64_t(1) << std::min<size_t>(3 * i, 63));  // level i has at most 8^i cells
    if (c > cap || (c == 0) != (l.level_counts.back() == 0) || nodes > size / sizeof(NodeRecord))
      return Status::error(name + ": malformed store header (node counts)");
    nodes += c;
  }
  h.node_table_bytes = nodes * sizeof(NodeRecord);
  h.page_data_bytes = l.data_bytes;
  if (size > l.file_bytes)
    return Status::error(name + ": store has " + std::to_string(size) + " bytes but its header says " +
                         std::to_string(l.file_bytes) + " (corrupt)");
  auto outside = [&](uint64_t offset, uint64_t length) { return offset > l.file_bytes || length > l.file_bytes - offset; };
  const uint64_t leaves = l.level_counts.back();
  if (l.node_table_bytes != nodes * sizeof(NodeRecord) || l.node_table_offset % alignof(NodeRecord) != 0)
    return Status::error(name + ": malformed store header (node table size)");
  if (l.boundary_count > leaves || l.boundary_offset % alignof(uint64_t) != 0)
    return Status::error(name + ": malformed store header (boundary list)");
  if (l.page_count > l.file_bytes / sizeof(PageInfo) || outside(l.node_table_offset, l.node_table_bytes) ||
      outside(l.page_table_offset, l.page_count * sizeof(PageInfo)) || outside(l.data_offset, l.data_bytes) ||
      l.boundary_offset < l.data_offset + l.data_bytes || l.boundary_offset - (l.data_offset + l.data_bytes) >= 8 ||
      outside(l.boundary_offset, l.boundary_count * 8) ||
      l.boundary_offset + l.boundary_count * 8 != l.file_bytes)
    return Status::error(name + ": malformed store header (tables outside the file)");
  return {};
}

}  // namespace store_format

namespace {

using namespace store_format;

constexpr char kRecordTitle[] = "raylod store corruption record";

std::string file_identity(dev_t dev, ino_t ino) {
  return std::to_string(uint64_t(dev)) + ":" + std::to_string(uint64_t(ino));
}

// The record names the store file by device and inode: a rebuilt store is a
// new file (renamed into place), so a record about the old one stops applying.
Status write_record(const std::filesystem::path& store, const std::string& identity, const std::string& what) {
  std::string text = std::string(kRecordTitle) + "\nstore " + store.string() + "\nfile " + identity + "\n" + what + "\n";
  return write_file_atomic(corruption_record_path(store), text);
}

class FileStore final : public OctreeStore {
 public:
  ~FileStore() override {
    if (mapping_) ::munmap(mapping_, mapping_bytes_);
    if (fd_ >= 0) ::close(fd_);
  }

  static StatusOr<std::unique_ptr<OctreeStore>> open_file(const std::filesystem::path& path) {
    auto store = std::make_unique<FileStore>();
    store->path_ = path;
    RAYLOD_RETURN_IF_ERROR(check_regular_file(path));  // a FIFO would block the open
    store->fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (store->fd_ < 0) return Status::error(path.string() + ": cannot open store: " + std::strerror(errno));
    RAYLOD_RETURN_IF_ERROR(read_header(store->fd_, path, store->header_, store->layout_));
    RAYLOD_RETURN_IF_ERROR(store->load_tables());
    store->grid_ = page_grid(store->header_.root_lo, store->header_.root_size, store->header_.grid_bits);
    return std::unique_ptr<OctreeStore>(std::move(store));
  }

  const StoreHeader& header() const override { return header_; }

  std::span<const NodeRecord> level(int level) const override {
    if (level < 0 || level > header_.quadric_depth || !nodes_) return {};
    return std::span<const NodeRecord>(nodes_ + level_begin_[size_t(level)], nodes_ + level_begin_[size_t(level) + 1]);
  }

  const NodeRecord* find(const CellKey& key) const override {
    auto nodes = level(int(key.level));
    auto it = std::lower_bound(nodes.begin(), nodes.end(), key.code,
                               [](const NodeRecord& n, uint64_t code) { return n.code < code; });
    return it != nodes.end() && it->code == key.code ? &*it : nullptr;
  }

  std::span<const PageInfo> pages() const override { return pages_; }

  bool touches_boundary(const CellKey& key) const override {
    const int q = header_.quadric_depth;
    if (int(key.level) > q) return false;
    const int shift = 3 * (q - int(key.level));
    const uint64_t lo = key.code << shift, end = (key.code + 1) << shift;
    auto it = std::lower_bound(boundary_.begin(), boundary_.end(), lo);
    return it != boundary_.end() && *it < end;
  }
  uint64_t boundary_leaves() const override { return boundary_.size(); }

  Status read_page(size_t i, TriangleBatch& batch) const override {
    return read_decoded(i, batch, decode_page, [](const TriangleBatch& b) { return !b.normals.empty(); });
  }

  Status read_page(size_t i, PageMesh& page) const override {
    return read_decoded(i, page, decode_page_mesh, [](const PageMesh& p) { return !p.normal_codes.empty(); });
  }

  bool found_corruption() const override { return found_corruption_; }

 private:
  // Page i read, checked and decoded into `out` (cleared first) by `decode`
  // (decode_page or decode_page_mesh).
  template <class Out, class Decode, class HasNormals>
  Status read_decoded(size_t i, Out& out, Decode decode, HasNormals has_normals) const {
    out.clear();
    thread_local std::vector<uint8_t> bytes;
    RAYLOD_RETURN_IF_ERROR(read_checked_page(i, bytes));
    // A page whose checksum matches but does not decode was written wrong
    // (or deliberately altered): an error, but not a record of corruption.
    // The page's own counts first: decoding sizes its output from them.
    const PageInfo& page = pages_[i];
    Status decoded = page_counts(bytes).triangles == page.triangle_count
                         ? decode(bytes, grid_, out)
                         : Status::error("its triangle count is not the page table's");
    if (decoded.is_ok() && (out.size() != page.triangle_count || has_normals(out) != header_.has_normals))
      decoded = Status::error("its counts do not match the page table");
    if (!decoded.is_ok()) {
      out.clear();
      return Status::error(path_.string() + ": page " + std::to_string(i) + " is malformed: " + decoded.message());
    }
    return {};
  }

  // Page i's bytes, read and checked against the page table's checksum (a
  // mismatch is recorded beside the store).
  Status read_checked_page(size_t i, std::vector<uint8_t>& bytes) const {
    if (i >= pages_.size())
      return Status::error(path_.string() + ": page " + std::to_string(i) + " out of range (" +
                           std::to_string(pages_.size()) + " pages)");
    const PageInfo& page = pages_[i];
    bytes.resize(size_t(page.bytes));
    RAYLOD_RETURN_IF_ERROR(pread_all(fd_, bytes.data(), bytes.size(), page.offset, path_));
    const uint32_t crc = crc32c(bytes.data(), bytes.size());
    if (crc != page.checksum) {
      char code[32];
      std::snprintf(code, sizeof code, "%" PRIx64, page.code);
      const std::string what = "page " + std::to_string(i) + " (cell " + code + ") checksum mismatch";
      // Recorded once per opened store (a corrupt page may be asked for by every thread).
      std::string note = "recorded in " + corruption_record_path(path_).string() + "; `raylod build` rebuilds it";
      if (!found_corruption_.exchange(true)) {
        struct stat st {};
        Status recorded = ::fstat(fd_, &st) == 0 ? write_record(path_, file_identity(st.st_dev, st.st_ino), what)
                                                 : Status::error(std::strerror(errno));
        if (!recorded) note = "could not record it: " + recorded.message() + "; rebuild it with `raylod build --force`";
      }
      return Status::error(path_.string() + ": " + what + " (the store is corrupt; " + note + ")");
    }
    return {};
  }

  Status load_tables() {
    const std::string name = path_.string();
    uint64_t total = 0;
    level_begin_.assign(1, 0);
    for (uint64_t c : layout_.level_counts) level_begin_.push_back(total += c);
    RAYLOD_RETURN_IF_ERROR(map_node_table(total));
    pages_.resize(layout_.page_count);
    RAYLOD_RETURN_IF_ERROR(pread_all(fd_, pages_.data(), pages_.size() * sizeof(PageInfo), layout_.page_table_offset, path_));
    if (crc32c(pages_.data(), pages_.size() * sizeof(PageInfo)) != layout_.page_table_crc)
      return Status::error(name + ": page table checksum mismatch (the store is corrupt; rebuild it)");
    // Cheap structural checks so that later code can trust the tables.
    uint64_t expect = layout_.data_offset, triangles = 0;
    for (size_t i = 0; i < pages_.size(); ++i) {
      const auto& p = pages_[i];
      // A page of n triangles has at least 24 + 3n/8 bytes (indices take at
      // least one bit) and at most 24 + 3n x (12 + 4 + 4) bytes.
      const uint64_t n = p.triangle_count;
      const uint64_t data_end = layout_.data_offset + layout_.data_bytes;
      if (p.offset != expect || (i > 0 && pages_[i - 1].code >= p.code) || p.bytes > data_end - expect ||
          p.bytes < 24 + (3 * n + 7) / 8 || p.bytes > 24 + 60 * n)
        return Status::error(name + ": page table is inconsistent at page " + std::to_string(i));
      expect += p.bytes;
      triangles += p.triangle_count;
    }
    if (expect != layout_.data_offset + layout_.data_bytes || triangles != header_.triangle_count)
      return Status::error(name + ": page table does not cover the page data (corrupt)");
    const int depth = header_.quadric_depth;
    for (int l = 0; l <= depth; ++l) {
      auto lv = level(l);
      for (size_t i = 1; i < lv.size(); ++i)
        if (lv[i - 1].code >= lv[i].code)
          return Status::error(name + ": level " + std::to_string(l) + " of the node table is not sorted (corrupt)");
      // Level l has 8^l cells (l <= 21: a shift of at most 63).
      if (!lv.empty() && (lv.back().code >> (3 * l)) != 0)
        return Status::error(name + ": level " + std::to_string(l) + " of the node table has a code out of range (corrupt)");
      if (l > 0 && !parents_match(level(l - 1), lv))
        return Status::error(name + ": level " + std::to_string(l - 1) +
                             " of the node table is not the parents of level " + std::to_string(l) + " (corrupt)");
    }
    boundary_.resize(layout_.boundary_count);
    RAYLOD_RETURN_IF_ERROR(pread_all(fd_, boundary_.data(), boundary_.size() * 8, layout_.boundary_offset, path_));
    if (crc32c(boundary_.data(), boundary_.size() * 8) != layout_.boundary_crc)
      return Status::error(name + ": boundary list checksum mismatch (the store is corrupt; rebuild it)");
    for (size_t i = 0; i < boundary_.size(); ++i) {
      const bool sorted = i == 0 || boundary_[i - 1] < boundary_[i];
      if (!sorted || !find(CellKey{uint32_t(depth), boundary_[i]}))
        return Status::error(name + ": boundary list is not a sorted list of leaves (corrupt)");
    }
    return {};
  }

  // The node table, mapped read-only where it lies in the file: the pages
  // come from the page cache, shared by every process that opens the store,
  // and nothing is decoded or copied. Where the file cannot be mapped it is
  // read into memory instead. Either way its checksum is checked. Stores are
  // replaced by rename, never rewritten in place, so a mapping stays valid
  // (on the file it was made from) while the store is open.
  Status map_node_table(uint64_t nodes) {
    const std::string name = path_.string();
    const uint64_t bytes = layout_.node_table_bytes;  // nodes * sizeof(NodeRecord) (read_header)
    if (bytes == 0) return {};
    const uint64_t page = uint64_t(::sysconf(_SC_PAGESIZE));
    const uint64_t start = layout_.node_table_offset / page * page;
#ifdef MAP_POPULATE
    const int flags = MAP_SHARED | MAP_POPULATE;  // the checksum reads it all at once anyway
#else
    const int flags = MAP_SHARED;
#endif
    void* mapped = ::mmap(nullptr, size_t(layout_.node_table_offset - start + bytes), PROT_READ, flags, fd_, off_t(start));
    if (mapped != MAP_FAILED) {
      mapping_ = mapped;
      mapping_bytes_ = size_t(layout_.node_table_offset - start + bytes);
      nodes_ = reinterpret_cast<const NodeRecord*>(static_cast<const char*>(mapped) + (layout_.node_table_offset - start));
    } else {
      read_nodes_.resize(size_t(nodes));
      RAYLOD_RETURN_IF_ERROR(pread_all(fd_, read_nodes_.data(), size_t(bytes), layout_.node_table_offset, path_));
      nodes_ = read_nodes_.data();
    }
    if (crc32c(nodes_, size_t(bytes)) != layout_.node_table_crc)
      return Status::error(name + ": node table checksum mismatch (the store is corrupt; rebuild it)");
    return {};
  }

  std::filesystem::path path_;
  int fd_ = -1;
  StoreHeader header_;
  Layout layout_;
  const NodeRecord* nodes_ = nullptr;   // every level in turn: mapped (mapping_), or read_nodes_
  void* mapping_ = nullptr;
  size_t mapping_bytes_ = 0;
  std::vector<NodeRecord> read_nodes_;
  std::vector<uint64_t> boundary_;  // codes of the leaves holding an open boundary's vertex, sorted
  std::vector<uint64_t> level_begin_;
  std::vector<PageInfo> pages_;
  PageGrid grid_;
  mutable std::atomic<bool> found_corruption_{false};
};

uint64_t spread3(uint32_t v) {
  uint64_t x = v & 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffull;
  x = (x | x << 16) & 0x1f0000ff0000ffull;
  x = (x | x << 8) & 0x100f00f00f00f00full;
  x = (x | x << 4) & 0x10c30c30c30c30c3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

uint32_t compact3(uint64_t x) {
  x &= 0x1249249249249249ull;
  x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ull;
  x = (x ^ (x >> 4)) & 0x100f00f00f00f00full;
  x = (x ^ (x >> 8)) & 0x1f0000ff0000ffull;
  x = (x ^ (x >> 16)) & 0x1f00000000ffffull;
  x = (x ^ (x >> 32)) & 0x1fffffull;
  return uint32_t(x);
}

}  // namespace

StatusOr<std::unique_ptr<OctreeStore>> OctreeStore::open(const std::filesystem::path& path) {
  return FileStore::open_file(path);
}

uint64_t morton_encode(uint32_t x, uint32_t y, uint32_t z) { return spread3(x) | spread3(y) << 1 | spread3(z) << 2; }

void morton_decode(uint64_t code, uint32_t& x, uint32_t& y, uint32_t& z) {
  x = compact3(code);
  y = compact3(code >> 1);
  z = compact3(code >> 2);
}

CellKey cell_in_cube(const Vec3d& p, const Vec3d& root_lo, double root_size, int level) {
  const double n = double(uint64_t(1) << level);
  const double size = root_size / n;
  auto coord = [&](double v, double lo) {
    double t = std::floor((v - lo) / size);
    return uint32_t(std::clamp(t, 0.0, n - 1));
  };
  return {uint32_t(level), morton_encode(coord(p.x, root_lo.x), coord(p.y, root_lo.y), coord(p.z, root_lo.z))};
}

CellKey OctreeStore::cell_of(const Vec3d& p, int level) const {
  return cell_in_cube(p, header().root_lo, header().root_size, level);
}

Bbox OctreeStore::cell_bounds(const CellKey& key) const {
  uint32_t x, y, z;
  morton_decode(key.code, x, y, z);
  const double s = cell_size(int(key.level));
  Vec3d lo = header().root_lo + Vec3d(x, y, z) * s;
  return Bbox{lo, lo + Vec3d(s)};
}

std::filesystem::path default_store_path(const std::filesystem::path& mesh) {
  std::filesystem::path p = mesh;
  p += ".raylod";
  return p;
}

std::filesystem::path corruption_record_path(const std::filesystem::path& store) {
  std::filesystem::path p = store;
  p += ".corrupt";
  return p;
}

Status record_store_corruption(const std::filesystem::path& store, const std::string& what) {
  struct stat st {};
  if (::stat(store.c_str(), &st) != 0) return Status::error(store.string() + ": " + std::strerror(errno));
  return write_record(store, file_identity(st.st_dev, st.st_ino), what);
}

std::optional<std::string> store_corruption(const std::filesystem::path& store) {
  struct stat st {};
  if (::stat(store.c_str(), &st) != 0) return std::nullopt;
  std::ifstream in(corruption_record_path(store));
  if (!in) return std::nullopt;
  std::string title, store_line, file_line, what;
  std::getline(in, title);
  std::getline(in, store_line);
  std::getline(in, file_line);
  std::getline(in, what);
  // An unreadable or foreign record is kept as a finding: rebuilding is the safe side.
  if (title != kRecordTitle || file_line.rfind("file ", 0) != 0)
    return "unreadable corruption record " + corruption_record_path(store).string();
  if (file_line.substr(5) != file_identity(st.st_dev, st.st_ino)) return std::nullopt;  // about a replaced store
  return what;
}

StatusOr<uint64_t> verify_store_pages(const std::filesystem::path& store) {
  RAYLOD_ASSIGN_OR_RETURN(auto opened, OctreeStore::open(store));
  TriangleBatch batch;
  const size_t n = opened->pages().size();
  for (size_t i = 0; i < n; ++i) RAYLOD_RETURN_IF_ERROR(opened->read_page(i, batch));
  return uint64_t(n);
}

bool is_store_file(const std::filesystem::path& path) {
  if (!check_regular_file(path)) return false;
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  char magic[8];
  bool ok = ::pread(fd, magic, 8, 0) == 8 && std::memcmp(magic, kMagic, 8) == 0;
  ::close(fd);
  return ok;
}

Status print_store_info(const std::filesystem::path& path, std::FILE* out) {
  RAYLOD_ASSIGN_OR_RETURN(auto store, OctreeStore::open(path));
  const StoreHeader& h = store->header();
  auto pages = store->pages();
  std::fprintf(out, "%s: raylod octree store, format version %u\n", path.string().c_str(), h.version);
  std::fprintf(out, "  source        %s (%s, content hash %016" PRIx64 ")\n", h.source_path.c_str(),
               format_bytes(h.source_bytes).c_str(), h.source_hash);
  std::fprintf(out, "  build options --memory-limit %s --max-depth %d (page target %u triangles)\n",
               describe_memory_limit(h.options.memory_limit).c_str(), h.options.max_depth, h.options.page_triangles);
  std::fprintf(out, "  reused under  --memory-limit %s to %s (a build under any limit in between makes this store)\n",
               format_bytes(h.reuse_limit_lo).c_str(),
               h.reuse_limit_hi == UINT64_MAX ? "any larger" : format_bytes(h.reuse_limit_hi).c_str());
  std::fprintf(out, "  triangles     %" PRIu64 "%s\n", h.triangle_count, h.has_normals ? " (with vertex normals)" : "");
  std::fprintf(out, "  bounds        [%.9g %.9g %.9g] - [%.9g %.9g %.9g]%s\n", h.bounds.lo.x, h.bounds.lo.y,
               h.bounds.lo.z, h.bounds.hi.x, h.bounds.hi.y, h.bounds.hi.z,
               h.mesh_origin == Vec3d(0) ? "" : " (store coordinates, relative to the mesh origin)");
  if (h.mesh_origin != Vec3d(0))
    std::fprintf(out, "  mesh origin   [%.12g %.12g %.12g] (the mesh lies far from zero; its coordinates are kept "
                      "relative to this point)\n",
                 h.mesh_origin.x, h.mesh_origin.y, h.mesh_origin.z);
  std::fprintf(out, "  root cube     corner [%.9g %.9g %.9g], side %.9g; quadric origin [%.9g %.9g %.9g]\n",
               h.root_lo.x, h.root_lo.y, h.root_lo.z, h.root_size, h.origin.x, h.origin.y, h.origin.z);
  std::fprintf(out, "  levels        0..%d with quadrics%s; pages at level %d\n", h.quadric_depth,
               h.coarsened ? " (lowered during the build to fit the memory limit)" : "", h.page_level);
  std::fprintf(out, "  %5s %12s %12s %14s\n", "level", "nodes", "cell size", "quadric mem");
  uint64_t nodes = 0;
  for (int l = 0; l <= h.quadric_depth; ++l) {
    const uint64_t n = store->level(l).size();
    nodes += n;
    std::fprintf(out, "  %5d %12" PRIu64 " %12.6g %14s\n", l, n, store->cell_size(l),
                 format_bytes(n * sizeof(NodeRecord)).c_str());
  }
  std::vector<uint32_t> counts;
  counts.reserve(pages.size());
  for (const auto& p : pages) counts.push_back(p.triangle_count);
  std::sort(counts.begin(), counts.end());
  std::fprintf(out, "  nodes         %" PRIu64 " (quadric memory %s)\n", nodes, format_bytes(h.node_table_bytes).c_str());
  std::fprintf(out, "  boundary      %" PRIu64 " leaves hold a vertex of an open boundary (a hole's or an open surface's rim)\n",
               store->boundary_leaves());
  if (!counts.empty())
    std::fprintf(out, "  pages         %zu, triangles per page min %u / median %u / max %u\n", counts.size(),
                 counts.front(), counts[counts.size() / 2], counts.back());
  std::fprintf(out, "  bytes         %s total: node table %s (every level, mapped on open), "
                    "page table %s, page data %s\n",
               format_bytes(h.file_bytes).c_str(), format_bytes(h.node_table_bytes).c_str(),
               format_bytes(pages.size() * sizeof(PageInfo)).c_str(), format_bytes(h.page_data_bytes).c_str());
  if (h.triangle_count > 0)
    std::fprintf(out, "  page data     %.1f bytes per triangle; positions on a grid of %.6g (2^-%d of the root side, "
                      "1/%.0f of the finest cell), within %.3g of the input\n",
                 double(h.page_data_bytes) / double(h.triangle_count), std::ldexp(h.root_size, -h.grid_bits), h.grid_bits,
                 std::ldexp(1.0, h.grid_bits - h.quadric_depth),
                 page_grid_max_error(page_grid(h.root_lo, h.root_size, h.grid_bits)));
  return {};
}

}  // namespace raylod
