#include "simplify/unfold.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace raylod {

namespace {

constexpr int kProjectionSweeps = 64;

// A triangle of a representative's fan as the half-space its position p
// must lie in: c + m.p >= need, p relative to the representative's
// position. Twice the triangle's area along its input normal n is linear in
// the corner: cross(x - p, y - p).n = cross(x, y).n + p.cross(x - y, n).
struct HalfSpace {
  Vec3d m;
  double c;
  double need;
};

// The mesh as unfold sees it: triangles of provisional ids, their input
// normals (zero for an input triangle without area, which has no side to
// turn over to), and where each id is.
struct UnfoldMesh {
  std::span<std::array<uint32_t, 3>> tris;
  std::span<const Vec3> keys;
  std::span<Vec3> rep_pos;
  std::span<const Vec3> kept_pos;
  const std::function<bool(uint32_t)>& movable_rep;

  uint32_t reps() const { return uint32_t(rep_pos.size()); }
  Vec3d pos(uint32_t v) const { return v < reps() ? Vec3d(rep_pos[v]) : Vec3d(kept_pos[v - reps()]); }
  bool movable(uint32_t v) const { return v < reps() && movable_rep(v); }
  bool keyed(size_t t) const { return keys[t] != Vec3(0); }
  bool folded(size_t t) const {
    const auto& x = tris[t];
    return keyed(t) && faces_against(pos(x[0]), pos(x[1]), pos(x[2]), Vec3d(keys[t]));
  }
  static int corner_of(const std::array<uint32_t, 3>& x, uint32_t v) { return x[0] == v ? 0 : (x[1] == v ? 1 : 2); }
  static bool uses(const std::array<uint32_t, 3>& x, uint32_t v) { return x[0] == v || x[1] == v || x[2] == v; }
  // The corners of t after v, in order: the edge opposite v.
  std::pair<uint32_t, uint32_t> opposite(size_t t, uint32_t v) const {
    const auto& x = tris[t];
    const int k = corner_of(x, v);
    return {x[size_t((k + 1) % 3)], x[size_t((k + 2) % 3)]};
  }
  // Twice the area of t along its input normal with corner v at p (for an
  // unkeyed triangle, its area).
  double twice_area_with(size_t t, uint32_t v, const Vec3d& p) const {
    const auto [a, b] = opposite(t, v);
    const Vec3d n = glm::cross(pos(a) - p, pos(b) - p);
    return keyed(t) ? glm::dot(n, Vec3d(keys[t])) : glm::length(n);
  }
  // The height (twice the area) corner v of t must keep over its opposite
  // edge: `fraction` of that edge's length squared, or for a triangle
  // upright but thinner than that (CAD slivers), half what it has.
  double needed(size_t t, uint32_t v, double fraction) const {
    const auto [a, b] = opposite(t, v);
    const double full = fraction * glm::dot(pos(a) - pos(b), pos(a) - pos(b));
    const double now = folded(t) ? 0.0 : twice_area_with(t, v, pos(v));
    return now > 0 ? std::min(full, 0.5 * now) : full;
  }
  // Whether moving v by d keeps the surface within `allowance` of the plane
  // of triangle t as it is.
  bool within(size_t t, const Vec3d& d, double allowance) const {
    const auto& x = tris[t];
    const Vec3d n = glm::cross(pos(x[1]) - pos(x[0]), pos(x[2]) - pos(x[0]));
    return !(std::abs(glm::dot(d, n)) > allowance * glm::length(n));
  }
};

// The fans of the corners of the triangles turned over at the start, and
// of the vertices merges give their triangles to (those corners too): a
// vertex -> triangles table over those vertices alone.
class Fans {
 public:
  Fans(std::span<const std::array<uint32_t, 3>> tris, std::vector<uint32_t> vertices) : vertices_(std::move(vertices)) {
    offset_.assign(vertices_.size() + 1, 0);
    for (const auto& x : tris)
      for (uint32_t v : x)
        if (const size_t i = index(v); i != kAbsent) ++offset_[i + 1];
    for (size_t i = 1; i < offset_.size(); ++i) offset_[i] += offset_[i - 1];
    fan_.resize(offset_.back());
    std::vector<uint32_t> fill(offset_.begin(), offset_.end() - 1);
    for (size_t t = 0; t < tris.size(); ++t)
      for (uint32_t v : tris[t])
        if (const size_t i = index(v); i != kAbsent) fan_[fill[i]++] = uint32_t(t);
  }
  bool has(uint32_t v) const { return index(v) != kAbsent; }
  // The live triangles that use v now (v must be one of the table's).
  void gather(uint32_t v, const UnfoldMesh& m, std::span<const uint8_t> dead, std::vector<uint32_t>& out) const {
    out.clear();
    const size_t i = index(v);
    for (uint32_t k = offset_[i]; k < offset_[i + 1]; ++k)
      if (const uint32_t t = fan_[k]; !dead[t] && UnfoldMesh::uses(m.tris[t], v)) out.push_back(t);
    if (const auto it = taken_.find(v); it != taken_.end())
      for (uint32_t t : it->second)
        if (!dead[t] && UnfoldMesh::uses(m.tris[t], v)) out.push_back(t);
  }
  void take(uint32_t v, uint32_t t) { taken_[v].push_back(t); }
  uint64_t memory_bytes() const {
    return vertices_.capacity() * 4 + offset_.capacity() * 4 + fan_.capacity() * 4;
  }

 private:
  static constexpr size_t kAbsent = ~size_t(0);
  size_t index(uint32_t v) const {
    const auto it = std::lower_bound(vertices_.begin(), vertices_.end(), v);
    return it != vertices_.end() && *it == v ? size_t(it - vertices_.begin()) : kAbsent;
  }
  std::vector<uint32_t> vertices_;  // sorted
  std::vector<uint32_t> offset_, fan_;
  std::unordered_map<uint32_t, std::vector<uint32_t>> taken_;
};

// Whether v's fan closes around it: each neighbour follows v in as many
// triangles as it precedes it. An open fan (v on an outline) is left alone:
// moving v there would move the outline, which no plane test sees.
bool closed_fan(const UnfoldMesh& m, uint32_t v, std::span<const uint32_t> fan,
                std::vector<std::pair<uint32_t, int>>& scratch) {
  scratch.clear();
  for (uint32_t t : fan) {
    const auto [a, b] = m.opposite(t, v);
    scratch.push_back({a, 1});
    scratch.push_back({b, -1});
  }
  std::sort(scratch.begin(), scratch.end());
  for (size_t i = 0; i < scratch.size();) {
    int sum = 0;
    size_t j = i;
    for (; j < scratch.size() && scratch[j].first == scratch[i].first; ++j) sum += scratch[j].second;
    if (sum != 0) return false;
    i = j;
  }
  return !fan.empty();
}

// Slides v within its limits to a point where every triangle of its fan is
// upright; true if it moved.
bool slide(const UnfoldMesh& m, uint32_t v, std::span<const uint32_t> fan, const UnfoldLimit& lim,
           std::vector<HalfSpace>& halves) {
  const Vec3d p0 = m.pos(v);
  halves.clear();
  for (uint32_t t : fan) {
    if (!m.keyed(t)) continue;  // only its area counts: checked below
    const auto [a, b] = m.opposite(t, v);
    if (a == v || b == v) return false;
    const Vec3d xa = m.pos(a) - p0, xb = m.pos(b) - p0, n(m.keys[t]);
    halves.push_back({glm::cross(xa - xb, n), glm::dot(glm::cross(xa, xb), n), m.needed(t, v, kUnfoldMinHeight)});
  }
  // Alternating projections onto the half-spaces, the plane and the cell,
  // all convex: a point of their intersection if they meet (near p0, not
  // always the nearest). The projections aim at the full height and accept
  // half of it (they approach the intersection from outside).
  const Vec3d lo = lim.cell.lo - p0, hi = lim.cell.hi - p0;
  const bool planar = glm::length(lim.plane_normal) > 0;
  Vec3d p(0);
  bool feasible = false;
  for (int sweep = 0; sweep < kProjectionSweeps && !feasible; ++sweep) {
    for (const HalfSpace& h : halves) {
      const double g = h.c + glm::dot(h.m, p), mm = glm::dot(h.m, h.m);
      if (g < h.need && mm > 0) p += (h.need - g) / mm * h.m;
    }
    if (planar) p -= glm::dot(p, lim.plane_normal) * lim.plane_normal;
    p = glm::clamp(p, lo, hi);
    feasible = std::all_of(halves.begin(), halves.end(),
                           [&](const HalfSpace& h) { return h.c + glm::dot(h.m, p) >= 0.5 * h.need; });
  }
  // The clamp may leave the plane: by no more than the allowance.
  if (!feasible || (planar && std::abs(glm::dot(p, lim.plane_normal)) > lim.allowance)) return false;
  Vec3 q;
  for (int a = 0; a < 3; ++a) q[a] = float_inside(p0[a] + p[a], lim.cell.lo[a], lim.cell.hi[a]);
  const Vec3d d = Vec3d(q) - p0;
  for (uint32_t t : fan) {
    const double area = m.twice_area_with(t, v, Vec3d(q));
    if (!m.within(t, d, lim.allowance) || !(area >= 0.25 * m.needed(t, v, kUnfoldMinHeight)) || !(area > 0))
      return false;
  }
  m.rep_pos[v] = q;
  return true;
}

// Merges a into b (a's triangles that use b die, the rest take b) if the
// edge's link is that of a manifold edge collapse (a and b share no
// neighbour but the far corners of the triangles that die, and no triangle
// left would repeat or face one of b's), and every triangle left is upright
// and within a's allowance of its plane.
bool merge(const UnfoldMesh& m, uint32_t a, uint32_t b, const UnfoldLimit& lim, Fans& fans,
           std::span<uint8_t> dead, std::vector<uint32_t>& fan_a, std::vector<uint32_t>& fan_b,
           std::vector<std::pair<uint32_t, int>>& scratch, std::unordered_map<uint64_t, uint32_t>& renamed,
           UnfoldStats& stats) {
  if (!fans.has(b)) return false;
  fans.gather(a, m, dead, fan_a);
  if (!closed_fan(m, a, fan_a, scratch)) return false;
  fans.gather(b, m, dead, fan_b);
  // The link condition: a neighbour of both is the far corner of a
  // triangle on the edge.
  std::vector<uint32_t> near_a, near_b, far;
  for (uint32_t t : fan_a) {
    const auto [x, y] = m.opposite(t, a);
    if (x == b || y == b) far.push_back(x == b ? y : x);
    near_a.push_back(x);
    near_a.push_back(y);
  }
  for (uint32_t t : fan_b) {
    const auto [x, y] = m.opposite(t, b);
    near_b.push_back(x);
    near_b.push_back(y);
  }
  for (auto* s : {&near_a, &near_b, &far}) {
    std::sort(s->begin(), s->end());
    s->erase(std::unique(s->begin(), s->end()), s->end());
  }
  for (uint32_t x : near_a)
    if (x != b && std::binary_search(near_b.begin(), near_b.end(), x) && !std::binary_search(far.begin(), far.end(), x))
      return false;
  const Vec3d pb = m.pos(b), d = pb - m.pos(a);
  for (uint32_t t : fan_a) {
    if (UnfoldMesh::uses(m.tris[t], b)) continue;
    const auto [x, y] = m.opposite(t, a);
    for (uint32_t u : fan_b)  // (b, x, y) again, or its reverse
      if (UnfoldMesh::uses(m.tris[u], x) && UnfoldMesh::uses(m.tris[u], y)) return false;
    const double area = m.twice_area_with(t, a, pb);
    if (!m.within(t, d, lim.allowance) || !(area >= m.needed(t, a, kUnfoldMinHeight)) || !(area > 0)) return false;
  }
  for (uint32_t t : fan_a) {
    auto& x = m.tris[t];
    if (UnfoldMesh::uses(x, b)) {
      dead[t] = 1;
      ++stats.dropped;
      continue;
    }
    const int k = UnfoldMesh::corner_of(x, a);
    renamed.emplace(3 * uint64_t(t) + uint64_t(k), a);  // the first name stays
    x[size_t(k)] = b;
    fans.take(b, t);
  }
  ++stats.merged;
  return true;
}

}  // namespace

// The float nearest v that lies in [lo, hi] if one within an ulp does: the
// output mesh is float, and rounding must not push a vertex out of its cell.
float float_inside(double v, double lo, double hi) {
  float f = float(v);
  if (double(f) < lo) {
    const float g = std::nextafter(f, std::numeric_limits<float>::infinity());
    if (double(g) <= hi) f = g;
  } else if (double(f) > hi) {
    const float g = std::nextafter(f, -std::numeric_limits<float>::infinity());
    if (double(g) >= lo) f = g;
  }
  return f;
}

UnfoldStats unfold_representatives(std::span<std::array<uint32_t, 3>> tris, std::span<const Vec3> keys,
                                   std::span<Vec3> rep_pos, std::span<const Vec3> kept_pos,
                                   const std::function<bool(uint32_t)>& movable,
                                   const std::function<UnfoldLimit(uint32_t)>& limit, UnfoldResult& out) {
  UnfoldStats stats;
  out = {};
  const UnfoldMesh m{tris, keys, rep_pos, kept_pos, movable};
  std::vector<uint32_t> folded, corners;
  for (size_t t = 0; t < tris.size(); ++t) {
    if (!m.folded(t)) continue;
    ++stats.folded_before;
    folded.push_back(uint32_t(t));
    for (uint32_t v : tris[t]) corners.push_back(v);
  }
  stats.folded_after = stats.folded_before;
  if (folded.empty()) return stats;
  std::sort(corners.begin(), corners.end());
  corners.erase(std::unique(corners.begin(), corners.end()), corners.end());

  std::vector<uint8_t> dead(tris.size(), 0);
  Fans fans(tris, corners);
  stats.peak_bytes = fans.memory_bytes() + dead.size();
  std::unordered_map<uint64_t, uint32_t> renamed;
  std::vector<uint32_t> fan, fan_b, slid;
  std::vector<HalfSpace> halves;
  std::vector<std::pair<uint32_t, int>> scratch;
  const auto any_folded = [&] {
    return std::any_of(fan.begin(), fan.end(), [&](uint32_t t) { return m.folded(t); });
  };
  for (int round = 0; round < kUnfoldRounds; ++round) {
    bool changed = false;
    // Slides first: each movable corner of a turned-over triangle, in id
    // order.
    for (uint32_t v : corners) {
      if (!m.movable(v)) continue;
      fans.gather(v, m, dead, fan);
      if (!any_folded() || !closed_fan(m, v, fan, scratch)) continue;
      if (slide(m, v, fan, limit(v), halves)) {
        slid.push_back(v);
        changed = true;
      }
    }
    // Then merges along the edges of what is still turned over, shortest
    // edge first.
    for (uint32_t t : folded) {
      if (dead[t] || !m.folded(t)) continue;
      std::array<std::pair<double, int>, 3> edges;
      for (int k = 0; k < 3; ++k) {
        const Vec3d e = m.pos(tris[t][size_t(k)]) - m.pos(tris[t][size_t((k + 1) % 3)]);
        edges[size_t(k)] = {glm::dot(e, e), k};
      }
      std::sort(edges.begin(), edges.end());
      for (const auto& [length2, k] : edges) {
        const uint32_t u = tris[t][size_t(k)], w = tris[t][size_t((k + 1) % 3)];
        if ((m.movable(u) && merge(m, u, w, limit(u), fans, dead, fan, fan_b, scratch, renamed, stats)) ||
            (m.movable(w) && merge(m, w, u, limit(w), fans, dead, fan, fan_b, scratch, renamed, stats))) {
          changed = true;
          break;
        }
      }
    }
    std::erase_if(folded, [&](uint32_t t) { return dead[t] || !m.folded(t); });
    if (!changed || folded.empty()) break;
  }
  std::sort(slid.begin(), slid.end());
  slid.erase(std::unique(slid.begin(), slid.end()), slid.end());
  stats.moved = slid.size();
  stats.folded_after = 0;  // by the same rule as before: every live keyed triangle
  for (size_t t = 0; t < tris.size(); ++t) stats.folded_after += !dead[t] && m.folded(t);
  for (size_t t = 0; t < tris.size(); ++t)
    if (dead[t]) out.dead.push_back(uint32_t(t));
  out.renamed.assign(renamed.begin(), renamed.end());
  std::sort(out.renamed.begin(), out.renamed.end());
  out.slid = std::move(slid);
  return stats;
}

}  // namespace raylod
