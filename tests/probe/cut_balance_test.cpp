// balance_cut: tiny exact cases, a seeded property test against a
// brute-force check of every pair of cut cells, and the probe's graded cuts.
#include "probe/cut_balance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "cut_grading_check.h"
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

// A cut cell: a collapsed node whose parent is not collapsed. Found here
// by a search per node, apart from cut_cells' merge walk.
std::vector<CellKey> brute_cut_cells(const std::vector<std::vector<uint64_t>>& codes,
                                     const std::vector<std::vector<char>>& collapsed) {
  std::vector<CellKey> cells;
  for (size_t L = 0; L < codes.size(); ++L)
    for (size_t i = 0; i < codes[L].size(); ++i) {
      if (!collapsed[L][i]) continue;
      bool top = true;
      if (L > 0) {
        const auto& p = codes[L - 1];
        auto it = std::lower_bound(p.begin(), p.end(), codes[L][i] >> 3);
        top = !(it != p.end() && *it == (codes[L][i] >> 3) && collapsed[L - 1][size_t(it - p.begin())]);
      }
      if (top) cells.push_back(CellKey{uint32_t(L), codes[L][i]});
    }
  return cells;
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
  ASSERT_GT(test::ungraded_pairs(brute_cut_cells(codes, collapsed), Q), 0u);
  EXPECT_EQ(balance_cut(codes, collapsed), 7u);
  const auto cells = brute_cut_cells(codes, collapsed);
  EXPECT_EQ(test::ungraded_pairs(cells, Q), 0u);
  size_t at[4] = {};
  for (const CellKey& c : cells) ++at[c.level];
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

// A coarse cut cell is split when its box touches a fine one, even where
// the space inside it next to the fine cell holds no node (its
// representative's triangles may reach across); a coarse cell that does not
// touch stays whole.
TEST(CutBalance, TouchingCountsThroughEmptySpaceInsideACell) {
  const int Q = 4;
  // Level-4 coordinates. The fine cut cell (8, 0, 0) of level 4; the coarse
  // cut cell (0, 0, 0) of level 1 is [0, 8)^3 and touches it at x = 8; the
  // coarse cut cell (0, 1, 0) of level 1, [0, 8) x [8, 16) x [0, 8), does not.
  for (bool bridge : {false, true}) {
    std::vector<std::vector<uint64_t>> codes(Q + 1);
    auto add = [&](uint32_t x, uint32_t y, uint32_t z) {
      const uint64_t code = morton_encode(x, y, z);
      for (int L = Q; L >= 0; --L) codes[size_t(L)].push_back(code >> (3 * (Q - L)));
    };
    add(8, 0, 0);
    add(0, 0, 0);   // far from the fine cell, inside the touching coarse cell
    add(0, 12, 0);  // inside the coarse cell that does not touch
    // Without the bridge, the coarse cell holds no node next to the fine
    // cell (its level-2 cell (1, 0, 0) is empty); with it, it does.
    if (bridge) add(7, 0, 0);
    for (auto& level : codes) {
      std::sort(level.begin(), level.end());
      level.erase(std::unique(level.begin(), level.end()), level.end());
    }
    auto collapsed = none_collapsed(codes);
    collapse(codes, collapsed, 4, morton_encode(8, 0, 0));
    collapse(codes, collapsed, 1, morton_encode(0, 0, 0));
    collapse(codes, collapsed, 1, morton_encode(0, 1, 0));
    // Without the bridge one split (the level-1 cell; its one child,
    // [0, 4)^3, does not touch); with it two (then its child [4, 8) x
    // [0, 4) x [0, 4), which touches).
    EXPECT_EQ(balance_cut(codes, collapsed), bridge ? 2u : 1u) << "bridge " << bridge;
    const auto cells = brute_cut_cells(codes, collapsed);
    EXPECT_EQ(test::ungraded_pairs(cells, Q), 0u);
    size_t at[Q + 1] = {};
    for (const CellKey& c : cells) ++at[c.level];
    EXPECT_EQ(at[1], 1u) << "the coarse cell that does not touch stays whole";
    EXPECT_EQ(at[2], 1u);
    EXPECT_EQ(at[3], bridge ? 1u : 0u);
    EXPECT_EQ(at[4], 1u);
  }
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
    // The least graded refinement is unique: split whatever cut cell
    // touches one two or more levels finer, by brute force, until none does.
    auto fixpoint = collapsed;
    for (bool changed = true; changed;) {
      changed = false;
      const auto now = brute_cut_cells(codes, fixpoint);
      for (const CellKey& a : now)
        for (const CellKey& b : now)
          if (int(b.level) - int(a.level) > 1 && test::cells_touch(a, b, Q)) {
            const auto& level = codes[size_t(a.level)];
            fixpoint[size_t(a.level)][size_t(std::lower_bound(level.begin(), level.end(), a.code) - level.begin())] = 0;
            changed = true;
          }
    }
    balance_cut(codes, collapsed);
    EXPECT_EQ(collapsed, fixpoint) << "trial " << trial << ": not the least graded refinement";
    const auto cells = brute_cut_cells(codes, collapsed);
    EXPECT_EQ(test::ungraded_pairs(cells, Q), 0u) << "trial " << trial;
    EXPECT_EQ(cut_cells(codes, collapsed), cells) << "trial " << trial;
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
