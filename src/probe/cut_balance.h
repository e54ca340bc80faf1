#pragma once
// Grading a cut (2:1 balance): no collapsed cell lies beside a region
// collapsed two or more levels coarser.
//
// Vertex clustering joins the representatives of neighbouring cells by
// triangles, so a triangle between a fine cell and a coarse one spans the
// coarse cell, and its interpolated normal and position follow the coarse
// cell's extent, not the fine cell's bound. Splitting the coarser cell until
// neighbours differ by at most one level keeps every triangle within about
// the size its cells were chosen for.
#include <cstdint>
#include <vector>

#include "streaming/octree_store.h"

namespace raylod {

// codes[L]: the sorted Morton codes of the store's nodes at level L (0..Q).
// collapsed[L][i]: node i of level L is collapsed (itself or inside a
// collapsed ancestor); a collapsed node whose parent is not is a cut cell.
// Clears the flag of cut cells (making their children cut cells) until
// every cut cell's 26 neighbours at its own level lie in cut cells at most
// one level coarser, or in space with no node. Nodes left whole (not
// collapsed) constrain nothing: counting finest ones as cells of level
// Q + 1 split more cells on the glass scene for no gain (35.04 dB at
// 862,064 triangles against 35.03 at 853,684). Returns the number of cells
// split.
uint64_t balance_cut(const std::vector<std::vector<uint64_t>>& codes, std::vector<std::vector<char>>& collapsed);

// For each of a level's sorted `codes`, whether its parent among the level
// above's sorted `parents` exists and is flagged in `parent_flags`: one
// merge walk.
std::vector<char> flagged_parents(const std::vector<uint64_t>& codes, const std::vector<uint64_t>& parents,
                                  const std::vector<char>& parent_flags);

// The cut cells of `collapsed` (as above), level by level in code order.
std::vector<CellKey> cut_cells(const std::vector<std::vector<uint64_t>>& codes,
                               const std::vector<std::vector<char>>& collapsed);

}  // namespace raylod
