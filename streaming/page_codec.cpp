// Compact store pages: indexed, grid-quantised positions, octahedral normals,
// bit-packed (format in page_codec.h).
#include "streaming/page_codec.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "streaming/distinct_keys.h"

namespace raylod {
namespace {

constexpr size_t kHeaderBytes = 24;
constexpr uint32_t kZeroNormal = 0x80008000u;  // both int16 at INT16_MIN: never produced for a unit normal

// Bits LSB first into a byte vector.
class BitWriter {
 public:
  explicit BitWriter(std::vector<uint8_t>& out) : out_(out) {}
  void put(uint32_t value, int bits) {
    if (bits == 0) return;
    acc_ |= uint64_t(value) << n_;
    n_ += bits;
    while (n_ >= 8) {
      out_.push_back(uint8_t(acc_));
      acc_ >>= 8;
      n_ -= 8;
    }
  }
  void finish() {
    if (n_ > 0) out_.push_back(uint8_t(acc_));
    acc_ = 0;
    n_ = 0;
  }

 private:
  std::vector<uint8_t>& out_;
  uint64_t acc_ = 0;
  int n_ = 0;
};

// `bits` (<= 32) bits at bit offset `at` of a section of `size` bytes, which
// the caller has checked holds them.
inline uint32_t get_bits(const uint8_t* data, size_t size, uint64_t at, int bits) {
  if (bits == 0) return 0;
  const size_t byte = size_t(at >> 3);
  uint64_t w = 0;
  // A whole word where the section has one (a fixed-size copy is one load);
  // the section's last bytes alone are copied byte by byte.
  if (byte + 8 <= size) std::memcpy(&w, data + byte, 8);
  else std::memcpy(&w, data + byte, size - byte);
  return uint32_t((w >> (at & 7)) & ((uint64_t(1) << bits) - 1));
}

inline uint64_t packed_bytes(uint64_t count, int bits) { return (count * uint64_t(bits) + 7) / 8; }

// Bits per vertex index: at least one whenever there are vertices (even one),
// so that a page's size grows with its triangle count and a short page cannot
// claim billions of triangles.
inline int index_bits_for(uint32_t vertices) { return vertices > 0 ? std::max(1, int(std::bit_width(vertices - 1))) : 0; }

inline uint32_t quantise(float v, double lo, double inv_step, uint32_t max) {
  const double q = std::nearbyint((double(v) - lo) * inv_step);
  return q <= 0 ? 0 : q >= double(max) ? max : uint32_t(q);
}

inline float dequantise(uint64_t q, double lo, double step) { return float(lo + double(q) * step); }

inline void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  const size_t at = out.size();
  out.resize(at + 4);
  std::memcpy(out.data() + at, &v, 4);
}

inline uint32_t get_u32(const uint8_t* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

// The octahedral point (x, y) unfolded onto the octahedron |x|+|y|+|z| = 1
// (float, as decode computes it; not normalised).
inline Vec3 unfolded(float x, float y) {
  const float z = 1.0f - std::fabs(x) - std::fabs(y);
  if (z < 0) {
    const float ox = (1.0f - std::fabs(y)) * (x >= 0 ? 1.0f : -1.0f);
    const float oy = (1.0f - std::fabs(x)) * (y >= 0 ? 1.0f : -1.0f);
    x = ox;
    y = oy;
  }
  return Vec3(x, y, z);
}

}  // namespace

int page_grid_bits(int quadric_depth) { return std::clamp(quadric_depth + kPageGridSubCellBits, 20, 30); }

PageGrid page_grid(const Vec3d& root_lo, double root_size, int bits) {
  PageGrid g;
  g.lo = root_lo;
  g.bits = bits;
  g.step = std::ldexp(root_size, -bits);
  g.inv_step = 1.0 / g.step;
  return g;
}

void quantise_position(const Vec3& p, const PageGrid& g, uint32_t q[3]) {
  const uint32_t max_q = uint32_t(1) << g.bits;
  for (int a = 0; a < 3; ++a) q[a] = quantise(p[a], g.lo[a], g.inv_step, max_q);
}

Vec3 grid_position(const uint32_t q[3], const PageGrid& g) {
  return Vec3(dequantise(q[0], g.lo.x, g.step), dequantise(q[1], g.lo.y, g.step), dequantise(q[2], g.lo.z, g.step));
}

uint32_t encode_octahedral(const Vec3& n) {
  const double s = std::fabs(double(n.x)) + std::fabs(double(n.y)) + std::fabs(double(n.z));
  if (!(s > 0) || !std::isfinite(s)) return kZeroNormal;
  double x = n.x / s, y = n.y / s;
  if (n.z < 0) {
    const double ox = (1.0 - std::fabs(y)) * (x >= 0 ? 1.0 : -1.0);
    const double oy = (1.0 - std::fabs(x)) * (y >= 0 ? 1.0 : -1.0);
    x = ox;
    y = oy;
  }
  // Of the four grid points around (x, y), the one whose decoded normal is
  // closest in angle to n (about half the error of plain rounding). The
  // angle's order is that of dot(d, n)^2 / |d|^2 for the unnormalised
  // unfolded point d (dot > 0 this close), so no square root is needed.
  const double fx = std::floor(std::clamp(x, -1.0, 1.0) * 32767.0), fy = std::floor(std::clamp(y, -1.0, 1.0) * 32767.0);
  uint32_t best = 0;
  double best_score = -1.0;
  for (int dy = 0; dy < 2; ++dy) {
    for (int dx = 0; dx < 2; ++dx) {
      const int ex = std::min(32767, int(fx) + dx), ey = std::min(32767, int(fy) + dy);
      const Vec3d d = unfolded(std::max(float(ex) / 32767.0f, -1.0f), std::max(float(ey) / 32767.0f, -1.0f));
      const double dot = d.x * n.x + d.y * n.y + d.z * n.z;
      const double score = dot > 0 ? dot * dot / glm::dot(d, d) : -1.0;
      if (score > best_score) {
        best_score = score;
        best = uint32_t(uint16_t(int16_t(ex))) | uint32_t(uint16_t(int16_t(ey))) << 16;
      }
    }
  }
  return best;
}

Vec3 decode_octahedral(uint32_t code) {
  if (code == kZeroNormal) return Vec3(0);
  const int16_t ex = int16_t(uint16_t(code & 0xffff)), ey = int16_t(uint16_t(code >> 16));
  return glm::normalize(unfolded(std::max(float(ex) / 32767.0f, -1.0f), std::max(float(ey) / 32767.0f, -1.0f)));
}

Bbox encode_page(std::span<const uint32_t> positions, std::span<const uint32_t> normals, const PageGrid& grid,
                 PageEncoder& enc, std::vector<uint8_t>& out) {
  out.clear();
  const bool has_normals = !normals.empty();
  const size_t corners = positions.size() / 9 * 3;
  const uint32_t max_q = uint32_t(1) << grid.bits;

  // Distinct (grid point, normal code) corners in first-use order.
  index_distinct_keys<4>(
      corners,
      [&](size_t c) {
        return std::array<uint32_t, 4>{positions[3 * c], positions[3 * c + 1], positions[3 * c + 2],
                                       has_normals ? normals[c] : 0u};
      },
      enc.slots, enc.keys, enc.index);
  const size_t nv = enc.keys.size() / 4;

  uint32_t origin[3] = {max_q, max_q, max_q}, top[3] = {0, 0, 0};
  for (size_t v = 0; v < nv; ++v)
    for (int a = 0; a < 3; ++a) {
      origin[a] = std::min(origin[a], enc.keys[4 * v + a]);
      top[a] = std::max(top[a], enc.keys[4 * v + a]);
    }
  if (nv == 0) origin[0] = origin[1] = origin[2] = 0;
  uint32_t extent = 0;
  for (int a = 0; a < 3 && nv > 0; ++a) extent = std::max(extent, top[a] - origin[a]);
  const int position_bits = std::bit_width(extent);
  const int index_bits = index_bits_for(uint32_t(nv));

  out.reserve(kHeaderBytes + packed_bytes(3 * nv, position_bits) + (has_normals ? 4 * nv : 0) +
              packed_bytes(corners, index_bits));
  put_u32(out, uint32_t(corners / 3));
  put_u32(out, uint32_t(nv));
  for (uint32_t o : origin) put_u32(out, o);
  out.push_back(uint8_t(position_bits));
  out.push_back(uint8_t(index_bits));
  out.push_back(has_normals ? 1 : 0);
  out.push_back(0);
  BitWriter bits(out);
  Bbox bounds;
  for (size_t v = 0; v < nv; ++v) {
    const uint32_t* q = &enc.keys[4 * v];
    for (int a = 0; a < 3; ++a) bits.put(q[a] - origin[a], position_bits);
    bounds.expand(grid_position(q, grid));
  }
  bits.finish();
  if (has_normals) {
    for (size_t v = 0; v < nv; ++v) put_u32(out, enc.keys[4 * v + 3]);
  }
  for (size_t c = 0; c < corners; ++c) bits.put(enc.index[c], index_bits);
  bits.finish();
  return bounds;
}

PageCounts page_counts(std::span<const uint8_t> bytes) {
  if (bytes.size() < kHeaderBytes) return {};
  return {get_u32(bytes.data()), get_u32(bytes.data() + 4)};
}

namespace {

// A page's vertices (grid points and normal codes) and corner indices.
struct GridPage {
  std::vector<uint32_t> q;      // 3 per vertex
  std::vector<uint32_t> codes;  // 1 per vertex, if the page has normals
  std::vector<uint32_t> index;  // 3 per triangle, each < the vertex count
  bool has_normals = false;
  size_t vertices() const { return q.size() / 3; }
};

Status parse_page(std::span<const uint8_t> bytes, const PageGrid& grid, GridPage& out) {
  out.q.clear();
  out.codes.clear();
  out.index.clear();
  if (bytes.size() < kHeaderBytes) return Status::error("page of " + std::to_string(bytes.size()) + " bytes is too short");
  const uint8_t* p = bytes.data();
  const uint32_t nt = get_u32(p), nv = get_u32(p + 4);
  const uint32_t origin[3] = {get_u32(p + 8), get_u32(p + 12), get_u32(p + 16)};
  const int position_bits = p[20], index_bits = p[21];
  out.has_normals = p[22] != 0;
  if (p[22] > 1 || p[23] != 0) return Status::error("page header has unknown flags");
  if ((nt == 0) != (nv == 0) || uint64_t(nv) > 3 * uint64_t(nt))
    return Status::error("page has " + std::to_string(nt) + " triangles and " + std::to_string(nv) + " vertices");
  if (position_bits > 31 || index_bits != index_bits_for(nv))
    return Status::error("page has bad bit widths");
  const uint64_t pos_bytes = packed_bytes(3 * uint64_t(nv), position_bits);
  const uint64_t nrm_bytes = out.has_normals ? 4 * uint64_t(nv) : 0;
  const uint64_t idx_bytes = packed_bytes(3 * uint64_t(nt), index_bits);
  if (kHeaderBytes + pos_bytes + nrm_bytes + idx_bytes != bytes.size())
    return Status::error("page of " + std::to_string(bytes.size()) + " bytes does not match its counts");
  const uint64_t max_q = uint64_t(1) << grid.bits;
  for (uint32_t o : origin)
    if (o > max_q) return Status::error("page origin is outside the root cube");

  out.q.resize(3 * size_t(nv));
  const uint8_t* pos = p + kHeaderBytes;
  uint64_t at = 0;
  for (size_t v = 0; v < size_t(nv); ++v) {
    bool inside = true;
    for (int a = 0; a < 3; ++a, at += uint64_t(position_bits)) {
      const uint64_t q = uint64_t(origin[a]) + get_bits(pos, size_t(pos_bytes), at, position_bits);
      inside &= q <= max_q;
      out.q[3 * v + size_t(a)] = uint32_t(q);
    }
    if (!inside) return Status::error("page vertex " + std::to_string(v) + " is outside the root cube");
  }
  if (out.has_normals) {
    out.codes.resize(nv);
    std::memcpy(out.codes.data(), pos + pos_bytes, 4 * size_t(nv));
  }
  const uint8_t* idx = pos + pos_bytes + nrm_bytes;
  out.index.resize(3 * size_t(nt));
  at = 0;
  for (size_t c = 0; c < 3 * size_t(nt); ++c, at += uint64_t(index_bits)) {
    const uint32_t i = get_bits(idx, size_t(idx_bytes), at, index_bits);
    if (i >= nv)
      return Status::error("page corner " + std::to_string(c) + " names vertex " + std::to_string(i) + " of " +
                           std::to_string(nv));
    out.index[c] = i;
  }
  return {};
}

}  // namespace

namespace {

// parse_page, then every vertex's position once (the corners index them).
Status parse_page_positions(std::span<const uint8_t> bytes, const PageGrid& grid, GridPage& page,
                            std::vector<Vec3>& vpos) {
  RAYLOD_RETURN_IF_ERROR(parse_page(bytes, grid, page));
  vpos.resize(page.vertices());
  for (size_t v = 0; v < vpos.size(); ++v) vpos[v] = grid_position(&page.q[3 * v], grid);
  return {};
}

}  // namespace

namespace {

// decode_page, keeping the parsed page (its corner indices) in `page`.
Status decode_page_into(std::span<const uint8_t> bytes, const PageGrid& grid, TriangleBatch& batch, GridPage& page) {
  batch.clear();
  thread_local std::vector<Vec3> vpos, vnrm;
  RAYLOD_RETURN_IF_ERROR(parse_page_positions(bytes, grid, page, vpos));
  const size_t nv = page.vertices();
  if (page.has_normals) {
    vnrm.resize(nv);
    for (size_t v = 0; v < nv; ++v) vnrm[v] = decode_octahedral(page.codes[v]);
  }
  batch.positions.resize(page.index.size());
  if (page.has_normals) batch.normals.resize(page.index.size());
  for (size_t c = 0; c < page.index.size(); ++c) {
    batch.positions[c] = vpos[page.index[c]];
    if (page.has_normals) batch.normals[c] = vnrm[page.index[c]];
  }
  return {};
}

}  // namespace

Status decode_page(std::span<const uint8_t> bytes, const PageGrid& grid, TriangleBatch& batch) {
  thread_local GridPage page;
  return decode_page_into(bytes, grid, batch, page);
}

void PageMesh::decode_normals() {
  normals.resize(normal_codes.size());
  for (size_t v = 0; v < normal_codes.size(); ++v) normals[v] = decode_octahedral(normal_codes[v]);
}

Status decode_page_mesh(std::span<const uint8_t> bytes, const PageGrid& grid, PageMesh& out) {
  out.clear();
  thread_local GridPage page;
  RAYLOD_RETURN_IF_ERROR(parse_page_positions(bytes, grid, page, out.positions));
  out.normal_codes.swap(page.codes);
  out.index.swap(page.index);
  return {};
}

Status decode_page_grid(std::span<const uint8_t> bytes, const PageGrid& grid, std::vector<uint32_t>& positions,
                        std::vector<uint32_t>& normals) {
  thread_local GridPage page;
  RAYLOD_RETURN_IF_ERROR(parse_page(bytes, grid, page));
  for (uint32_t i : page.index) {
    positions.insert(positions.end(), &page.q[3 * size_t(i)], &page.q[3 * size_t(i)] + 3);
    if (page.has_normals) normals.push_back(page.codes[i]);
  }
  return {};
}

}  // namespace raylod
