// On-disk layout of the octree store (internal to streaming/octree_*.cpp).
//
//   offset 0      magic "RLODSTOR", u32 version, u32 blob_bytes, blob, u32 CRC-32C of all before
//   node table    (64-aligned) the leaves (level quadric_depth) sorted by code, each as
//                 varint(code - previous code; the first code itself),
//                 varint(corner_count << 1 | boundary: the leaf holds an end of an
//                 open boundary edge, an edge of one triangle only),
//                 then the quadric, vertex_sum and normal_sum as in NodeRecord (128 bytes);
//                 levels above are the sums of their children, computed on open
//                 (sum_parent_levels), so they are not stored
//   page table    (64-aligned) PageInfo records sorted by code
//   page data     (4096-aligned) pages in page-table order, back to back; each is
//                 PageInfo::bytes long, encoded as in streaming/page_codec.h (indexed
//                 vertices, grid-quantised positions, octahedral normals)
//
// Every number is little-endian (the code asserts a little-endian host and
// writes records as they are in memory; the static_asserts pin their layout).
// The blob holds the StoreHeader fields, the per-level node counts and the
// offsets, sizes and CRC-32C of the node table and the page table; each page's
// CRC-32C is in its PageInfo. file_bytes is recorded so truncation is caught
// on open.
#pragma once

#include <bit>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "core/status.h"
#include "streaming/octree_store.h"

namespace raylod::store_format {

static_assert(std::endian::native == std::endian::little, "the store format is little-endian; add byte swapping");
static_assert(sizeof(Quadric) == 80 && std::is_trivially_copyable_v<Quadric>);
static_assert(sizeof(NodeRecord) == 144 && std::is_trivially_copyable_v<NodeRecord>);
static_assert(offsetof(NodeRecord, quadric) == 8 && offsetof(NodeRecord, vertex_sum) == 88 &&
              offsetof(NodeRecord, normal_sum) == 112 && offsetof(NodeRecord, corner_count) == 136);
static_assert(sizeof(PageInfo) == 80 && std::is_trivially_copyable_v<PageInfo>);
static_assert(offsetof(PageInfo, triangle_count) == 16 && offsetof(PageInfo, checksum) == 20 &&
              offsetof(PageInfo, bounds) == 24 && offsetof(PageInfo, bytes) == 72);

inline constexpr char kMagic[8] = {'R', 'L', 'O', 'D', 'S', 'T', 'O', 'R'};
// 2: the header records the memory limits a store is reused under
// (StoreHeader::reuse_limit_lo/hi).
// 3: compact pages (page_codec.h; PageInfo::bytes); version 2 pages were
// float triangle soup, 72 bytes per triangle with normals.
// 4: the mesh's local origin (StoreHeader::mesh_origin): store coordinates
// are relative to it, so a mesh far from zero keeps its detail.
// 5: the leaves that hold open boundary vertices are flagged (the low bit of
// the corner count's varint).
inline constexpr uint32_t kVersion = 5;
inline constexpr uint32_t kMaxLevel = 21;  // Morton codes hold 3 x 21 bits

struct Layout {
  std::vector<uint64_t> level_counts;  // nodes per level, quadric_depth + 1 entries
  uint64_t node_table_offset = 0;
  uint32_t node_table_crc = 0;
  uint64_t node_table_bytes = 0;       // on disk (the encoded leaves)
  uint64_t page_count = 0, page_table_offset = 0;
  uint32_t page_table_crc = 0;
  uint64_t data_offset = 0, data_bytes = 0, file_bytes = 0;
};

inline uint64_t align_up(uint64_t x, uint64_t a) { return (x + a - 1) / a * a; }

// The full header bytes (magic .. CRC).
std::string encode_header(const StoreHeader& header, const Layout& layout);
// Reads and checks the header of an open store file: magic, version, CRC and
// the recorded file size against the real one. Errors name `path`.
Status read_header(int fd, const std::filesystem::path& path, StoreHeader& header, Layout& layout);

// The node table's encoding (see the layout above).
inline constexpr size_t kLeafFixedBytes = 128;  // quadric, vertex_sum, normal_sum
inline constexpr size_t kLeafMaxBytes = 10 + 10 + kLeafFixedBytes;
// Bytes the leaves take on disk.
uint64_t encoded_leaves_bytes(std::span<const NodeRecord> leaves);
// Appends the leaves' encoding to `out`; boundary[i] != 0 flags leaf i (or
// empty: none); `previous_code` carries the last code between calls (start
// with 0).
void encode_leaves(std::span<const NodeRecord> leaves, std::span<const uint8_t> boundary, uint64_t& previous_code,
                   std::string& out);
// Nodes per level 0..depth above sorted leaves at `depth`.
std::vector<uint64_t> level_counts_of(std::span<const NodeRecord> leaves, int depth);
// Fills levels 0..depth-1 of `nodes` (level l at level_begin[l] ..
// level_begin[l + 1]) from level `depth`, each parent the sum of its children
// in code order. False if a level's count is not what level_begin says.
bool sum_parent_levels(std::vector<NodeRecord>& nodes, const std::vector<uint64_t>& level_begin, int depth);

// Full-length pread/pwrite; errors name `path`.
Status pread_all(int fd, void* data, size_t bytes, uint64_t offset, const std::filesystem::path& path);
Status pwrite_all(int fd, const void* data, size_t bytes, uint64_t offset, const std::filesystem::path& path);

}  // namespace raylod::store_format
