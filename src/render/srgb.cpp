#include "render/srgb.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace raylod {

float linear_to_srgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgb_to_linear(float v) { return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f); }

namespace {

// The formula srgb_byte stands for.
uint8_t byte_by_formula(float v) { return uint8_t(std::lround(linear_to_srgb(v) * 255.0f)); }

constexpr uint32_t kOneBits = 0x3f800000u;          // 1.0f
constexpr uint32_t kBuckets = (kOneBits >> 16) + 1;  // runs of 2^16 floats in [0, 1]

struct ByteTable {
  // step[k]: the bits of the smallest float in [0, 1] whose byte is >= k
  // (k = 1..255; step[0] = 0). Non-negative floats order as their bits.
  std::array<uint32_t, 257> step{};
  // start[i]: the byte of the float with bits i << 16.
  std::array<uint8_t, kBuckets> start{};

  ByteTable() {
    for (int k = 1; k <= 255; ++k) {
      uint32_t lo = step[size_t(k - 1)], hi = kOneBits;  // byte(lo) < k <= byte(hi)
      if (byte_by_formula(std::bit_cast<float>(lo)) >= k) {  // the byte stepped by two at lo
        step[size_t(k)] = lo;
        continue;
      }
      while (hi - lo > 1) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (byte_by_formula(std::bit_cast<float>(mid)) >= k) hi = mid;
        else lo = mid;
      }
      step[size_t(k)] = hi;
    }
    step[256] = UINT32_MAX;  // a sentinel: no byte past 255
    for (uint32_t i = 0; i < kBuckets; ++i) {
      const uint32_t bits = i << 16;
      start[i] = uint8_t(std::upper_bound(step.begin() + 1, step.begin() + 256, bits) - (step.begin() + 1));
    }
  }
};

const ByteTable& byte_table() {
  static const ByteTable table;
  return table;
}

uint8_t byte_from(const ByteTable& t, float v) {
  if (!(v > 0.0f)) return 0;  // NaN, zero and below
  if (v >= 1.0f) return 255;
  const uint32_t bits = std::bit_cast<uint32_t>(v);
  uint32_t k = t.start[bits >> 16];
  while (bits >= t.step[k + 1]) ++k;  // a run of 2^16 floats crosses at most a step or two
  return uint8_t(k);
}

}  // namespace

uint8_t srgb_byte(float v) { return byte_from(byte_table(), v); }

void srgb_bytes(std::span<const float> linear, std::span<uint8_t> out) {
  assert(out.size() == linear.size());
  const ByteTable& t = byte_table();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, linear.size(), size_t(1) << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) out[i] = byte_from(t, linear[i]);
  });
}

}  // namespace raylod
