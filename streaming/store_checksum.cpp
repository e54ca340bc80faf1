// Checksums for the octree store: CRC-32C (Castagnoli polynomial 0x82F63B78,
// reflected) for headers, tables and pages, using the SSE4.2 crc32
// instruction when the CPU has it; and a 64-bit content hash for mesh files
// (four independent multiply-rotate lanes so the loop runs at memory speed).
#include <cstring>

#include "streaming/octree_store.h"

#if defined(__x86_64__) || defined(__i386__)
#include <nmmintrin.h>
#define RAYLOD_HAVE_X86_CRC 1
#endif

namespace raylod {
namespace {

struct Crc32cTable {
  uint32_t t[8][256];
  Crc32cTable() {
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0x82F63B78u & (0u - (c & 1u)));
      t[0][i] = c;
    }
    for (uint32_t i = 0; i < 256; ++i)
      for (int s = 1; s < 8; ++s) t[s][i] = (t[s - 1][i] >> 8) ^ t[0][t[s - 1][i] & 0xff];
  }
};

uint32_t crc32c_soft(const unsigned char* p, size_t n, uint32_t crc) {
  static const Crc32cTable table;
  const auto& t = table.t;
  while (n >= 8) {  // slice-by-8
    uint64_t w;
    std::memcpy(&w, p, 8);
    w ^= crc;
    crc = t[7][w & 0xff] ^ t[6][(w >> 8) & 0xff] ^ t[5][(w >> 16) & 0xff] ^ t[4][(w >> 24) & 0xff] ^
          t[3][(w >> 32) & 0xff] ^ t[2][(w >> 40) & 0xff] ^ t[1][(w >> 48) & 0xff] ^ t[0][w >> 56];
    p += 8;
    n -= 8;
  }
  while (n--) crc = (crc >> 8) ^ t[0][(crc ^ *p++) & 0xff];
  return crc;
}

#ifdef RAYLOD_HAVE_X86_CRC
__attribute__((target("sse4.2"))) uint32_t crc32c_hw(const unsigned char* p, size_t n, uint32_t crc) {
  uint64_t c = crc;
  while (n >= 8) {
    uint64_t w;
    std::memcpy(&w, p, 8);
    c = _mm_crc32_u64(c, w);
    p += 8;
    n -= 8;
  }
  uint32_t c32 = uint32_t(c);
  while (n--) c32 = _mm_crc32_u8(c32, *p++);
  return c32;
}
const bool kHaveHwCrc = __builtin_cpu_supports("sse4.2");
#endif

constexpr uint64_t kP1 = 0x9E3779B185EBCA87ull, kP2 = 0xC2B2AE3D27D4EB4Full, kP3 = 0x165667B19E3779F9ull;
inline uint64_t rotl(uint64_t x, int r) { return (x << r) | (x >> (64 - r)); }
inline uint64_t round64(uint64_t acc, uint64_t w) { return rotl(acc + w * kP2, 31) * kP1; }
inline uint64_t mix64(uint64_t h) {
  h ^= h >> 33; h *= kP2; h ^= h >> 29; h *= kP3; h ^= h >> 32;
  return h;
}

}  // namespace

uint32_t crc32c(const void* data, size_t bytes, uint32_t crc) {
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
#ifdef RAYLOD_HAVE_X86_CRC
  crc = kHaveHwCrc ? crc32c_hw(p, bytes, crc) : crc32c_soft(p, bytes, crc);
#else
  crc = crc32c_soft(p, bytes, crc);
#endif
  return ~crc;
}

namespace {

// CRC combination: appending n zero bytes to a message is a linear map on
// the CRC register, so crc(a + b) = Z^len(b) crc(a) ^ crc(b), with Z^len
// built by repeated squaring of the one-zero-bit operator over GF(2).
uint32_t gf2_times(const uint32_t* mat, uint32_t vec) {
  uint32_t sum = 0;
  for (; vec; vec >>= 1, ++mat)
    if (vec & 1) sum ^= *mat;
  return sum;
}

void gf2_square(uint32_t* square, const uint32_t* mat) {
  for (int n = 0; n < 32; ++n) square[n] = gf2_times(mat, mat[n]);
}

}  // namespace

uint32_t crc32c_combine(uint32_t crc_a, uint32_t crc_b, uint64_t bytes_b) {
  if (bytes_b == 0) return crc_a;
  uint32_t even[32], odd[32];
  odd[0] = 0x82F63B78u;  // one zero bit
  for (int n = 1; n < 32; ++n) odd[n] = 1u << (n - 1);
  gf2_square(even, odd);  // two zero bits
  gf2_square(odd, even);  // four zero bits
  // Each step squares the operator (one zero byte, then 2, 4, ...).
  for (;;) {
    gf2_square(even, odd);
    if (bytes_b & 1) crc_a = gf2_times(even, crc_a);
    bytes_b >>= 1;
    if (!bytes_b) break;
    gf2_square(odd, even);
    if (bytes_b & 1) crc_a = gf2_times(odd, crc_a);
    bytes_b >>= 1;
    if (!bytes_b) break;
  }
  return crc_a ^ crc_b;
}

void ContentHasher::update(const void* data, size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  total_ += bytes;
  if (tail_bytes_) {
    size_t take = std::min(bytes, 32 - tail_bytes_);
    std::memcpy(tail_ + tail_bytes_, p, take);
    tail_bytes_ += take; p += take; bytes -= take;
    if (tail_bytes_ < 32) return;
    for (int l = 0; l < 4; ++l) {
      uint64_t w; std::memcpy(&w, tail_ + 8 * l, 8);
      lanes_[l] = round64(lanes_[l], w);
    }
    tail_bytes_ = 0;
  }
  uint64_t a = lanes_[0], b = lanes_[1], c = lanes_[2], d = lanes_[3];
  while (bytes >= 32) {
    uint64_t w[4];
    std::memcpy(w, p, 32);
    a = round64(a, w[0]); b = round64(b, w[1]); c = round64(c, w[2]); d = round64(d, w[3]);
    p += 32; bytes -= 32;
  }
  lanes_[0] = a; lanes_[1] = b; lanes_[2] = c; lanes_[3] = d;
  std::memcpy(tail_, p, bytes);
  tail_bytes_ = bytes;
}

uint64_t ContentHasher::digest() const {
  uint64_t h = rotl(lanes_[0], 1) + rotl(lanes_[1], 7) + rotl(lanes_[2], 12) + rotl(lanes_[3], 18);
  h ^= total_ * kP3;
  for (size_t i = 0; i < tail_bytes_; ++i) h = rotl(h ^ (tail_[i] * kP1), 11) * kP2;
  return mix64(h);
}

uint64_t content_hash64(const void* data, size_t bytes) {
  ContentHasher h;
  h.update(data, bytes);
  return h.digest();
}

}  // namespace raylod
