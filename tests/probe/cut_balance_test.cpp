// balance_cut: tiny exact cases, a seeded property test against a
// brute-force check of every pair of cut cells, and the probe's graded cuts.
#include "probe/cut_balance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "streaming/octree_store.h"

namespace raylod {
namespace {

// A complete octree of depth Q: every node of every level exists.
std::vector<std::vector<uint64_t>> full_tree(int Q) {
  std::vector<std::vector<uint64_t>> codes(size_t(Q) + 1);
  for (int L = 0; L <= Q; ++L)
    for (uint64_t c = 0; c < (uint64_t(1) << (3 * L)); ++c) codes[size_t(L)].push_back(c);
  return codes;
}

// A cut cell: a collapsed node whose parent is not collapsed.
struct CutCell {
  int level;
  uint64_t code;
};

std::vector<CutCell> cut_cells(const std::vector<std::vector<uint64_t>>& codes,
                               const std::vector<std::vector<char>>& collapsed) {
  std::vector<CutCell> cells;
  for (size_t L = 0; L < codes.size(); ++L)
    for (size_t i = 0; i < codes[L].size(); ++i) {
      if (!collapsed[L][i]) continue;
      bool top = true;
      if (L > 0) {
        const auto& p = codes[L - 1];
        auto it = std::lower_bound(p.begin(), p.end(), codes[L][i] >> 3);
        top = !(it != p.end() && *it == (codes[L][i] >> 3) && collapsed[L - 1][size_t(it - p.begin())]);
      }
      if (top) cells.push_back({int(L), codes[L][i]});
    }
  return cells;
}

// Whether the closed boxes of two cells touch (at a face, an edge or a
// corner, or overlap), in units of the level-Q cells.
bool touch(const CutCell& a, const CutCell& b, int Q) {
  uint32_t p[2][3];
  morton_decode(a.code, p[0][0], p[0][1], p[0][2]);
  morton_decode(b.code, p[1][0], p[1][1], p[1][2]);
  const int64_t sa = int64_t(1) << (Q - a.level), sb = int64_t(1) << (Q - b.level);
  for (int k = 0; k < 3; ++k) {
    const int64_t alo = p[0][k] * sa, ahi = alo + sa, blo = p[1][k] * sb, bhi = blo + sb;
    if (alo > bhi || blo > ahi) return false;
  }
  return true;
}

// Brute force: the pairs of cut cells that touch and whose levels differ by
// more than one.
size_t unbalanced_pairs(const std::vector<CutCell>& cells, int Q) {
  size_t bad = 0;
  for (size_t a = 0; a < cells.size(); ++a)
    for (size_t b = a + 1; b < cells.size(); ++b)
      bad += std::abs(cells[a].level - cells[b].level) > 1 && touch(cells[a], cells[b], Q);
  return bad;
}

// Marks node (L, code) and everything below it collapsed.
void collapse(const std::vector<std::vector<uint64_t>>& codes, std::vector<std::vector<char>>& collapsed, int L,
              uint64_t code) {
  for (size_t l = size_t(L); l < codes.size(); ++l) {
    const uint64_t shift = 3 * (l - size_t(L));
    for (size_t i = 0; i < codes[l].size(); ++i)
      if ((codes[l][i] >> shift) == code) collapsed[l][i] = 1;
  }
}

std::vector<std::vector<char>> none_collapsed(const std::vector<std::vector<uint64_t>>& codes) {
  std::vector<std::vector<char>> c(codes.size());
  for (size_t L = 0; L < codes.size(); ++L) c[L].assign(codes[L].size(), 0);
  return c;
}

// Seven level-1 cells around an eighth cut at level 3: the seven all touch
// it (at the cube's centre at least) and split once each into level 2, which
// is then balanced; nothing else changes.
TEST(CutBalance, CoarseCellsBesideFineOnesSplitOnce) {
  const int Q = 3;
  const auto codes = full_tree(Q);
  auto collapsed = none_collapsed(codes);
  for (uint64_t c = 0; c < 7; ++c) collapse(codes, collapsed, 1, c);
  for (uint64_t c = 0; c < 64; ++c) collapse(codes, collapsed, 3, (uint64_t(7) << 6) | c);
  ASSERT_GT(unbalanced_pairs(cut_cells(codes, collapsed), Q), 0u);
  EXPECT_EQ(balance_cut(codes, collapsed), 7u);
  const auto cells = cut_cells(codes, collapsed);
  EXPECT_EQ(unbalanced_pairs(cells, Q), 0u);
  size_t at[4] = {};
  for (const CutCell& c : cells) ++at[c.level];
  EXPECT_EQ(at[1], 0u);
  EXPECT_EQ(at[2], 7u * 8u);
  EXPECT_EQ(at[3], 64u);
}

// A balanced cut stays as it is: one level everywhere, or levels differing
// by one.
TEST(CutBalance, ABalancedCutIsLeftAlone) {
  const int Q = 3;
  const auto codes = full_tree(Q);
  auto uniform = none_collapsed(codes);
  for (uint64_t c = 0; c < 64; ++c) collapse(codes, uniform, 2, c);
  const auto before = uniform;
  EXPECT_EQ(balance_cut(codes, uniform), 0u);
  EXPECT_EQ(uniform, before);
  auto graded = none_collapsed(codes);
  for (uint64_t c = 0; c < 7; ++c) collapse(codes, graded, 1, c);
  for (uint64_t c = 0; c < 8; ++c) collapse(codes, graded, 2, (uint64_t(7) << 3) | c);
  const auto graded_before = graded;
  EXPECT_EQ(balance_cut(codes, graded), 0u);
  EXPECT_EQ(graded, graded_before);
}

// Space with no node joins no triangles: a coarse cell across empty space
// from a fine one is not split.
TEST(CutBalance, EmptySpaceDoesNotPropagate) {
  const int Q = 3;
  // Two clusters of nodes at opposite corners of the root, far apart.
  std::vector<std::vector<uint64_t>> codes(Q + 1);
  codes[0] = {0};
  codes[1] = {0, 7};
  codes[2] = {0, 63};
  codes[3] = {0, 511};
  auto collapsed = none_collapsed(codes);
  collapse(codes, collapsed, 1, 0);   // coarse, at the origin corner
  collapse(codes, collapsed, 3, 511); // fine, at the far corner
  const auto before = collapsed;
  EXPECT_EQ(balance_cut(codes, collapsed), 0u);
  EXPECT_EQ(collapsed, before);
}

// Property (seeded): random sparse trees and random cuts, balanced, have no
// touching cut cells more than one level apart (brute force over all pairs);
// balancing only splits (every originally collapsed point stays covered by
// a cell at least as fine) and never collapses a node the cut kept.
TEST(CutBalance, RandomCutsComeOutGradedBySplittingOnly) {
  const int Q = 5;
  std::mt19937_64 rng(20261126);
  for (int trial = 0; trial < 40; ++trial) {
    // A sparse tree: random finest nodes and their ancestors.
    std::vector<std::vector<uint64_t>> codes(Q + 1);
    const int leaves = 30 + int(rng() % 300);
    for (int i = 0; i < leaves; ++i) {
      // Points along a random smooth-ish sheet, so that nodes are neighbours.
      const uint32_t x = uint32_t(rng() % 32), y = uint32_t(rng() % 32);
      const uint32_t z = std::min<uint32_t>(31, (x + y) / 2 + uint32_t(rng() % 3));
      const uint64_t code = morton_encode(x, y, z);
      for (int L = Q; L >= 0; --L) codes[size_t(L)].push_back(code >> (3 * (Q - L)));
    }
    for (auto& level : codes) {
      std::sort(level.begin(), level.end());
      level.erase(std::unique(level.begin(), level.end()), level.end());
    }
    auto collapsed = none_collapsed(codes);
    // Random cut cells at random levels, top-down.
    for (int L = 1; L <= Q; ++L)
      for (uint64_t c : codes[size_t(L)])
        if (rng() % 4 == 0) collapse(codes, collapsed, L, c);
    const auto before = collapsed;
    balance_cut(codes, collapsed);
    const auto cells = cut_cells(codes, collapsed);
    EXPECT_EQ(unbalanced_pairs(cells, Q), 0u) << "trial " << trial;
    for (size_t L = 0; L <= size_t(Q); ++L)
      for (size_t i = 0; i < codes[L].size(); ++i) {
        // Splitting clears a cut cell's flag and leaves its children's.
        EXPECT_LE(collapsed[L][i], before[L][i]) << "trial " << trial;
        if (L == size_t(Q)) {
          EXPECT_EQ(collapsed[L][i], before[L][i]) << "trial " << trial;
        }
      }
  }
}

}  // namespace
}  // namespace raylod
