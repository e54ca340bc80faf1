// The cut file: a small versioned binary file.
//
//   offset 0   8 bytes  magic "RLODCUT\x1a"
//          8   u32      format version (1)
//         12   u32      reserved (0)
//         16   u64      payload size in bytes
//         24   u64      FNV-1a 64 of the payload
//         32   payload  (all integers and floats little-endian)
//
// payload: u64 store_hash, str store_path, str key, u64 rays, u64 seed,
// f64 footprint_scale, f32 min_footprint, u32 counter count, then per counter
// (str name, u64 value), u64 cell count, then per cell (u32 level, u64 code,
// f32 min_footprint, u32 hits). str = u32 length + bytes.
#include "streaming/cut_file.h"

#include <bit>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

#include "core/fault_point.h"
#include "core/system.h"

namespace raylod {

namespace {

constexpr char kMagic[8] = {'R', 'L', 'O', 'D', 'C', 'U', 'T', '\x1a'};
constexpr uint32_t kVersion = 1;
constexpr size_t kHeaderBytes = 32;
constexpr uint64_t kMaxPayload = uint64_t(1) << 34;  // 16 GiB: anything larger is corrupt

static_assert(std::endian::native == std::endian::little, "cut_file.cpp assumes a little-endian host");

struct Writer {
  std::string bytes;
  template <class T>
  void pod(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    bytes.append(b, sizeof(T));
  }
  void str(const std::string& s) {
    pod(uint32_t(s.size()));
    bytes += s;
  }
};

struct Reader {
  const std::string& bytes;
  size_t pos = 0;
  bool ok = true;
  template <class T>
  T pod() {
    T v{};
    if (pos + sizeof(T) > bytes.size()) { ok = false; return v; }
    std::memcpy(&v, bytes.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
  std::string str() {
    uint32_t n = pod<uint32_t>();
    if (!ok || pos + n > bytes.size()) { ok = false; return {}; }
    std::string s = bytes.substr(pos, n);
    pos += n;
    return s;
  }
};

}  // namespace

Status write_cut(const std::filesystem::path& path, const Cut& cut) {
  Writer w;
  w.pod(cut.store_hash);
  w.str(cut.store_path);
  w.str(cut.key);
  w.pod(cut.rays);
  w.pod(cut.seed);
  w.pod(cut.footprint_scale);
  w.pod(cut.min_footprint);
  w.pod(uint32_t(cut.counters.size()));
  for (const auto& [name, value] : cut.counters) {
    w.str(name);
    w.pod(value);
  }
  w.pod(uint64_t(cut.cells.size()));
  for (const CollapsedCell& c : cut.cells) {
    w.pod(c.key.level);
    w.pod(c.key.code);
    w.pod(c.min_footprint);
    w.pod(c.hits);
  }
  Writer h;
  h.bytes.append(kMagic, sizeof(kMagic));
  h.pod(kVersion);
  h.pod(uint32_t(0));
  h.pod(uint64_t(w.bytes.size()));
  h.pod(fnv1a64(w.bytes.data(), w.bytes.size()));

  std::error_code ec;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  AtomicOutput out(path);
  RAYLOD_RETURN_IF_ERROR(write_temporary(out, {std::string_view(h.bytes), std::string_view(w.bytes)}));
  fault_point("cut.before_rename");
  return out.commit().with_context(path.string());
}

bool is_cut_file(const std::filesystem::path& path) {
  if (!check_regular_file(path)) return false;  // a FIFO would block the open
  std::ifstream f(path, std::ios::binary);
  char m[sizeof(kMagic)];
  if (!f.read(m, sizeof(m))) return false;
  return std::memcmp(m, kMagic, sizeof(kMagic)) == 0;
}

StatusOr<Cut> read_cut(const std::filesystem::path& path) {
  const std::string name = path.string();
  RAYLOD_RETURN_IF_ERROR(check_regular_file(path));
  std::ifstream f(path, std::ios::binary);
  if (!f) return Status::error(name + ": cannot open cut file");
  std::string header(kHeaderBytes, '\0');
  if (!f.read(header.data(), std::streamsize(kHeaderBytes)))
    return Status::error(name + ": not a cut file (shorter than its header)");
  if (std::memcmp(header.data(), kMagic, sizeof(kMagic)) != 0) return Status::error(name + ": not a cut file (bad magic)");
  Reader hr{header, sizeof(kMagic)};
  const uint32_t version = hr.pod<uint32_t>();
  hr.pod<uint32_t>();
  const uint64_t size = hr.pod<uint64_t>();
  const uint64_t checksum = hr.pod<uint64_t>();
  if (version != kVersion)
    return Status::error(name + ": cut file version " + std::to_string(version) + " is not supported (expected " +
                         std::to_string(kVersion) + "); run raylod probe again");
  if (size > kMaxPayload) return Status::error(name + ": corrupt cut file (payload size " + std::to_string(size) + ")");
  // Check the claimed size against the file before allocating it: a damaged
  // header must not make a small file cost gigabytes of memory.
  std::error_code ec;
  const uint64_t file_bytes = std::filesystem::file_size(path, ec);
  if (ec) return Status::error(name + ": cannot read the cut file's size: " + ec.message());
  if (file_bytes < kHeaderBytes || size > file_bytes - kHeaderBytes)
    return Status::error(name + ": truncated cut file (expected " + std::to_string(size) + " payload bytes, the file has " +
                         std::to_string(file_bytes - kHeaderBytes) + ")");
  std::string payload(size, '\0');
  if (!f.read(payload.data(), std::streamsize(size)))
    return Status::error(name + ": truncated cut file (expected " + std::to_string(size) + " payload bytes)");
  if (f.peek() != std::char_traits<char>::eof()) return Status::error(name + ": corrupt cut file (trailing bytes)");
  if (fnv1a64(payload.data(), payload.size()) != checksum) return Status::error(name + ": corrupt cut file (checksum mismatch)");

  Cut cut;
  cut.version = version;
  Reader r{payload};
  cut.store_hash = r.pod<uint64_t>();
  cut.store_path = r.str();
  cut.key = r.str();
  cut.rays = r.pod<uint64_t>();
  cut.seed = r.pod<uint64_t>();
  cut.footprint_scale = r.pod<double>();
  cut.min_footprint = r.pod<float>();
  const uint32_t counters = r.pod<uint32_t>();
  for (uint32_t i = 0; i < counters && r.ok; ++i) {
    std::string key = r.str();
    cut.counters[key] = r.pod<uint64_t>();
  }
  const uint64_t cells = r.pod<uint64_t>();
  if (!r.ok || cells > (payload.size() - r.pos) / 20) return Status::error(name + ": corrupt cut file (cell count)");
  cut.cells.resize(cells);
  for (CollapsedCell& c : cut.cells) {
    c.key.level = r.pod<uint32_t>();
    c.key.code = r.pod<uint64_t>();
    c.min_footprint = r.pod<float>();
    c.hits = r.pod<uint32_t>();
  }
  if (!r.ok || r.pos != payload.size()) return Status::error(name + ": corrupt cut file (payload layout)");
  // The cut must be an antichain of valid cells, sorted by key.
  std::set<CellKey> seen;
  for (size_t i = 0; i < cut.cells.size(); ++i) {
    const CellKey k = cut.cells[i].key;
    if (k.level > 21 || (k.level < 21 && (k.code >> (3 * k.level)) != 0))
      return Status::error(name + ": corrupt cut file (cell " + std::to_string(i) + " is not a valid octree cell)");
    if (i > 0 && !(cut.cells[i - 1].key < k)) return Status::error(name + ": corrupt cut file (cells not sorted)");
    for (CellKey a = k; a.level > 0;) {
      a = a.parent();
      if (seen.count(a))
        return Status::error(name + ": corrupt cut file (cell " + std::to_string(i) + " lies inside another marked cell)");
    }
    seen.insert(k);
  }
  return cut;
}

Status print_cut_info(const std::filesystem::path& path, std::FILE* out) {
  auto cut = read_cut(path);
  if (!cut) return cut.status();
  const Cut& c = *cut;
  std::fprintf(out, "%s: raylod cut (format version %u)\n", path.string().c_str(), c.version);
  std::fprintf(out, "  store:            %s (fingerprint %016llx)\n", c.store_path.c_str(),
               static_cast<unsigned long long>(c.store_hash));
  std::fprintf(out, "  key:              %s\n", c.key.c_str());
  std::fprintf(out, "  test rays:        %llu (seed %llu), footprint scale K = %g\n",
               static_cast<unsigned long long>(c.rays), static_cast<unsigned long long>(c.seed), c.footprint_scale);
  std::fprintf(out, "  min footprint:    %g\n", double(c.min_footprint));
  std::map<uint32_t, std::pair<uint64_t, uint64_t>> per_level;  // level -> (cells, cells with hits)
  for (const CollapsedCell& cell : c.cells) {
    auto& e = per_level[cell.key.level];
    ++e.first;
    if (cell.hits > 0) ++e.second;
  }
  std::fprintf(out, "  cells marked:     %zu\n", c.cells.size());
  for (const auto& [level, e] : per_level)
    std::fprintf(out, "    level %2u: %10llu cells (%llu with test-ray hits, %llu by the unreached-cell policy)\n", level,
                 static_cast<unsigned long long>(e.first), static_cast<unsigned long long>(e.second),
                 static_cast<unsigned long long>(e.first - e.second));
  std::fprintf(out, "  counters:\n");
  for (const auto& [name, value] : c.counters)
    std::fprintf(out, "    %-28s %llu\n", name.c_str(), static_cast<unsigned long long>(value));
  return {};
}

}  // namespace raylod
