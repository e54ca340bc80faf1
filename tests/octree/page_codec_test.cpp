// The compact page encoding (streaming/page_codec.h): tiny exact cases,
// seeded round trips within the stated bounds, and refusal of malformed bytes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "streaming/page_codec.h"

namespace raylod {
namespace {

const PageGrid kGrid = page_grid(Vec3d(-8), 16.0, 20);  // step 16 / 2^20

struct Encoded {
  std::vector<uint8_t> bytes;
  Bbox bounds;
};

// Quantises the soup onto kGrid and encodes it.
Encoded encode(const std::vector<Vec3>& positions, const std::vector<Vec3>& normals) {
  std::vector<uint32_t> q(3 * positions.size()), n;
  for (size_t c = 0; c < positions.size(); ++c) quantise_position(positions[c], kGrid, &q[3 * c]);
  for (const Vec3& v : normals) n.push_back(encode_octahedral(v));
  PageEncoder encoder;
  Encoded e;
  e.bounds = encode_page(q, n, kGrid, encoder, e.bytes);
  return e;
}

TEST(PageCodec, SharedCornersAreStoredOnce) {
  // Two triangles sharing an edge: 4 vertices, 2-bit indices, and 6 corners.
  const std::vector<Vec3> p = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  const Encoded e = encode(p, {});
  const PageCounts counts = page_counts(e.bytes);
  EXPECT_EQ(counts.triangles, 2u);
  EXPECT_EQ(counts.vertices, 4u);
  // Header, 4 x 3 coordinates of 17 bits (extent 2^16 steps), 6 indices of 2 bits.
  EXPECT_EQ(e.bytes.size(), 24u + (4 * 3 * 17 + 7) / 8 + (6 * 2 + 7) / 8);
  TriangleBatch b;
  ASSERT_TRUE(decode_page(e.bytes, kGrid, b).is_ok());
  ASSERT_EQ(b.size(), 2u);
  EXPECT_TRUE(b.normals.empty());
  for (size_t c = 0; c < 6; ++c) EXPECT_EQ(b.positions[c], p[c]) << "corner " << c;  // on the grid: exact
  EXPECT_EQ(e.bounds.lo, Vec3d(0, 0, 0));
  EXPECT_EQ(e.bounds.hi, Vec3d(1, 1, 0));
}

TEST(PageCodec, CornersWithOtherNormalsStaySeparate) {
  // The same position with two normals (a crease): two vertices, both normals kept.
  const Vec3 up(0, 0, 1), side(1, 0, 0);
  const std::vector<Vec3> p = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  const std::vector<Vec3> n = {up, up, up, side, side, side};
  const Encoded e = encode(p, n);
  EXPECT_EQ(page_counts(e.bytes).vertices, 6u);
  TriangleBatch b;
  ASSERT_TRUE(decode_page(e.bytes, kGrid, b).is_ok());
  for (size_t c = 0; c < 6; ++c) EXPECT_EQ(b.normals[c], n[c]) << "axis normals are exact";
}

TEST(PageCodec, RandomSoupRoundTripsWithinTheBounds) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-7.9f, 7.9f);
  std::normal_distribution<float> g;
  std::vector<Vec3> p, n;
  for (int t = 0; t < 3000; ++t)
    for (int k = 0; k < 3; ++k) {
      p.push_back(Vec3(u(rng), u(rng), u(rng)));
      n.push_back(glm::normalize(Vec3(g(rng), g(rng), g(rng))));
    }
  const Encoded e = encode(p, n);
  TriangleBatch b;
  ASSERT_TRUE(decode_page(e.bytes, kGrid, b).is_ok());
  ASSERT_EQ(b.positions.size(), p.size());
  Bbox decoded;
  double worst = 0, worst_angle = 0;
  for (size_t c = 0; c < p.size(); ++c) {
    decoded.expand(b.positions[c]);
    for (int a = 0; a < 3; ++a) {
      const double allowed = 0.5 * kGrid.step + std::abs(double(p[c][a])) * 0x1p-24;
      worst = std::max(worst, std::abs(double(b.positions[c][a]) - double(p[c][a])) / allowed);
    }
    const Vec3d n0(n[c]), n1(b.normals[c]);
    worst_angle = std::max(worst_angle, std::atan2(glm::length(glm::cross(n0, n1)), glm::dot(n0, n1)));
  }
  EXPECT_LE(worst, 1.0);
  EXPECT_GT(worst, 0.1) << "random positions should use much of the half-step bound";
  EXPECT_LT(worst_angle, 1e-4);
  EXPECT_EQ(decoded.lo, e.bounds.lo);
  EXPECT_EQ(decoded.hi, e.bounds.hi);
}

TEST(PageCodec, OctahedralCodesOverTheSphere) {
  std::mt19937 rng(5);
  std::normal_distribution<float> g;
  double worst = 0;
  for (int i = 0; i < 200000; ++i) {
    const Vec3 n = glm::normalize(Vec3(g(rng), g(rng), g(rng)));
    const Vec3d a(n), b(decode_octahedral(encode_octahedral(n)));
    worst = std::max(worst, std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b)));
  }
  EXPECT_LT(worst, 1e-4);
  for (const Vec3 axis : {Vec3(1, 0, 0), Vec3(0, -1, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)})
    EXPECT_EQ(decode_octahedral(encode_octahedral(axis)), axis);
  EXPECT_EQ(decode_octahedral(encode_octahedral(Vec3(0))), Vec3(0));
  EXPECT_EQ(decode_octahedral(encode_octahedral(Vec3(NAN, 0, 1))), Vec3(0));
}

TEST(PageCodec, EqualPointsDecodeEqualInEveryPage) {
  // A vertex shared by two pages with different origins and bit widths
  // decodes to the same float in both: pages meet without cracks.
  const Vec3 shared(1.2345678f, -3.3333333f, 0.1f);
  const Encoded a = encode({shared, Vec3(1.3f, -3.3f, 0.1f), Vec3(1.2f, -3.2f, 0.2f)}, {});
  const Encoded b = encode({Vec3(-7, 5, 3), shared, Vec3(6, -6, -6)}, {});
  TriangleBatch ta, tb;
  ASSERT_TRUE(decode_page(a.bytes, kGrid, ta).is_ok());
  ASSERT_TRUE(decode_page(b.bytes, kGrid, tb).is_ok());
  EXPECT_EQ(ta.positions[0], tb.positions[1]);
}

TEST(PageCodec, MalformedBytesAreRefused) {
  const std::vector<Vec3> p = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  const Encoded e = encode(p, {});
  TriangleBatch b;
  auto refused = [&](std::vector<uint8_t> bytes, const std::string& what) {
    Status s = decode_page(bytes, kGrid, b);
    EXPECT_FALSE(s.is_ok()) << what;
    EXPECT_TRUE(b.positions.empty()) << what;
  };
  refused({}, "empty");
  refused(std::vector<uint8_t>(e.bytes.begin(), e.bytes.end() - 1), "truncated");
  auto more = e.bytes;
  more.push_back(0);
  refused(more, "a byte too many");
  auto put = [](std::vector<uint8_t> bytes, size_t at, uint32_t v) {
    std::memcpy(bytes.data() + at, &v, 4);
    return bytes;
  };
  refused(put(e.bytes, 0, 3), "more triangles than the bytes hold");
  refused(put(e.bytes, 4, 7), "more vertices than the bytes hold");
  refused(put(e.bytes, 4, 0), "triangles without vertices");
  refused(put(e.bytes, 8, (1u << 20) + 1), "origin outside the root cube");
  // 24 bytes claiming 2^32 - 1 triangles of one vertex: indices take a bit
  // each, so such a page would need over a gigabyte, and is refused before
  // anything is allocated for it.
  std::vector<uint8_t> claims(24, 0);
  const uint32_t many = 0xffffffffu, one_vertex = 1;
  std::memcpy(claims.data(), &many, 4);
  std::memcpy(claims.data() + 4, &one_vertex, 4);
  refused(claims, "a short page claiming billions of triangles");
  claims[21] = 1;
  refused(claims, "the same with one index bit");
  auto wide = e.bytes;
  wide[21] = 3;  // index width not that of 4 vertices
  refused(wide, "index width");
  auto flags = e.bytes;
  flags[23] = 1;
  refused(flags, "unknown flags");
  // An index past the vertices: 4 vertices in 2 bits cannot overflow, so use
  // a page of 3 vertices (2-bit indices, index 3 is out of range).
  Encoded one = encode({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {});
  ASSERT_TRUE(decode_page(one.bytes, kGrid, b).is_ok());
  one.bytes.back() |= 0x03;  // the first index (bits 0-1 of the index section's only byte) becomes 3
  refused(one.bytes, "index out of range");
}

}  // namespace
}  // namespace raylod
