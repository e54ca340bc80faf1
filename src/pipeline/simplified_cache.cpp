#include "pipeline/simplified_cache.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/fault_point.h"
#include "core/system.h"

namespace raylod {
namespace fs = std::filesystem;

namespace {

// flock() on the cache's lock file for the lifetime of the object; serialises
// index changes between concurrent runs (readers and writers alike: entries
// are small and the critical sections short).
class CacheLock {
 public:
  explicit CacheLock(const fs::path& dir) {
    fd_ = ::open((dir / "lock").c_str(), O_RDWR | O_CREAT, 0644);
    // A cache this user may only read: its lock file opened for reading
    // locks as well (flock does not need write access).
    if (fd_ < 0) fd_ = ::open((dir / "lock").c_str(), O_RDONLY);
    if (fd_ >= 0) ::flock(fd_, LOCK_EX);
  }
  ~CacheLock() {
    if (fd_ >= 0) { ::flock(fd_, LOCK_UN); ::close(fd_); }
  }
  CacheLock(const CacheLock&) = delete;
  CacheLock& operator=(const CacheLock&) = delete;

 private:
  int fd_ = -1;
};

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string hex64(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)v);
  return buf;
}

std::optional<CacheEntry> read_meta(const fs::path& json_path) {
  std::ifstream in(json_path);
  if (!in) return std::nullopt;
  try {
    nlohmann::json j = nlohmann::json::parse(in);
    CacheEntry e;
    e.key = j.at("key").get<std::string>();
    e.store_hash = std::stoull(j.at("store_hash").get<std::string>(), nullptr, 16);
    e.content_hash = std::stoull(j.at("content_hash").get<std::string>(), nullptr, 16);
    e.triangles = j.at("triangles").get<uint64_t>();
    e.footprint_scale = j.at("footprint_scale").get<double>();
    e.max_position_error = j.at("max_position_error").get<double>();
    e.crease_angle_deg = j.contains("crease_angle") ? j.at("crease_angle").get<double>()
                                                    : std::numeric_limits<double>::quiet_NaN();
    e.exact_normals = j.contains("exact_normals") && j.at("exact_normals").get<bool>();
    e.normal_bits = j.contains("normal_bits") ? j.at("normal_bits").get<int>() : 0;
    e.position_bits = j.contains("position_bits") ? j.at("position_bits").get<int>() : 0;
    e.last_used_ns = j.at("last_used_ns").get<int64_t>();
    fs::path dir = json_path.parent_path();
    e.mesh = dir / (e.key + ".drc");
    e.cut = dir / (e.key + ".cut");
    std::error_code ec;
    e.bytes = fs::file_size(json_path, ec);
    if (auto s = fs::file_size(e.mesh, ec); !ec) e.bytes += s;
    if (auto s = fs::file_size(e.cut, ec); !ec) e.bytes += s;
    return e;
  } catch (...) {
    return std::nullopt;
  }
}

Status write_meta(const fs::path& dir, const CacheEntry& e) {
  nlohmann::json j;
  j["key"] = e.key;
  j["store_hash"] = hex64(e.store_hash);
  j["content_hash"] = hex64(e.content_hash);
  j["triangles"] = e.triangles;
  j["footprint_scale"] = e.footprint_scale;
  j["max_position_error"] = e.max_position_error;
  j["crease_angle"] = e.crease_angle_deg;
  j["exact_normals"] = e.exact_normals;
  j["normal_bits"] = e.normal_bits;
  j["position_bits"] = e.position_bits;
  j["last_used_ns"] = e.last_used_ns;
  return write_file_atomic(dir / (e.key + ".json"), j.dump(2) + "\n");
}

void remove_entry_files(const fs::path& dir, const std::string& key) {
  std::error_code ec;
  for (const char* ext : {".json", ".drc", ".cut"}) fs::remove(dir / (key + ext), ec);
}

// Verifies an entry's files are all there and the mesh matches its hash.
bool verify(const CacheEntry& e, std::string* why) {
  std::error_code ec;
  if (!fs::is_regular_file(e.mesh, ec) || !fs::is_regular_file(e.cut, ec)) {
    if (why) *why = "entry " + e.key + " is incomplete";
    return false;
  }
  auto h = hash_file(e.mesh);
  if (!h.is_ok() || *h != e.content_hash) {
    if (why) *why = "entry " + e.key + " is corrupt (content hash mismatch)";
    return false;
  }
  return true;
}

}  // namespace

StatusOr<uint64_t> hash_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::error(path.string() + ": cannot open");
  std::vector<char> buf(1 << 20);
  uint64_t h = 0xcbf29ce484222325ull;
  while (in) {
    in.read(buf.data(), std::streamsize(buf.size()));
    h = fnv1a64(buf.data(), size_t(in.gcount()), h);
  }
  return h;
}

bool cut_is_at_least_as_fine(const Cut& cached, const Cut& wanted, std::string* reason) {
  if (cached.store_hash != wanted.store_hash) {
    if (reason) *reason = "made from another store";
    return false;
  }
  // Both cuts are sorted antichains; a cached cell is fine if some wanted
  // cell is itself or one of its ancestors. Look ancestors up in a set.
  std::set<CellKey> wanted_cells;
  for (const auto& c : wanted.cells) wanted_cells.insert(c.key);
  for (const auto& c : cached.cells) {
    bool covered = false;
    for (CellKey k = c.key;; k = k.parent()) {
      if (wanted_cells.count(k)) { covered = true; break; }
      if (k.level == 0) break;
    }
    if (!covered) {
      if (reason) {
        *reason = "cell (level " + std::to_string(c.key.level) + ", code " + std::to_string(c.key.code) +
                  ") is collapsed there but the new view needs it finer";
      }
      return false;
    }
  }
  return true;
}

StatusOr<SimplifiedCache> SimplifiedCache::open(const fs::path& dir, uint64_t size_limit) {
  std::error_code ec;
  fs::create_directories(dir / "simplified", ec);
  if (ec) return Status::error(dir.string() + ": cannot create cache directory: " + ec.message());
  // Leftovers of killed runs (kill -9, a crash) go now, not an hour later
  // (evict): temporaries of processes that no longer exist (staged
  // simplified meshes, half-written .drc, .cut and .json files), and an
  // insert's staged copy, which is made and renamed under the lock, so one
  // seen under the lock was left by a dead process.
  CacheLock lock(dir);
  for (const auto& f : fs::directory_iterator(dir / "simplified", ec)) {
    const std::string name = f.path().filename().string();
    const bool insert_copy = name.size() > 11 && name.compare(name.size() - 11, 11, ".tmp-insert") == 0;
    std::error_code rm;
    if (insert_copy || is_dead_process_temporary(name)) fs::remove(f.path(), rm);
  }
  return SimplifiedCache(dir, size_limit);
}

std::string SimplifiedCache::key_for(const Cut& cut, double crease_angle_deg, bool exact_normals, int normal_bits) {
  // Version 2 of the normal rule: crease-angle normals (geometry/crease_normals.h);
  // 3: the same with exact normals at representatives (simplify/collapse.h);
  // 4: exact normals, and fold passes (which come with them in raylod run)
  // take back a refinement that leaves no fewer triangles turned over;
  // 5 and 6: 2 and 4 with turned-over triangles unfolded (simplify/unfold.h).
  const uint32_t normal_rule = exact_normals ? 6 : 5;
  uint64_t h = fnv1a64(&cut.store_hash, sizeof cut.store_hash);
  h = fnv1a64(&normal_rule, sizeof normal_rule, h);
  h = fnv1a64(&crease_angle_deg, sizeof crease_angle_deg, h);
  if (normal_bits != 0) h = fnv1a64(&normal_bits, sizeof normal_bits, h);
  for (const auto& c : cut.cells) {
    h = fnv1a64(&c.key.level, sizeof c.key.level, h);
    h = fnv1a64(&c.key.code, sizeof c.key.code, h);
  }
  return hex64(cut.store_hash).substr(0, 8) + "-" + hex64(h);
}

std::vector<CacheEntry> SimplifiedCache::entries() const {
  std::vector<CacheEntry> out;
  std::error_code ec;
  for (const auto& f : fs::directory_iterator(dir_ / "simplified", ec)) {
    if (f.path().extension() != ".json") continue;
    if (auto e = read_meta(f.path())) out.push_back(*e);
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.key < b.key; });
  return out;
}

std::optional<CacheEntry> SimplifiedCache::find_exact(const std::string& key, std::string* note) {
  CacheLock lock(dir_);
  auto e = read_meta(dir_ / "simplified" / (key + ".json"));
  if (!e) return std::nullopt;
  std::string why;
  if (!verify(*e, &why)) {
    remove_entry_files(dir_ / "simplified", key);
    if (note) *note = why + "; removed, will rebuild";
    return std::nullopt;
  }
  return e;
}

std::optional<CacheEntry> SimplifiedCache::find_reusable(const Cut& wanted, double max_position_error,
                                                         std::string* why, double crease_angle_deg,
                                                         const std::set<std::string>* candidates, bool exact_normals,
                                                         int normal_bits) {
  CacheLock lock(dir_);
  // Candidates by the cheap checks first (metadata and cut); only the chosen
  // one is hashed, and a corrupt one is removed and the next tried.
  std::vector<std::pair<CacheEntry, size_t>> fine;
  for (const auto& e : entries()) {
    if (e.store_hash != wanted.store_hash || e.max_position_error > max_position_error * (1 + 1e-9)) continue;
    if (!(e.crease_angle_deg == crease_angle_deg)) continue;  // another normal rule (or an old entry)
    if (e.exact_normals != exact_normals) continue;
    if (e.normal_bits < normal_bits) continue;  // normals quantised more coarsely than asked (or unknown)
    if (candidates && !candidates->count(e.key)) continue;
    auto cut = read_cut(e.cut);
    // Corrupt, missing, or not the cut the mesh was made from (the key hashes
    // that cut's cells: a .cut swapped in from another entry or view would
    // let a coarser mesh pass the reuse rule): the entry can never be reused.
    if (!cut.is_ok() || key_for(*cut, e.crease_angle_deg, e.exact_normals, e.normal_bits) != e.key) {
      remove_entry_files(dir_ / "simplified", e.key);
      continue;
    }
    if (!cut_is_at_least_as_fine(*cut, wanted)) continue;
    fine.push_back({e, cut->cells.size()});
  }
  std::sort(fine.begin(), fine.end(), [](const auto& a, const auto& b) { return a.first.triangles < b.first.triangles; });
  for (const auto& [e, cells] : fine) {
    if (!verify(e, nullptr)) {
      remove_entry_files(dir_ / "simplified", e.key);
      continue;
    }
    if (why) {
      *why = "every cell it collapsed is also collapsed by the new view's cut (" + std::to_string(cells) +
             " cells checked) and its quantisation is fine enough; " + std::to_string(e.triangles) +
             " triangles, the coarsest such entry";
    }
    return e;
  }
  return std::nullopt;
}

Status SimplifiedCache::checkout(const CacheEntry& entry, const fs::path& dest) {
  CacheLock lock(dir_);
  std::error_code ec;
  fs::remove(dest, ec);
  fs::create_hard_link(entry.mesh, dest, ec);
  if (ec) fs::copy_file(entry.mesh, dest, fs::copy_options::overwrite_existing, ec);
  if (ec)
    return Status::write_failed(dest.string(), entry.mesh.string() + ": cannot use cached mesh: cannot link or copy it to " +
                                                   dest.string() + ": " + ec.message(),
                                ec.value());
  return {};
}

StatusOr<CacheEntry> SimplifiedCache::insert(const Cut& cut, const fs::path& drc_file, uint64_t triangles,
                                             double max_position_error, double crease_angle_deg,
                                             bool exact_normals, int normal_bits, int position_bits) {
  CacheEntry e;
  e.key = key_for(cut, crease_angle_deg, exact_normals, normal_bits);
  e.crease_angle_deg = crease_angle_deg;
  e.exact_normals = exact_normals;
  e.normal_bits = normal_bits;
  e.position_bits = position_bits;
  fs::path dir = dir_ / "simplified";
  e.mesh = dir / (e.key + ".drc");
  e.cut = dir / (e.key + ".cut");
  e.store_hash = cut.store_hash;
  e.triangles = triangles;
  e.footprint_scale = cut.footprint_scale;
  e.max_position_error = max_position_error;
  e.last_used_ns = now_ns();
  RAYLOD_ASSIGN_OR_RETURN(e.content_hash, hash_file(drc_file));
  {
    CacheLock lock(dir_);
    // Mesh and cut first, metadata last: an entry exists only once its .json
    // does. A failed insert (a full disk) removes whatever it wrote.
    fs::path staged = e.mesh;
    staged += ".tmp-insert";
    bool done = false;
    struct Undo {
      const bool& done;
      const fs::path &dir, &staged;
      const std::string& key;
      ~Undo() {
        if (done) return;
        std::error_code ec;
        fs::remove(staged, ec);
        remove_entry_files(dir, key);
      }
    } undo{done, dir, staged, e.key};
    RAYLOD_RETURN_IF_ERROR(write_cut(e.cut, cut));
    std::error_code ec;
    fs::copy_file(drc_file, staged, fs::copy_options::overwrite_existing, ec);
    if (ec) return Status::error(e.mesh.string() + ": cannot copy into cache: " + ec.message());
    fs::rename(staged, e.mesh, ec);
    if (ec) return Status::error(e.mesh.string() + ": cannot rename into cache: " + ec.message());
    fault_point("cache.before_meta");
    RAYLOD_RETURN_IF_ERROR(write_meta(dir, e));
    done = true;
  }
  evict();
  if (auto fresh = read_meta(dir / (e.key + ".json"))) return *fresh;
  return e;  // evicted at once (larger than the whole limit): still usable by this run
}

void SimplifiedCache::touch(const CacheEntry& entry) {
  CacheLock lock(dir_);
  CacheEntry e = entry;
  e.last_used_ns = now_ns();
  (void)write_meta(dir_ / "simplified", e);
}

void SimplifiedCache::evict() {
  CacheLock lock(dir_);
  auto all = entries();
  uint64_t total = 0;
  for (const auto& e : all) total += e.bytes;
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.last_used_ns < b.last_used_ns; });
  // Keep the most recently used entry even if it alone exceeds the limit,
  // and the entries held for the view being prepared.
  for (size_t i = 0; i + 1 < all.size() && total > limit_; ++i) {
    if (held_.count(all[i].key)) continue;
    remove_entry_files(dir_ / "simplified", all[i].key);
    total -= all[i].bytes;
  }
  // Leftovers of killed runs, older than an hour: temporary files, and a mesh
  // or cut whose metadata was never written (an entry exists only with it).
  std::error_code ec;
  auto cutoff = fs::file_time_type::clock::now() - std::chrono::hours(1);
  for (const auto& f : fs::directory_iterator(dir_ / "simplified", ec)) {
    const fs::path& p = f.path();
    const bool temporary = p.filename().string().find(".tmp-") != std::string::npos;
    const bool orphan = (p.extension() == ".drc" || p.extension() == ".cut") &&
                        !fs::exists(fs::path(p).replace_extension(".json"));
    if ((temporary || orphan) && f.last_write_time(ec) < cutoff) fs::remove(p, ec);
  }
}

}  // namespace raylod
