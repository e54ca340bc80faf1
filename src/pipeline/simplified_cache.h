// The cache of simplified meshes that `raylod run` reuses across views.
//
// Layout under the cache directory:
//   simplified/<key>.drc    the simplified mesh (Draco; a part file from 2M
//                           triangles, streaming/draco_io.h)
//   simplified/<key>.cut    the cut it was made from (for the reuse rule)
//   simplified/<key>.json   metadata: store hash, options, triangle count,
//                           content hash of the .drc, last use
//   lock                    flock()ed while the index is read or changed
//
// Every file is written under a temporary name and renamed, so a killed run
// leaves either a complete entry or none. An entry whose .drc no longer
// matches its recorded content hash is corrupt: it is removed and rebuilt,
// never rendered.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <set>
#include <vector>

#include "core/status.h"
#include "geometry/crease_normals.h"
#include "streaming/cut_file.h"

namespace raylod {

struct CacheEntry {
  std::string key;
  std::filesystem::path mesh;   // the .drc
  std::filesystem::path cut;    // the .cut
  uint64_t store_hash = 0;
  uint64_t triangles = 0;
  uint64_t bytes = 0;           // .drc + .cut + .json
  uint64_t content_hash = 0;    // of the .drc
  double footprint_scale = 1;
  double max_position_error = 0;  // Draco quantisation bound of the mesh (world units)
  // The normal rule the mesh was made with (NaN for entries from before
  // crease-angle normals: never reused).
  double crease_angle_deg = kDefaultCreaseAngleDeg;
  // Made with exact normals (SimplifyConfig::exact_normals: the meshes a
  // mirror or glass object uses); entries from before it say false.
  bool exact_normals = false;
  // Draco's normal quantisation (0: an entry from before it was recorded,
  // never reused where bits are asked for) and position bits, for stats.
  int normal_bits = 0;
  int position_bits = 0;
  int64_t last_used_ns = 0;
};

// The reuse rule: a cached mesh made with cut `cached` is at least as fine as
// the view with cut `wanted` needs if every cell it collapsed is also
// collapsed (itself or inside a collapsed ancestor) by the wanted cut. Then
// wherever the new probe asks for detail, the cached mesh still has it.
// Returns false and a reason (the first cell that is too coarse) otherwise.
bool cut_is_at_least_as_fine(const Cut& cached, const Cut& wanted, std::string* reason = nullptr);

class SimplifiedCache {
 public:
  // Opens (creating if needed) the cache at dir with a size limit in bytes.
  static StatusOr<SimplifiedCache> open(const std::filesystem::path& dir, uint64_t size_limit);

  const std::filesystem::path& dir() const { return dir_; }
  uint64_t size_limit() const { return limit_; }

  // Key of a cut for a store: stable hash of the store hash, the cut cells,
  // the normal rule (crease angle, exact normals) and the normals'
  // quantisation (normal_bits, left out when 0): a glossier material asks
  // for more bits, and an exact hit must be the mesh a fresh run writes.
  static std::string key_for(const Cut& cut, double crease_angle_deg = kDefaultCreaseAngleDeg,
                             bool exact_normals = false, int normal_bits = 0);

  // Exact hit for this key, verified (content hash); a corrupt entry is
  // removed and reported through `note`.
  std::optional<CacheEntry> find_exact(const std::string& key, std::string* note = nullptr);
  // The coarsest verified entry for the same store whose cut is at least as
  // fine as `wanted` needs and whose quantisation error is at most
  // `max_position_error`; `why` says which and why.
  // Only entries made with the same crease angle and exact-normals setting
  // and at least normal_bits normal bits qualify, and, if `candidates` is
  // given, only entries whose key it holds.
  std::optional<CacheEntry> find_reusable(const Cut& wanted, double max_position_error, std::string* why = nullptr,
                                          double crease_angle_deg = kDefaultCreaseAngleDeg,
                                          const std::set<std::string>* candidates = nullptr,
                                          bool exact_normals = false, int normal_bits = 0);
  // Copies a finished .drc (written elsewhere, e.g. a temporary file) into the
  // cache with its cut, then evicts least-recently-used entries over the limit.
  StatusOr<CacheEntry> insert(const Cut& cut, const std::filesystem::path& drc_file, uint64_t triangles,
                              double max_position_error, double crease_angle_deg = kDefaultCreaseAngleDeg,
                              bool exact_normals = false, int normal_bits = 0, int position_bits = 0);
  // Links (or copies) an entry's mesh to `dest` under the cache lock, so that
  // a concurrent eviction cannot remove the file this run is about to render.
  Status checkout(const CacheEntry& entry, const std::filesystem::path& dest);
  // Marks an entry used now (LRU order).
  void touch(const CacheEntry& entry);
  std::vector<CacheEntry> entries() const;
  // Removes least-recently-used entries until the total is within the limit,
  // never one that is held (and never the most recently used).
  void evict();
  // Entries the view being prepared uses (the meshes of a scene): evicting
  // one of them to make room for another would leave the next run of the
  // same view a miss for each, in turn. Held until release_held(), when the
  // next view starts; they may exceed the limit together meanwhile.
  void hold(const std::string& key) { held_.insert(key); }
  void release_held() { held_.clear(); }

 private:
  SimplifiedCache(std::filesystem::path dir, uint64_t limit) : dir_(std::move(dir)), limit_(limit) {}
  std::filesystem::path dir_;
  uint64_t limit_ = 0;
  std::set<std::string> held_;
};

// Hash of a file's content (for corruption checks).
StatusOr<uint64_t> hash_file(const std::filesystem::path& path);

}  // namespace raylod
