// Draco (.drc) mesh files: the compressed simplified meshes raylod writes.
#pragma once

#include <cstdint>
#include <filesystem>
#include <algorithm>
#include <memory>
#include <span>
#include <vector>

#include "core/status.h"
#include "streaming/mesh_reader.h"

namespace draco {
class PointAttribute;
}

namespace raylod {

struct IndexedMesh {
  // Positions are relative to this point (the mesh's local origin,
  // MeshHeader::origin): (0, 0, 0) unless the mesh lies far from zero. A .drc
  // file carries it as the geometry metadata entry "raylod_origin" (three
  // doubles), so the file's coordinates are origin + position.
  Vec3d origin{0};
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;      // empty or one per position
  std::vector<uint32_t> indices;  // 3 per triangle
  size_t triangle_count() const { return indices.size() / 3; }
};

// The encoder speed for a simplified mesh of `triangles` (the pipeline's cache
// entries): Draco's speed 6 from a million triangles, its speed 5 below (both
// select the standard edgebreaker and the same prediction schemes). Measured
// (tools/MEASUREMENTS.md, "Draco's speed for large simplified meshes"): on the
// 100M glass scene's 9.4M-triangle teapot, speed 6 encodes in 3.5 to 4.1 s
// instead of 4.8 to 5.2 s and decodes in 1.13 to 1.15 s instead of 1.59 to
// 1.72 s, 0.06% smaller; on meshes under a million triangles the time saved is
// under a tenth of a second, and some grow (the bunny scan's cut by 22%, the
// default view's 72k-triangle one by 12%).
inline constexpr uint64_t kFastDracoFromTriangles = 1'000'000;
inline int draco_speed_for(uint64_t triangles) { return triangles >= kFastDracoFromTriangles ? 6 : 5; }

// A large simplified mesh is written as a part file: its triangles split
// into consecutive ranges, each range (with the vertices it uses, in order
// of first use) its own Draco bitstream, all quantised on the whole mesh's
// grid (Draco's explicit quantisation with the whole mesh's origin and
// range), so a vertex shared by two parts decodes to the same position in
// both. The parts are encoded and decoded in parallel; their number depends
// on the triangle count alone, so the bytes do not depend on the threads.
// Layout (little-endian):
//   "RLODDRCP", u32 version (1), u32 part count P,
//   P x (u64 Draco bytes, u64 triangles),
//   the P Draco bitstreams, in order.
// read_draco, draco_triangle_count and open_draco_reader read part files and
// plain .drc alike; write_draco writes a plain .drc unless asked for parts.
inline constexpr char kDracoPartsMagic[8] = {'R', 'L', 'O', 'D', 'D', 'R', 'C', 'P'};
inline constexpr uint64_t kDracoPartTriangles = 1'000'000;
// Parts for a mesh of `triangles`: 1 below 2 x kDracoPartTriangles, else one
// per kDracoPartTriangles (rounded up), at most 256.
inline int draco_parts_for(uint64_t triangles) {
  if (triangles < 2 * kDracoPartTriangles) return 1;
  return int(std::min<uint64_t>(256, (triangles + kDracoPartTriangles - 1) / kDracoPartTriangles));
}

// Octahedral normal bits when nothing asks for more (0.275 degrees at most).
inline constexpr int kDefaultNormalBits = 10;

struct DracoOptions {
  int parts = 1;          // > 1: a part file of this many parts (at most one per triangle)
  int position_bits = 0;  // 0 = choose from the data and max_position_error
  int normal_bits = kDefaultNormalBits;  // 0 = choose from max_normal_error
  double max_position_error = 0;  // world units; used when position_bits == 0
  double max_normal_error = 0;    // radians; used when normal_bits == 0
  int speed = 5;                   // Draco encoder speed 0 (best) .. 10 (fastest)
};

struct DracoWriteReport {
  int position_bits = 0, normal_bits = 0;
  double max_position_error = 0;  // bound implied by the quantisation
  uint64_t bytes = 0;
  double max_normal_error = 0;    // radians; bound implied by the octahedral normal quantisation
  double requested_position_error = 0;  // the target position_bits was chosen for (0 if given)
};
// Smallest position_bits (1..30) whose quantisation error bound for a mesh
// whose bounding box's largest side is `extent` and largest coordinate
// magnitude is `max_abs` is at most max_error; if none is (float rounding
// dominates), the fewest bits within 10% of the best achievable bound.
int choose_position_bits(double extent, double max_abs, double max_error);
// The bound for those bits: sqrt(3) * (extent / (2^bits - 1) / 2 + float rounding).
double position_error_bound(double extent, double max_abs, int bits);

// The most octahedral normal bits raylod encodes: 24 bits quantise a normal
// to 2.9e-7 rad, about the precision of the float normals the renderer
// shades with (2^-24 per component). Draco's normal coder holds tables of
// about 2^bits entries whatever the mesh's size: 82 MB at 24 bits, 4.2 GB at
// 30 (measured, `raylod simplify --normal-bits B` on a 40k-triangle sphere),
// which a memory limit did not see.
inline constexpr int kMaxNormalBits = 24;
// Smallest normal_bits (2..kMaxNormalBits) whose octahedral quantisation
// error bound is at most max_error radians (kMaxNormalBits if none is: a
// glossy shininess of 1e4 and more asks for less).
int choose_normal_bits(double max_error);
// The bound for those bits (radians).
double normal_error_bound(int bits);

// Encodes the mesh (degenerate triangles must be removed by the caller) and
// writes it atomically.
StatusOr<DracoWriteReport> write_draco(const std::filesystem::path& path, const IndexedMesh& mesh,
                                       const DracoOptions& options);
// The same, freeing the mesh's arrays as soon as Draco holds a copy (the
// encoder's peak then does not stack on the mesh; a large simplified mesh).
StatusOr<DracoWriteReport> write_draco(const std::filesystem::path& path, IndexedMesh&& mesh,
                                       const DracoOptions& options);
StatusOr<IndexedMesh> read_draco(const std::filesystem::path& path);
// Whether a decoded attribute stores numbers that Draco can convert to float:
// it converts a stored bool by reading each byte as a C++ bool, undefined for
// bytes other than 0 and 1, so such an attribute is refused (fuzz_draco,
// under UBSan, found a file whose bool positions held 3).
bool draco_attribute_holds_numbers(const draco::PointAttribute& attribute);
// Draco sizes its tables from the counts a mesh's header claims before it
// reads what they describe (a 415-byte file made it allocate 2.9 GB), so a
// header is checked first: an error for a bitstream before version 2 (raw
// 32-bit counts; a 150-byte one made Draco allocate 3 GB), and for a Draco
// 2.2 mesh that claims more vertices than three a triangle, or more
// triangles or vertices than kDracoCountFloor plus kDracoCountsPerByte a
// byte of `size` (real files take bits a triangle). A header that does not
// parse is left to Draco. Both Draco readers (.drc, glTF primitives) call it.
inline constexpr uint64_t kDracoCountFloor = uint64_t(1) << 22;
inline constexpr uint64_t kDracoCountsPerByte = 256;
Status check_draco_counts(const char* data, size_t size, const std::string& where);
// The triangle count of a .drc without decoding it: from the header's
// "raylod_triangles" metadata entry, which write_draco adds; a file without
// one is decoded to count.
StatusOr<uint64_t> draco_triangle_count(const std::filesystem::path& path);
// Decodes a Draco mesh held in memory (name says whose, in errors).
StatusOr<IndexedMesh> decode_draco(const char* data, size_t size, const std::string& name);
// The Draco bitstreams of a part file held in memory (views into `data`);
// an error if it is not one or is malformed. A plain Draco buffer gives one.
StatusOr<std::vector<std::span<const char>>> draco_parts(const char* data, size_t size, const std::string& name);

// The encoded bytes, without writing them (write_draco and the .glb writer).
struct DracoEncoded {
  std::vector<char> bytes;
  DracoWriteReport report;
  int position_id = -1, normal_id = -1;  // the attributes' unique ids (-1: no normals)
};
StatusOr<DracoEncoded> encode_draco(const std::filesystem::path& path, const IndexedMesh& mesh,
                                    const DracoOptions& options);
StatusOr<DracoEncoded> encode_draco(const std::filesystem::path& path, IndexedMesh&& mesh,
                                    const DracoOptions& options);
// A MeshReader over a decoded Draco file (used by open_mesh for .drc).
StatusOr<std::unique_ptr<MeshReader>> open_draco_reader(const std::filesystem::path& path, ReaderOptions options);

}  // namespace raylod
