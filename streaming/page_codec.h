// The compact page encoding of the octree store (format version 3).
//
// A page is one page-level cell's triangles. It is stored indexed: each
// distinct corner (position and normal) once, then three vertex indices per
// triangle, in the page's input order.
//
// Positions are quantised on one grid for the whole store (PageGrid): the
// root cube divided into 2^bits steps per axis, bits = the planned quadric
// depth + 12 (at least 20, at most 30), so a step is 1/4096 of the finest
// quadric cell or finer up to depth 18 (the default --max-depth is 12), and
// 2^(depth - 30) of it beyond. The build quantises every corner as it reads it, and
// computes quadrics, sums and pages from the quantised mesh, so the store is
// consistent with what read_page gives back. A vertex is the integer point nearest to it, so the error per
// axis is at most half a step (1/8192 of the finest cell), wherever the model
// sits: positions are kept as integers relative to the root corner, which is
// a double. Decoding gives float(root_lo + q * step), computed in double; a
// vertex shared by two pages decodes to the same float in both, so pages meet
// without cracks. A page stores its vertices relative to the smallest grid
// point among them, each coordinate in position_bits bits (the bit width of
// the page's largest extent in steps).
//
// Normals are octahedral-encoded in two int16 (under 1e-4 rad of error; the
// largest over 2M random unit normals was 4.3e-5 rad); a
// zero normal keeps a code of its own. Indices use index_bits bits (the bit
// width of vertex_count - 1, at least 1).
//
// Page bytes (little-endian):
//   u32 triangle_count, u32 vertex_count, u32 origin[3] (grid point),
//   u8 position_bits, u8 index_bits, u8 has_normals, u8 0,
//   positions: vertex_count x 3 coordinates of position_bits bits (LSB first),
//              padded to a byte,
//   normals (if has_normals): vertex_count x 2 int16,
//   indices: triangle_count x 3 of index_bits bits, padded to a byte.
// Algorithms only: spans in, bytes out; the store code reads and writes files.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"
#include "streaming/mesh_reader.h"

namespace raylod {

struct PageGrid {
  Vec3d lo{0};     // the root cube's corner (world)
  double step = 1; // grid spacing (world), root_size / 2^bits, a power of two times root_size
  double inv_step = 1;  // 1 / step (exact: a power of two)
  int bits = 20;   // grid points per axis: 2^bits + 1
};

inline constexpr int kPageGridSubCellBits = 12;  // grid steps per finest cell: 2^12
// Grid bits for a store whose finest quadric level is `quadric_depth`.
int page_grid_bits(int quadric_depth);
// The grid of a store with this root cube and grid bits.
PageGrid page_grid(const Vec3d& root_lo, double root_size, int bits);
// The largest distance between an input position (inside the root cube) and
// its grid point: half a step per axis. The decoded float adds its own
// rounding (half an ulp of each coordinate).
inline double page_grid_max_error(const PageGrid& g) { return 0.5 * g.step * 1.7320508075688772; }

// The grid point nearest to p (clamped to the root cube), and back: the
// decoded position, computed in double and rounded to float once, so equal
// grid points decode to equal floats in every page.
void quantise_position(const Vec3& p, const PageGrid& g, uint32_t q[3]);
Vec3 grid_position(const uint32_t q[3], const PageGrid& g);

// Octahedral normal code: two int16 (the unit normal's octahedral map); a
// zero or non-finite normal has a code of its own that decodes to zero.
uint32_t encode_octahedral(const Vec3& n);
Vec3 decode_octahedral(uint32_t code);

// Reusable buffers for encode_page (the vertex hash table).
struct PageEncoder {
  std::vector<uint32_t> slots;
  std::vector<uint32_t> keys;   // 4 per vertex: qx, qy, qz, normal code
  std::vector<uint32_t> index;  // 3 per triangle
};

// Encodes a page from its corners, already on the grid: `positions` holds 3
// grid coordinates per corner, 3 corners per triangle; `normals` one
// octahedral code per corner, or is empty for a mesh without normals. Fills
// `out` (cleared first) and returns the bounds of the decoded positions.
Bbox encode_page(std::span<const uint32_t> positions, std::span<const uint32_t> normals, const PageGrid& grid,
                 PageEncoder& encoder, std::vector<uint8_t>& out);

// Decodes page bytes into a triangle soup (batch cleared first). Every count
// and width is checked against the bytes given, so malformed bytes give an
// error (a message without the file name), never a read outside them.
Status decode_page(std::span<const uint8_t> bytes, const PageGrid& grid, TriangleBatch& batch);

// A page indexed as it is stored: each page vertex once, three vertex
// indices per triangle. decode_page gives the same triangles as corners
// (positions[index[c]], and normals); per-vertex work (a cell lookup, a hash,
// a normal) is done here once per vertex, and nothing is copied per corner.
struct PageMesh {
  std::vector<Vec3> positions;         // per vertex
  std::vector<uint32_t> normal_codes;  // per vertex, or empty without normals
  std::vector<Vec3> normals;           // per vertex once decode_normals() ran, else empty
  std::vector<uint32_t> index;         // 3 per triangle, each < vertices()
  size_t size() const { return index.size() / 3; }
  size_t vertices() const { return positions.size(); }
  void clear() {
    positions.clear();
    normal_codes.clear();
    normals.clear();
    index.clear();
  }
  // Fills `normals` from `normal_codes` (decode_octahedral).
  void decode_normals();
};
// decode_page into PageMesh (cleared first); normals stay as codes.
Status decode_page_mesh(std::span<const uint8_t> bytes, const PageGrid& grid, PageMesh& page);
// Decodes page bytes back to the corners encode_page was given: appends 3
// grid coordinates per corner to `positions` and, if the page has normals,
// one normal code per corner to `normals` (for the build's sorted runs).
Status decode_page_grid(std::span<const uint8_t> bytes, const PageGrid& grid, std::vector<uint32_t>& positions,
                        std::vector<uint32_t>& normals);

// The triangle and vertex counts from a page's first bytes (0, 0 if too short).
struct PageCounts {
  uint32_t triangles = 0, vertices = 0;
};
PageCounts page_counts(std::span<const uint8_t> bytes);

}  // namespace raylod
