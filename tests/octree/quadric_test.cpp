// Plane quadrics (eq. 4), checksums and Morton codes: tiny exact cases.
#include <gtest/gtest.h>

#include <random>

#include "streaming/octree_store.h"

namespace raylod {
namespace {

TEST(Quadric, ErrorIsWeightedSquaredDistanceToThePlane) {
  const Vec3d n = glm::normalize(Vec3d(1, 2, 2));
  const Vec3d x(0.5, -1, 3);
  const Quadric q = quadric_from_plane(n, x, 2.5);
  EXPECT_NEAR(quadric_error(q, x), 0, 1e-12);
  const Vec3d v = x + 0.3 * n + Vec3d(-2, 1, 0);  // (-2,1,0) is in the plane: n.(-2,1,0) = 0
  EXPECT_NEAR(quadric_error(q, v), 2.5 * 0.09, 1e-12);
}

TEST(Quadric, SumOfTheThreeAxisPlanesIsTheSquaredDistanceToTheirCorner) {
  Quadric q;
  const Vec3d corner(1, 2, 3);
  quadric_add(q, quadric_from_plane({1, 0, 0}, corner));
  quadric_add(q, quadric_from_plane({0, 1, 0}, corner));
  quadric_add(q, quadric_from_plane({0, 0, 1}, corner));
  EXPECT_DOUBLE_EQ(q.a00, 1);
  EXPECT_DOUBLE_EQ(q.a01, 0);
  EXPECT_DOUBLE_EQ(q.b0, 1);
  EXPECT_DOUBLE_EQ(q.b2, 3);
  EXPECT_DOUBLE_EQ(q.c, 14);
  EXPECT_DOUBLE_EQ(quadric_error(q, {0, 0, 0}), 14);
  EXPECT_DOUBLE_EQ(quadric_error(q, corner), 0);
}

TEST(Checksum, Crc32cKnownValueAndChaining) {
  const char* text = "123456789";
  EXPECT_EQ(crc32c(text, 9), 0xE3069283u);  // the CRC-32C check value
  EXPECT_EQ(crc32c(text + 4, 5, crc32c(text, 4)), 0xE3069283u);
  EXPECT_EQ(crc32c(nullptr, 0), 0u);
  EXPECT_EQ(crc32c_combine(crc32c(text, 4), crc32c(text + 4, 5), 5), 0xE3069283u);
  EXPECT_EQ(crc32c_combine(crc32c(text, 9), crc32c(text, 0), 0), 0xE3069283u);
  std::vector<unsigned char> big(1000);
  for (size_t i = 0; i < big.size(); ++i) big[i] = static_cast<unsigned char>(i * 7 + 1);
  uint32_t whole = crc32c(big.data(), big.size());
  for (size_t cut : {size_t(0), size_t(1), size_t(8), size_t(333), size_t(999)})
    EXPECT_EQ(crc32c_combine(crc32c(big.data(), cut), crc32c(big.data() + cut, big.size() - cut), big.size() - cut), whole);
  big[500] ^= 1;
  EXPECT_NE(crc32c(big.data(), big.size()), whole);
}

TEST(Checksum, ContentHashIsStreamingAndSensitive) {
  std::vector<unsigned char> data(10007);
  std::mt19937 rng(3);
  for (auto& b : data) b = static_cast<unsigned char>(rng());
  const uint64_t whole = content_hash64(data.data(), data.size());
  ContentHasher h;
  h.update(data.data(), 5);
  h.update(data.data() + 5, 40);
  h.update(data.data() + 45, data.size() - 45);
  EXPECT_EQ(h.digest(), whole);
  data[9000] ^= 0x10;
  EXPECT_NE(content_hash64(data.data(), data.size()), whole);
  EXPECT_NE(content_hash64(data.data(), data.size() - 1), content_hash64(data.data(), data.size()));
}

TEST(Morton, RoundTripsAndInterleavesXYZ) {
  EXPECT_EQ(morton_encode(1, 0, 0), 1u);
  EXPECT_EQ(morton_encode(0, 1, 0), 2u);
  EXPECT_EQ(morton_encode(0, 0, 1), 4u);
  EXPECT_EQ(morton_encode(2, 0, 0), 8u);
  std::mt19937 rng(1);
  for (int i = 0; i < 1000; ++i) {
    uint32_t x = rng() & 0x1fffff, y = rng() & 0x1fffff, z = rng() & 0x1fffff, a, b, c;
    morton_decode(morton_encode(x, y, z), a, b, c);
    ASSERT_EQ(a, x);
    ASSERT_EQ(b, y);
    ASSERT_EQ(c, z);
    // The parent cell is the code shifted by one level.
    EXPECT_EQ(morton_encode(x >> 1, y >> 1, z >> 1), morton_encode(x, y, z) >> 3);
  }
}

}  // namespace
}  // namespace raylod
