// On-disk layout of the octree store (internal to streaming/octree_*.cpp).
//
//   offset 0      magic "RLODSTOR", u32 version, u32 blob_bytes, blob, u32 CRC-32C of all before
//   node table    (64-aligned) every level 0..quadric_depth in turn, each level's
//                 NodeRecords sorted by code, exactly as in memory (144 bytes
//                 each): the open maps it read-only and uses it in place, so
//                 processes on one machine share its pages (format 6; before,
//                 only the leaves were stored, varint-packed, and each open
//                 decoded them and summed the levels above into its own memory:
//                 2.3 s for the 10M teapot's 524 MiB table on this machine,
//                 nearly all of it the first touch of fresh pages)
//   page table    (64-aligned) PageInfo records sorted by code
//   page data     (4096-aligned) pages in page-table order, back to back; each is
//                 PageInfo::bytes long, encoded as in streaming/page_codec.h (indexed
//                 vertices, grid-quantised positions, octahedral normals)
//   boundary      (8-aligned, last) the codes of the leaves that hold an end of an
//                 open boundary edge (an edge of one triangle only), sorted
//
// Every number is little-endian (the code asserts a little-endian host and
// writes records as they are in memory; the static_asserts pin their layout).
// The blob holds the StoreHeader fields, the per-level node counts and the
// offsets, sizes and CRC-32C of the node table, the page table and the
// boundary list; each page's
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
// 6: the node table holds every level as in memory (mapped on open); the
// boundary leaves are a list of codes at the end of the file.
inline constexpr uint32_t kVersion = 6;
inline constexpr uint32_t kMaxLevel = 21;  // Morton codes hold 3 x 21 bits

struct Layout {
  std::vector<uint64_t> level_counts;  // nodes per level, quadric_depth + 1 entries
  uint64_t node_table_offset = 0;
  uint32_t node_table_crc = 0;
  uint64_t node_table_bytes = 0;       // all levels' NodeRecords
  uint64_t page_count = 0, page_table_offset = 0;
  uint32_t page_table_crc = 0;
  uint64_t data_offset = 0, data_bytes = 0;
  uint64_t boundary_offset = 0, boundary_count = 0;  // u64 codes, after the page data
  uint32_t boundary_crc = 0;
  uint64_t file_bytes = 0;
};

inline uint64_t align_up(uint64_t x, uint64_t a) { return (x + a - 1) / a * a; }

// The full header bytes (magic .. CRC).
std::string encode_header(const StoreHeader& header, const Layout& layout);
// Reads and checks the header of an open store file: magic, version, CRC and
// the recorded file size against the real one. Errors name `path`.
Status read_header(int fd, const std::filesystem::path& path, StoreHeader& header, Layout& layout);

// Nodes per level 0..depth above sorted leaves at `depth`.
std::vector<uint64_t> level_counts_of(std::span<const NodeRecord> leaves, int depth);
// The level above `children` (sorted by code): each parent the sum of its
// children in code order, with code child.code >> 3.
std::vector<NodeRecord> sum_parent_level(std::span<const NodeRecord> children);
// True if `parents` holds exactly the distinct codes of `children` >> 3 (both
// sorted): the structure sum_parent_level gives.
bool parents_match(std::span<const NodeRecord> parents, std::span<const NodeRecord> children);

// Full-length pread/pwrite; errors name `path`.
Status pread_all(int fd, void* data, size_t bytes, uint64_t offset, const std::filesystem::path& path);
Status pwrite_all(int fd, const void* data, size_t bytes, uint64_t offset, const std::filesystem::path& path);

}  // namespace raylod::store_format
