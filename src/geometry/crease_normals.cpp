// Crease-angle normals (see crease_normals.h for the rule and its reasons).
#include "geometry/crease_normals.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>

namespace raylod {
namespace {

const double kCosMerge = std::cos(kClusterMergeAngleRad);
const double kCosOverflow = std::cos(10.0 * M_PI / 180.0);

Vec3d unit_or_zero(const Vec3d& v) {
  const double len = glm::length(v);
  return len > 0 && std::isfinite(len) ? v / len : Vec3d(0);
}

}  // namespace

double crease_cosine(double crease_angle_deg) {
  const double deg = std::clamp(crease_angle_deg, 0.0, 180.0);
  return std::cos(deg * M_PI / 180.0);
}

namespace {
// Whether float rounding of the corners can turn the triangle's face normal
// by more than about a hundredth of a radian: a rounding of eps times the
// corners' size against the triangle's height over its longest edge. Such a
// triangle (a zero-area cap filling a T-junction, whose corner angle is pi)
// weighs nothing in its vertices' normals: its face normal is noise.
bool face_normal_is_noise(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3d p[3] = {Vec3d(a), Vec3d(b), Vec3d(c)};
  const double longest =
      std::max({glm::length(p[1] - p[0]), glm::length(p[2] - p[1]), glm::length(p[0] - p[2])});
  const double height = longest > 0 ? glm::length(glm::cross(p[1] - p[0], p[2] - p[0])) / longest : 0.0;
  const double size = std::max({max_abs(p[0]), max_abs(p[1]), max_abs(p[2]), longest});
  return !(height > 100.0 * double(std::numeric_limits<float>::epsilon()) * size);
}

// The interior angle at corner k (0 for a degenerate triangle), whatever
// the triangle's conditioning.
double interior_angle(const Vec3& a, const Vec3& b, const Vec3& c, int k) {
  const Vec3d p[3] = {Vec3d(a), Vec3d(b), Vec3d(c)};
  const Vec3d e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
  const double s = glm::length(glm::cross(e1, e2)), d = glm::dot(e1, e2);
  if (!(s > 0)) return 0;
  return std::atan2(s, d);  // robust for slivers, unlike acos of a ratio
}

}  // namespace

double corner_angle(const Vec3& a, const Vec3& b, const Vec3& c, int k) {
  return face_normal_is_noise(a, b, c) ? 0.0 : interior_angle(a, b, c, k);
}

std::array<double, 3> corner_angles(const Vec3& a, const Vec3& b, const Vec3& c) {
  if (face_normal_is_noise(a, b, c)) return {0.0, 0.0, 0.0};
  return {interior_angle(a, b, c, 0), interior_angle(a, b, c, 1), interior_angle(a, b, c, 2)};
}

void NormalClusterPool::add_to_nearest(uint32_t v, const Vec3d& n, double w) {
  if (!(w > 0)) return;
  uint32_t best = kNoCluster;
  double best_cos = kCosOverflow;
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) {
    if (pool_[c].seed == Vec3(0)) continue;
    const double cs = glm::dot(Vec3d(pool_[c].seed), n);
    if (cs >= best_cos) { best_cos = cs; best = c; }
  }
  if (best != kNoCluster) {
    pool_[best].sum += Vec3(w * n);
    return;
  }
  // Into the leftover sum (seed zero), as add() does when a vertex is full.
  uint32_t last = kNoCluster;
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) {
    if (pool_[c].seed == Vec3(0)) {
      pool_[c].sum += Vec3(w * n);
      return;
    }
    last = c;
  }
  const uint32_t id = uint32_t(pool_.size());
  pool_.push_back(NormalCluster{Vec3(w * n), Vec3(0), kNoCluster});
  if (last == kNoCluster) heads_[v] = id;
  else pool_[last].next = id;
}

void NormalClusterPool::add(uint32_t v, const Vec3d& n, double w, uint32_t max_clusters) {
  if (!(w > 0)) return;
  // Neighbouring corners mostly share a direction: the cluster the vertex
  // matched last is tried first (a vertex of a coarse cell on a curved
  // surface has dozens of clusters, and scanning them all was half of
  // simplify's time on the 10M teapot).
  if (const uint32_t hit = recent_[v]; hit != kNoCluster && glm::dot(Vec3d(pool_[hit].seed), n) >= kCosMerge) {
    pool_[hit].sum += Vec3(w * n);
    return;
  }
  uint32_t best = kNoCluster, count = 0, last = kNoCluster, leftover = kNoCluster;
  double best_cos = -2;
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) {
    last = c;
    if (pool_[c].seed == Vec3(0)) { leftover = c; continue; }
    const double cs = glm::dot(Vec3d(pool_[c].seed), n);
    if (cs >= kCosMerge) {
      pool_[c].sum += Vec3(w * n);
      recent_[v] = c;
      return;
    }
    if (cs > best_cos) { best_cos = cs; best = c; }
    ++count;
  }
  if (count >= max_clusters && best != kNoCluster) {
    // Full: into the nearest seed if it is close enough to stand for this
    // direction. A direction no seed is near goes to the vertex's leftover
    // sum, which only the smooth-everything rule (crease angle 180) and the
    // fallback mean use: summed into an unrelated cluster it could tilt a
    // flat face by the leftovers of a whole bore.
    if (best_cos >= kCosOverflow) { pool_[best].sum += Vec3(w * n); return; }
    if (leftover != kNoCluster) { pool_[leftover].sum += Vec3(w * n); return; }
    const uint32_t id = uint32_t(pool_.size());
    pool_.push_back(NormalCluster{Vec3(w * n), Vec3(0), kNoCluster});
    pool_[last].next = id;
    return;
  }
  const uint32_t id = uint32_t(pool_.size());
  pool_.push_back(NormalCluster{Vec3(w * n), Vec3(n), kNoCluster});
  recent_[v] = id;
  // Appended at the tail, so that clusters keep their order of creation.
  if (last == kNoCluster) heads_[v] = id;
  else pool_[last].next = id;
}

Vec3d NormalClusterPool::resolve(uint32_t v, const Vec3d& key, double cos_crease) const {
  Vec3d sum(0);
  const bool everything = cos_crease <= -1.0 + 1e-12;
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) {
    const Vec3d s(pool_[c].sum);
    if (pool_[c].seed == Vec3(0) ? everything : glm::dot(unit_or_zero(s), key) >= cos_crease) sum += s;
  }
  return unit_or_zero(sum);
}

Vec3d NormalClusterPool::flat_side(uint32_t v, const Vec3d& key, double cos_near, double share,
                                    uint32_t min_others) const {
  uint32_t own = kNoCluster;
  for (uint32_t c = heads_[v]; c != kNoCluster && own == kNoCluster; c = pool_[c].next)
    if (pool_[c].seed != Vec3(0) && glm::dot(Vec3d(pool_[c].seed), key) >= kCosMerge) own = c;
  if (own == kNoCluster) return Vec3d(0);
  const Vec3d dir = unit_or_zero(Vec3d(pool_[own].sum));
  const double w = glm::length(Vec3d(pool_[own].sum));
  double near = 0;
  Vec3d sum(0);
  uint32_t others = 0;
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) {
    if (pool_[c].seed == Vec3(0)) continue;
    const Vec3d s(pool_[c].sum);
    if (glm::dot(unit_or_zero(s), dir) < cos_near) continue;
    near += glm::length(s);
    sum += s;
    others += c != own;
  }
  return w >= share * near && others >= min_others ? unit_or_zero(sum) : Vec3d(0);
}

Vec3d NormalClusterPool::nearest_seed(uint32_t v, const Vec3d& key) const {
  Vec3d best(0);
  double best_dot = -2;
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) {
    if (pool_[c].seed == Vec3(0)) continue;
    const double d = glm::dot(Vec3d(pool_[c].seed), key);
    if (d > best_dot) {
      best_dot = d;
      best = Vec3d(pool_[c].seed);
    }
  }
  return best;
}

Vec3d NormalClusterPool::mean(uint32_t v) const {
  Vec3d sum(0);
  for (uint32_t c = heads_[v]; c != kNoCluster; c = pool_[c].next) sum += Vec3d(pool_[c].sum);
  return unit_or_zero(sum);
}

std::vector<Vec3> crease_corner_normals(std::span<const Vec3> positions, std::span<const uint32_t> indices,
                                        double crease_angle_deg) {
  const size_t nv = positions.size(), nt = indices.size() / 3;
  const double cos_crease = crease_cosine(crease_angle_deg);
  // Face normals (and whether each is rounding noise, which gives its
  // corners no weight: corner_angle), then vertex -> incident corners (CSR,
  // in triangle order).
  std::vector<Vec3> face(nt);
  std::vector<uint8_t> noise(nt);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 1 << 14), [&](const auto& r) {
    for (size_t t = r.begin(); t != r.end(); ++t) {
      const uint32_t* f = &indices[3 * t];
      face[t] = Vec3(face_normal(Vec3d(positions[f[0]]), Vec3d(positions[f[1]]), Vec3d(positions[f[2]])));
      noise[t] = face_normal_is_noise(positions[f[0]], positions[f[1]], positions[f[2]]);
    }
  });
  std::vector<uint32_t> start(nv + 1, 0);
  for (uint32_t v : indices) ++start[v + 1];
  for (size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<uint32_t> corners(indices.size());
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t i = 0; i < indices.size(); ++i) corners[fill[indices[i]]++] = uint32_t(i);
  }
  std::vector<Vec3> out(indices.size());
  // Each vertex is independent: its clusters live in a thread-local pool of
  // one vertex, so the result does not depend on the thread count.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, nv, 1 << 12), [&](const auto& r) {
    NormalClusterPool local(1);
    for (size_t v = r.begin(); v != r.end(); ++v) {
      local.clear();
      for (uint32_t j = start[v]; j < start[v + 1]; ++j) {
        const uint32_t corner = corners[j], t = corner / 3;
        const uint32_t* f = &indices[3 * size_t(t)];
        const double w = noise[t] ? 0.0 : interior_angle(positions[f[0]], positions[f[1]], positions[f[2]], int(corner % 3));
        local.add(0, Vec3d(face[t]), w, kNoCluster);
      }
      const Vec3d fallback = local.mean(0);
      for (uint32_t j = start[v]; j < start[v + 1]; ++j) {
        const uint32_t corner = corners[j];
        const Vec3d key(face[corner / 3]);
        Vec3d n = glm::length(key) > 0 ? local.resolve(0, key, cos_crease) : Vec3d(0);
        if (glm::length(n) == 0) n = glm::length(key) > 0 ? key : fallback;
        if (glm::length(n) == 0) n = Vec3d(0, 1, 0);
        out[corner] = Vec3(n);
      }
    }
  });
  return out;
}

}  // namespace raylod
