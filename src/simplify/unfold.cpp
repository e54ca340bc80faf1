#include "simplify/unfold.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace raylod {

namespace {

constexpr uint32_t kNone = 0xffffffffu;
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
// normals, and where each id is.
struct UnfoldMesh {
  std::span<std::array<uint32_t, 3>> tris;
  std::span<const Vec3> keys;
  std::span<Vec3> rep_pos;
  std::span<const Vec3> kept_pos;
  const std::function<bool(uint32_t)>& movable_rep;

  uint32_t reps() const { return uint32_t(rep_pos.size()); }
  Vec3d pos(uint32_t v) const { return v < reps() ? Vec3d(rep_pos[v]) : Vec3d(kept_pos[v - reps()]); }
  bool movable(uint32_t v) const { return v < reps() && movable_rep(v); }
  bool has_movable(size_t t) const { return movable(tris[t][0]) || movable(tris[t][1]) || movable(tris[t][2]); }
  bool folded(size_t t) const {
    const auto& x = tris[t];
    return faces_against(pos(x[0]), pos(x[1]), pos(x[2]), Vec3d(keys[t]));
  }
  static int corner_of(const std::array<uint32_t, 3>& x, uint32_t v) { return x[0] == v ? 0 : (x[1] == v ? 1 : 2); }
  static bool uses(const std::array<uint32_t, 3>& x, uint32_t v) { return x[0] == v || x[1] == v || x[2] == v; }
  // Whether moving corner v of triangle t to p leaves it facing its input,
  // at least `height` of its opposite edge high.
  bool upright_with(size_t t, uint32_t v, const Vec3d& p, double height) const {
    const auto& x = tris[t];
    const int k = corner_of(x, v);
    const Vec3d a = pos(x[size_t((k + 1) % 3)]), b = pos(x[size_t((k + 2) % 3)]);
    const double twice_area = glm::dot(glm::cross(a - p, b - p), Vec3d(keys[t]));
    return twice_area >= height * glm::dot(a - b, a - b) && twice_area > 0;
  }
  // Whether moving v by d keeps the surface within `allowance` of the plane
  // of triangle t as it is.
  bool within(size_t t, const Vec3d& d, double allowance) const {
    const auto& x = tris[t];
    const Vec3d n = glm::cross(pos(x[1]) - pos(x[0]), pos(x[2]) - pos(x[0]));
    return !(std::abs(glm::dot(d, n)) > allowance * glm::length(n));
  }
};

// Vertex -> triangles, as a compressed table built once, plus the
// triangles each vertex took over from merges.
class Fans {
 public:
  Fans(std::span<const std::array<uint32_t, 3>> tris, size_t vertices) : offset_(vertices + 1, 0) {
    for (const auto& x : tris)
      for (uint32_t v : x) ++offset_[v + 1];
    for (size_t i = 1; i < offset_.size(); ++i) offset_[i] += offset_[i - 1];
    fan_.resize(offset_.back());
    std::vector<uint32_t> fill(offset_.begin(), offset_.end() - 1);
    for (size_t t = 0; t < tris.size(); ++t)
      for (uint32_t v : tris[t]) fan_[fill[v]++] = uint32_t(t);
  }
  // The live triangles that use v now.
  void gather(uint32_t v, const UnfoldMesh& m, std::span<const uint8_t> dead, std::vector<uint32_t>& out) const {
    out.clear();
    for (uint32_t k = offset_[v]; k < offset_[v + 1]; ++k)
      if (const uint32_t t = fan_[k]; !dead[t] && UnfoldMesh::uses(m.tris[t], v)) out.push_back(t);
    if (const auto it = taken_.find(v); it != taken_.end())
      for (uint32_t t : it->second)
        if (!dead[t] && UnfoldMesh::uses(m.tris[t], v)) out.push_back(t);
  }
  void take(uint32_t v, uint32_t t) { taken_[v].push_back(t); }

 private:
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
    const auto& x = m.tris[t];
    const int k = UnfoldMesh::corner_of(x, v);
    scratch.push_back({x[size_t((k + 1) % 3)], 1});
    scratch.push_back({x[size_t((k + 2) % 3)], -1});
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
    const auto& x = m.tris[t];
    const int k = UnfoldMesh::corner_of(x, v);
    const uint32_t a = x[size_t((k + 1) % 3)], b = x[size_t((k + 2) % 3)];
    if (a == v || b == v) return false;
    const Vec3d xa = m.pos(a) - p0, xb = m.pos(b) - p0, n(m.keys[t]);
    halves.push_back({glm::cross(xa - xb, n), glm::dot(glm::cross(xa, xb), n), kUnfoldMinHeight * glm::dot(xa - xb, xa - xb)});
  }
  // Alternating projections onto the half-spaces, the plane and the cell,
  // all convex: a point of their intersection if they meet (near p0, not
  // always the nearest). The projections aim at the full height and accept
  // half of it (they approach the intersection from outside).
  const Vec3d lo = lim.cell.lo - p0, hi = lim.cell.hi - p0;
  Vec3d p(0);
  bool feasible = false;
  for (int sweep = 0; sweep < kProjectionSweeps && !feasible; ++sweep) {
    for (const HalfSpace& h : halves) {
      const double g = h.c + glm::dot(h.m, p), mm = glm::dot(h.m, h.m);
      if (g < h.need && mm > 0) p += (h.need - g) / mm * h.m;
    }
    if (glm::length(lim.plane_normal) > 0) p -= glm::dot(p, lim.plane_normal) * lim.plane_normal;
    p = glm::clamp(p, lo, hi);
    feasible = std::all_of(halves.begin(), halves.end(),
                           [&](const HalfSpace& h) { return h.c + glm::dot(h.m, p) >= 0.5 * h.need; });
  }
  if (!feasible) return false;
  Vec3 q;
  for (int a = 0; a < 3; ++a) q[a] = float_inside(p0[a] + p[a], lim.cell.lo[a], lim.cell.hi[a]);
  const Vec3d d = Vec3d(q) - p0;
  for (uint32_t t : fan)
    if (!m.within(t, d, lim.allowance) || !m.upright_with(t, v, Vec3d(q), 0.25 * kUnfoldMinHeight)) return false;
  m.rep_pos[v] = q;
  return true;
}

// Merges a into b (a's triangles that use b die, the rest take b) if that
// leaves each of them upright and within a's allowance of its plane.
bool merge(const UnfoldMesh& m, uint32_t a, uint32_t b, const UnfoldLimit& lim, Fans& fans,
           std::span<uint8_t> dead, std::vector<uint32_t>& fan, std::vector<std::pair<uint32_t, int>>& scratch,
           std::unordered_map<uint64_t, uint32_t>& renamed, UnfoldStats& stats) {
  fans.gather(a, m, dead, fan);
  if (!closed_fan(m, a, fan, scratch)) return false;
  const Vec3d pb = m.pos(b), d = pb - m.pos(a);
  for (uint32_t t : fan) {
    if (UnfoldMesh::uses(m.tris[t], b)) continue;
    if (!m.within(t, d, lim.allowance) || !m.upright_with(t, a, pb, kUnfoldMinHeight)) return false;
  }
  for (uint32_t t : fan) {
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

bool faces_against(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3d& key) {
  return !(glm::dot(glm::cross(b - a, c - a), key) > 0);
}

UnfoldStats unfold_representatives(std::span<std::array<uint32_t, 3>> tris, std::span<const Vec3> keys,
                                   std::span<Vec3> rep_pos, std::span<const Vec3> kept_pos,
                                   const std::function<bool(uint32_t)>& movable,
                                   const std::function<UnfoldLimit(uint32_t)>& limit, std::vector<uint8_t>& dead,
                                   std::vector<std::pair<uint64_t, uint32_t>>& renamed_out) {
  UnfoldStats stats;
  dead.clear();
  renamed_out.clear();
  std::unordered_map<uint64_t, uint32_t> renamed;
  const UnfoldMesh m{tris, keys, rep_pos, kept_pos, movable};
  std::vector<uint32_t> folded;
  for (size_t t = 0; t < tris.size(); ++t)
    if (m.has_movable(t) && m.folded(t)) folded.push_back(uint32_t(t));
  stats.folded_before = folded.size();
  if (folded.empty()) return stats;

  dead.assign(tris.size(), 0);
  Fans fans(tris, rep_pos.size() + kept_pos.size());
  std::vector<uint32_t> fan;
  std::vector<HalfSpace> halves;
  std::vector<std::pair<uint32_t, int>> scratch;
  const auto any_folded = [&] {
    return std::any_of(fan.begin(), fan.end(), [&](uint32_t t) { return m.folded(t); });
  };
  for (int round = 0; round < kUnfoldRounds; ++round) {
    bool changed = false;
    // Slides first: each representative of a turned-over triangle, in id
    // order, where no move of one vertex alone helps none is made.
    std::vector<uint32_t> corners;
    for (uint32_t t : folded)
      if (!dead[t])
        for (uint32_t v : tris[t])
          if (m.movable(v)) corners.push_back(v);
    std::sort(corners.begin(), corners.end());
    corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
    for (uint32_t v : corners) {
      fans.gather(v, m, dead, fan);
      if (!any_folded() || !closed_fan(m, v, fan, scratch)) continue;
      if (slide(m, v, fan, limit(v), halves)) {
        ++stats.moved;
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
        if ((m.movable(u) && merge(m, u, w, limit(u), fans, dead, fan, scratch, renamed, stats)) ||
            (m.movable(w) && merge(m, w, u, limit(w), fans, dead, fan, scratch, renamed, stats))) {
          changed = true;
          break;
        }
      }
    }
    std::erase_if(folded, [&](uint32_t t) { return dead[t] || !m.folded(t); });
    if (!changed || folded.empty()) break;
  }
  for (size_t t = 0; t < tris.size(); ++t) stats.folded_after += !dead[t] && m.has_movable(t) && m.folded(t);
  renamed_out.assign(renamed.begin(), renamed.end());
  std::sort(renamed_out.begin(), renamed_out.end());
  return stats;
}

}  // namespace raylod
