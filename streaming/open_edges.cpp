// Open boundary edges by counting (see open_edges.h).
#include "streaming/open_edges.h"

#include <algorithm>
#include <bit>

#include "streaming/distinct_keys.h"

namespace raylod {

namespace {

constexpr int kFan = 8;  // neighbours listed per position; more go to the overflow list

}  // namespace

void find_open_edges(std::span<const uint32_t> vertex_keys, std::span<const uint32_t> corner_vertex,
                     OpenEdgeScratch& scratch, std::vector<GridEdge>& out) {
  const size_t nv = vertex_keys.size() / 4;
  if (nv == 0 || corner_vertex.size() < 3) return;
  // Positions: the distinct grid points of the vertices, in first-use order.
  index_distinct_keys<3>(
      nv, [&](size_t v) { return std::array<uint32_t, 3>{vertex_keys[4 * v], vertex_keys[4 * v + 1], vertex_keys[4 * v + 2]}; },
      scratch.slots, scratch.points, scratch.position);
  const size_t np = scratch.points.size() / 3;
  // Each edge is listed at its smaller position, with a use count; a
  // position's list is short (its fan) and was touched a moment ago, so the
  // lookups stay in cache.
  scratch.neighbour.resize(np * kFan);
  scratch.uses.resize(np * kFan);
  scratch.fan.assign(np, 0);
  scratch.overflow.clear();
  for (size_t c = 0; c + 2 < corner_vertex.size(); c += 3)
    for (int k = 0; k < 3; ++k) {
      uint32_t a = scratch.position[corner_vertex[c + size_t(k)]];
      uint32_t b = scratch.position[corner_vertex[c + size_t((k + 1) % 3)]];
      if (a == b) continue;
      if (b < a) std::swap(a, b);
      uint32_t* list = &scratch.neighbour[size_t(a) * kFan];
      uint8_t* uses = &scratch.uses[size_t(a) * kFan];
      const int n = scratch.fan[a];
      int j = 0;
      while (j < n && list[j] != b) ++j;
      if (j < n) {
        uses[j] = 2;
      } else if (n < kFan) {
        list[n] = b;
        uses[n] = 1;
        scratch.fan[a] = uint8_t(n + 1);
      } else {
        scratch.overflow.push_back({a, b});
      }
    }
  auto edge = [&](uint32_t a, uint32_t b) {
    const uint32_t* p = &scratch.points[3 * size_t(a)];
    const uint32_t* q = &scratch.points[3 * size_t(b)];
    if (std::lexicographical_compare(q, q + 3, p, p + 3)) std::swap(p, q);
    return GridEdge{p[0], p[1], p[2], q[0], q[1], q[2]};
  };
  for (uint32_t a = 0; a < np; ++a)
    for (int j = 0; j < scratch.fan[a]; ++j)
      if (scratch.uses[size_t(a) * kFan + size_t(j)] == 1) out.push_back(edge(a, scratch.neighbour[size_t(a) * kFan + size_t(j)]));
  // Edges from positions with more than kFan neighbours: counted by sorting.
  std::sort(scratch.overflow.begin(), scratch.overflow.end());
  for (size_t i = 0; i < scratch.overflow.size();) {
    size_t j = i + 1;
    while (j < scratch.overflow.size() && scratch.overflow[j] == scratch.overflow[i]) ++j;
    if (j == i + 1) out.push_back(edge(scratch.overflow[i].first, scratch.overflow[i].second));
    i = j;
  }
}

void OpenEdgeMatcher::add(std::span<const GridEdge> page_open_edges) {
  for (const GridEdge& e : page_open_edges) toggle(e);
  peak_ = std::max(peak_, count_);
}

void OpenEdgeMatcher::toggle(const GridEdge& e) {
  if (2 * (count_ + 1) > slots_.size()) grow();
  const size_t mask = slots_.size() - 1;
  const GridEdgeHash hash;
  size_t i = hash(e) & mask;
  for (; slots_[i] != kEmpty; i = (i + 1) & mask) {
    if (slots_[i] != e) continue;
    // Matched: erase, shifting back every later entry of the run whose home
    // is not between the hole and it.
    for (size_t j = i;;) {
      j = (j + 1) & mask;
      if (slots_[j] == kEmpty) break;
      const size_t home = hash(slots_[j]) & mask;
      const bool stays = i <= j ? (i < home && home <= j) : (i < home || home <= j);
      if (stays) continue;
      slots_[i] = slots_[j];
      i = j;
    }
    slots_[i] = kEmpty;
    --count_;
    return;
  }
  slots_[i] = e;
  ++count_;
}

void OpenEdgeMatcher::grow() {
  std::vector<GridEdge> old(std::max<size_t>(64, 2 * slots_.size()), kEmpty);
  old.swap(slots_);
  const size_t mask = slots_.size() - 1;
  const GridEdgeHash hash;
  for (const GridEdge& e : old)
    if (e != kEmpty) {
      size_t i = hash(e) & mask;
      while (slots_[i] != kEmpty) i = (i + 1) & mask;
      slots_[i] = e;
    }
}

std::vector<GridEdge> OpenEdgeMatcher::open() const {
  std::vector<GridEdge> v;
  for_each([&](const GridEdge& e) { v.push_back(e); });
  std::sort(v.begin(), v.end());
  return v;
}

}  // namespace raylod
