// The cut: which octree cells the probe marked for collapse (method step A4),
// written by `raylod probe` and read by `raylod simplify`.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/status.h"
#include "streaming/octree_store.h"

namespace raylod {

struct CollapsedCell {
  CellKey key;
  float min_footprint = 0;  // smallest footprint ||dP|| seen inside (0 if none: policy-collapsed)
  uint32_t hits = 0;        // test-ray hits inside the cell
};

struct Cut {
  uint32_t version = 1;
  // What the cut was made for: the store's fingerprint, the camera and the probe options.
  uint64_t store_hash = 0;
  std::string store_path;
  std::string key;                       // printable key: camera + options
  uint64_t rays = 0, seed = 0;
  double footprint_scale = 1;
  std::vector<CollapsedCell> cells;      // an antichain: no cell is inside another, sorted by key
  std::map<std::string, uint64_t> counters;  // rays by kind, hits, pages read, ...
  float min_footprint = 0;               // smallest footprint of any hit, across its ray (ProbeHit::width)
};

Status write_cut(const std::filesystem::path& path, const Cut& cut);  // atomic
StatusOr<Cut> read_cut(const std::filesystem::path& path);
// True if the file starts with the cut magic (for `raylod info`).
bool is_cut_file(const std::filesystem::path& path);
// Prints the summary `raylod info CUT` shows: cells marked per level, rays
// traced by kind, hits, pages read.
Status print_cut_info(const std::filesystem::path& path, std::FILE* out);

}  // namespace raylod
