// The 8-bit sRGB encoding (render/srgb.h): the table equals the formula
// lround(linear_to_srgb(v) * 255) it stands for. Checked here on every
// 61st float in [0, 1], on the floats around each step, and on the values
// that are not in [0, 1]; all 1,065,353,217 floats in [0, 1] were compared
// once when it was written (no mismatch).
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "render/srgb.h"

namespace raylod {
namespace {

uint8_t by_formula(float v) { return uint8_t(std::lround(linear_to_srgb(v) * 255.0f)); }

TEST(Srgb, TheTableIsTheFormulaOnASweepOfFloats) {
  size_t mismatches = 0;
  for (uint32_t bits = 0; bits <= 0x3f800000u; bits += 61) {
    const float v = std::bit_cast<float>(bits);
    if (srgb_byte(v) != by_formula(v) && ++mismatches <= 5)
      ADD_FAILURE() << v << ": " << int(srgb_byte(v)) << " against " << int(by_formula(v));
  }
  EXPECT_EQ(mismatches, 0u);
}

TEST(Srgb, TheTableIsTheFormulaAroundEveryStep) {
  // Each step: the first float of byte k and the floats just before it.
  int steps = 0;
  for (uint32_t bits = 1; bits <= 0x3f800000u;) {
    const uint8_t here = by_formula(std::bit_cast<float>(bits));
    // Bisect for the first float past `bits` with a larger byte.
    uint32_t lo = bits, hi = 0x3f800000u;
    if (by_formula(std::bit_cast<float>(hi)) == here) break;
    while (hi - lo > 1) {
      const uint32_t mid = lo + (hi - lo) / 2;
      (by_formula(std::bit_cast<float>(mid)) == here ? lo : hi) = mid;
    }
    for (uint32_t b = hi - 3; b <= hi + 3; ++b) {
      const float v = std::bit_cast<float>(b);
      ASSERT_EQ(srgb_byte(v), by_formula(v)) << v;
    }
    ++steps;
    bits = hi;
  }
  EXPECT_EQ(steps, 255);  // every byte from 0 to 255 is reached
}

TEST(Srgb, ValuesOutsideTheRange) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  EXPECT_EQ(srgb_byte(nan), 0);
  EXPECT_EQ(srgb_byte(-nan), 0);
  EXPECT_EQ(srgb_byte(-inf), 0);
  EXPECT_EQ(srgb_byte(-1.0f), 0);
  EXPECT_EQ(srgb_byte(-0.0f), 0);
  EXPECT_EQ(srgb_byte(0.0f), 0);
  EXPECT_EQ(srgb_byte(std::numeric_limits<float>::denorm_min()), 0);
  EXPECT_EQ(srgb_byte(1.0f), 255);
  EXPECT_EQ(srgb_byte(std::nextafter(1.0f, 2.0f)), 255);
  EXPECT_EQ(srgb_byte(1e30f), 255);
  EXPECT_EQ(srgb_byte(inf), 255);
  // Known values of the standard curve: 18% grey is byte 118, 0.5 is 188.
  EXPECT_EQ(srgb_byte(0.18f), 118);
  EXPECT_EQ(srgb_byte(0.5f), 188);
}

TEST(Srgb, ManyAtOnceAsOneAtATime) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-0.2f, 1.2f);
  std::vector<float> linear(300001);
  for (float& v : linear) v = u(rng);
  linear[17] = std::numeric_limits<float>::quiet_NaN();
  std::vector<uint8_t> bytes(linear.size());
  srgb_bytes(linear, bytes);
  for (size_t i = 0; i < linear.size(); ++i) ASSERT_EQ(bytes[i], srgb_byte(linear[i])) << i;
}

TEST(Srgb, TheInverseUndoesTheCurve) {
  for (int i = 0; i <= 1000; ++i) {
    const float v = float(i) / 1000.0f;
    EXPECT_NEAR(srgb_to_linear(linear_to_srgb(v)), v, 2e-6f) << v;
  }
}

}  // namespace
}  // namespace raylod
