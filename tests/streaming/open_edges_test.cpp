// Open edges (streaming/open_edges.h): tiny exact cases, and matching across
// pages against a brute-force count over the whole mesh.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "streaming/open_edges.h"

namespace raylod {
namespace {

using Tri = std::array<uint32_t, 9>;

GridEdge edge(std::array<uint32_t, 3> a, std::array<uint32_t, 3> b) {
  if (b < a) std::swap(a, b);
  return {a[0], a[1], a[2], b[0], b[1], b[2]};
}

// A page as the encoder gives it: one vertex per corner here (positions
// repeat; normal code = the corner number, as if every corner had its own
// normal, so only positions can join them).
struct Page {
  std::vector<uint32_t> keys, corners;
};
Page page_of(const std::vector<Tri>& tris) {
  Page p;
  for (const Tri& t : tris)
    for (int k = 0; k < 3; ++k) {
      p.corners.push_back(uint32_t(p.keys.size() / 4));
      p.keys.insert(p.keys.end(), {t[3 * k], t[3 * k + 1], t[3 * k + 2], uint32_t(p.corners.size())});
    }
  return p;
}

// Sorted (find_open_edges reports in its own order).
std::vector<GridEdge> open_of(const std::vector<Tri>& tris, OpenEdgeScratch* reuse = nullptr) {
  OpenEdgeScratch scratch;
  std::vector<GridEdge> out;
  const Page p = page_of(tris);
  find_open_edges(p.keys, p.corners, reuse ? *reuse : scratch, out);
  std::sort(out.begin(), out.end());
  return out;
}

TEST(OpenEdges, OneTriangleTwoTrianglesATetrahedron) {
  const Tri t0{0, 0, 0, 4, 0, 0, 0, 4, 0};
  std::vector<GridEdge> three{edge({0, 0, 0}, {4, 0, 0}), edge({4, 0, 0}, {0, 4, 0}), edge({0, 4, 0}, {0, 0, 0})};
  std::sort(three.begin(), three.end());
  EXPECT_EQ(open_of({t0}), three);
  // Sharing the edge (4,0,0)-(0,4,0), in the opposite direction.
  const Tri t1{4, 0, 0, 4, 4, 0, 0, 4, 0};
  const auto two = open_of({t0, t1});
  EXPECT_EQ(two.size(), 4u);
  EXPECT_EQ(std::count(two.begin(), two.end(), edge({4, 0, 0}, {0, 4, 0})), 0);
  // A closed tetrahedron has none.
  const std::array<uint32_t, 3> a{0, 0, 0}, b{4, 0, 0}, c{0, 4, 0}, d{0, 0, 4};
  auto tri = [](auto p, auto q, auto r) { return Tri{p[0], p[1], p[2], q[0], q[1], q[2], r[0], r[1], r[2]}; };
  EXPECT_TRUE(open_of({tri(a, c, b), tri(a, b, d), tri(b, c, d), tri(c, a, d)}).empty());
  // A degenerate triangle (repeated corner) has one edge, twice: not open.
  EXPECT_TRUE(open_of({tri(a, a, b)}).empty());
  // Three triangles on one edge (non-manifold): used more than once, not open.
  const std::array<uint32_t, 3> e{2, 2, 2};
  const auto fan = open_of({tri(a, b, c), tri(b, a, d), tri(a, b, e)});
  EXPECT_EQ(std::count(fan.begin(), fan.end(), edge(a, b)), 0);
  EXPECT_EQ(fan.size(), 6u);
}

TEST(OpenEdges, AReusedScratchForgetsThePreviousPage) {
  OpenEdgeScratch scratch;
  const Tri t0{0, 0, 0, 4, 0, 0, 0, 4, 0}, t1{4, 0, 0, 4, 4, 0, 0, 4, 0};
  EXPECT_EQ(open_of({t0, t1}, &scratch).size(), 4u);
  // The next page shares nothing with the last: its one triangle's three edges.
  EXPECT_EQ(open_of({t1}, &scratch).size(), 3u);
}

TEST(OpenEdges, AFanOfManyTrianglesAroundOneVertex) {
  // 40 triangles around the origin (more neighbours than a vertex's short
  // list holds): closed fan, so only the 40 rim edges are open.
  std::vector<Tri> fan;
  auto rim = [](int i) { return std::array<uint32_t, 3>{1000 + uint32_t(i % 40), 7, 9}; };
  for (int i = 0; i < 40; ++i) {
    const auto a = rim(i), b = rim(i + 1);
    fan.push_back(Tri{500, 500, 500, a[0], a[1], a[2], b[0], b[1], b[2]});
  }
  const auto open = open_of(fan);
  EXPECT_EQ(open.size(), 40u);
  for (const GridEdge& e : open) EXPECT_NE(e[0], 500u);  // no spoke is open
  // Half of it: the two outer spokes are open too.
  const auto half = open_of(std::vector<Tri>(fan.begin(), fan.begin() + 20));
  EXPECT_EQ(half.size(), 22u);
}

TEST(OpenEdgesProperty, PagesMatchedAgreeWithAWholeMeshCount) {
  // Random triangles on a small grid (so that edges repeat), cut into random
  // pages. Each page reports the edges it uses once; the matcher keeps those
  // reported by an odd number of pages, which includes every edge the whole
  // mesh uses once (an edge open across two pages is interior).
  std::mt19937 rng(11);
  for (int round = 0; round < 20; ++round) {
    std::vector<Tri> tris;
    std::uniform_int_distribution<uint32_t> coord(0, 3);
    for (int i = 0; i < 300; ++i) {
      Tri t;
      for (uint32_t& v : t) v = coord(rng);
      tris.push_back(t);
    }
    // Whole-mesh reference: edges used once.
    std::map<GridEdge, int> uses;
    for (const Tri& t : tris)
      for (int k = 0; k < 3; ++k) {
        const std::array<uint32_t, 3> p{t[3 * k], t[3 * k + 1], t[3 * k + 2]};
        const int m = (k + 1) % 3;
        const std::array<uint32_t, 3> q{t[3 * m], t[3 * m + 1], t[3 * m + 2]};
        if (p != q) ++uses[edge(p, q)];
      }
    // Pages: contiguous runs of random length.
    OpenEdgeMatcher matcher;
    std::map<GridEdge, int> pages_with_one_use;  // in how many pages an edge is open
    size_t at = 0;
    while (at < tris.size()) {
      const size_t len = std::min<size_t>(tris.size() - at, 1 + rng() % 60);
      const std::vector<Tri> page(tris.begin() + long(at), tris.begin() + long(at + len));
      const auto open = open_of(page);
      EXPECT_TRUE(std::is_sorted(open.begin(), open.end()));
      for (const GridEdge& e : open) ++pages_with_one_use[e];
      matcher.add(open);
      at += len;
    }
    // The matcher keeps an edge open in an odd number of pages.
    std::set<GridEdge> expected;
    for (const auto& [e, n] : pages_with_one_use)
      if (n % 2 == 1) expected.insert(e);
    const std::vector<GridEdge> pending = matcher.open();
    std::set<GridEdge> got(pending.begin(), pending.end());
    EXPECT_EQ(matcher.size(), pending.size());
    EXPECT_EQ(got, expected) << "round " << round;
    // Every edge of one use in the whole mesh is among them.
    for (const auto& [e, n] : uses) {
      if (n == 1) {
        EXPECT_EQ(got.count(e), 1u) << "round " << round;
      }
    }
  }
}

TEST(OpenEdgesProperty, MatcherIsASetThatToggles) {
  // Random edges from a small pool, added in random batches: the matcher
  // holds exactly those added an odd number of times (a std::set reference),
  // through its table's growth and its erases.
  std::mt19937 rng(5);
  std::vector<GridEdge> pool;
  for (uint32_t i = 0; i < 3000; ++i) pool.push_back(GridEdge{i % 17, i / 17, 3, i % 5 + 100, i, 7});
  OpenEdgeMatcher matcher;
  std::set<GridEdge> reference;
  size_t most = 0;
  for (int round = 0; round < 400; ++round) {
    std::vector<GridEdge> batch;
    const size_t n = rng() % 300;
    for (size_t i = 0; i < n; ++i) {
      const GridEdge& e = pool[rng() % pool.size()];
      batch.push_back(e);
      if (!reference.erase(e)) reference.insert(e);
      most = std::max(most, reference.size());  // an upper bound: the matcher counts per batch
    }
    matcher.add(batch);
    ASSERT_EQ(matcher.size(), reference.size()) << "round " << round;
  }
  const std::vector<GridEdge> open = matcher.open();
  EXPECT_EQ(std::set<GridEdge>(open.begin(), open.end()), reference);
  EXPECT_LE(matcher.peak(), most);
  matcher.clear();
  EXPECT_EQ(matcher.size(), 0u);
  EXPECT_TRUE(matcher.open().empty());
}

}  // namespace
}  // namespace raylod
