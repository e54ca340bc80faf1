// Crease-angle normals: the one shading-normal rule that the full-resolution
// render and the collapse share, so that collapsing nothing reproduces the
// full render.
//
// The rule. A corner of triangle t at vertex v gets the normalised weighted
// sum of the normals of the triangles around v whose normal is within the
// crease angle of t's own normal: smooth across the flat or gently curved
// facets of one CAD face, split where two faces meet at a crease. The weight
// is the triangle's angle at v (angle weighting: independent of how a face
// happens to be cut into slivers). Normals that come with the input are kept
// as they are; the rule applies only where the input gives none.
//
// Why clusters: a vertex can have thousands of incident triangles (the centre
// of a tessellated disc) and a collapsed cell many more. Incident normals are
// grouped into clusters of nearly equal direction (within kClusterMergeAngle,
// far below any useful crease angle), and the crease test runs against the
// clusters' mean directions. The result differs from the exact pairwise rule
// only for a normal within that merge angle of the crease threshold.
//
// The representative of a collapsed cell (simplify/collapse.h) uses the same
// clusters over all corners merged into it (area weighted), keyed by the
// normal of the output triangle's input triangle: a cell that spans a crease
// gets one normal per side, and a flat side gets exactly that side's normal.
// A cell that holds one vertex is that vertex kept, and takes this rule.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/math.h"

namespace raylod {

// Default crease angle: facets meeting at more than this are shaded as a
// crease. 25 degrees keeps 30-, 45- and 90-degree CAD edges (nut chamfers,
// chamfers, steps, bores) sharp while smoothing tessellations of curved
// faces, whose neighbouring facets differ by a few degrees (OpenCASCADE's
// mesher with an angular deflection a: at most about 2a, 20 degrees for the
// script's coarse crank arm at a = 10). Not 30: a threshold at a common design
// angle splits that edge's facets both ways, as tessellation moves their
// dihedrals a degree either side (OpenCASCADE's Pump_Nut.brep: its 30-degree
// chamfer measures 29 to 30 degrees, rendered as radial streaks).
inline constexpr double kDefaultCreaseAngleDeg = 25.0;

// Two normals within this angle fall into one cluster.
inline constexpr double kClusterMergeAngleRad = 0.5 * 3.14159265358979323846 / 180.0;

// One cluster: the weighted sum of its members' unit normals and the first
// member's normal (its seed: membership is decided against the seed, so a
// cluster cannot drift, and a full list of clusters cannot smear opposite
// normals into one sum), linked to the next cluster of the same vertex
// (kNoCluster ends the list).
inline constexpr uint32_t kNoCluster = 0xffffffffu;
struct NormalCluster {
  Vec3 sum{0};
  Vec3 seed{0};
  uint32_t next = kNoCluster;
};

// Per-vertex lists of normal clusters in one pool (vertex ids are dense).
class NormalClusterPool {
 public:
  NormalClusterPool() = default;
  explicit NormalClusterPool(size_t vertices) {
    heads_.assign(vertices, kNoCluster);
    recent_.assign(vertices, kNoCluster);
  }
  void add_vertex() {
    heads_.push_back(kNoCluster);
    recent_.push_back(kNoCluster);
  }
  // Empties every vertex's list and the pool, keeping the allocations.
  void clear() {
    std::fill(heads_.begin(), heads_.end(), kNoCluster);
    std::fill(recent_.begin(), recent_.end(), kNoCluster);
    pool_.clear();
  }
  size_t vertices() const { return heads_.size(); }
  // Adds unit normal n with weight w > 0 to vertex v: into a cluster whose
  // seed is within the merge angle (the one v matched last if it is, else
  // the first in order of creation), else a new one; once the vertex
  // has max_clusters, into the one with the nearest seed if that is within
  // 10 degrees, else into the vertex's leftover sum (seed zero), which only
  // a crease angle of 180 degrees and mean() include.
  void add(uint32_t v, const Vec3d& n, double w, uint32_t max_clusters);
  // Adds w * n to the cluster of v whose seed is nearest n if it is within
  // the overflow angle of add() (10 degrees), else to v's leftover sum: a sum
  // of many normals whose direction no cluster stands for (the mean across a
  // crease) must not become a direction of its own.
  void add_to_nearest(uint32_t v, const Vec3d& n, double w);
  // The rule for a corner whose own (face) normal is `key`: the normalised sum
  // of v's clusters within the crease angle (cos_crease) of key; zero if
  // there is none (then the caller falls back).
  Vec3d resolve(uint32_t v, const Vec3d& key, double cos_crease) const;
  // The normalised sum of all of v's clusters (zero if they cancel).
  Vec3d mean(uint32_t v) const;
  // The seed (its first member's normal, as given) of v's cluster whose seed
  // is nearest `key`; zero if v has none. For a vertex whose corners bring
  // their own normals, the normal of the corner nearest key.
  Vec3d nearest_seed(uint32_t v, const Vec3d& key) const;
  // A flat side at v: the direction of v's cluster within the merge angle of
  // `key` if it holds at least `share` of the weight of the clusters within
  // the angle whose cosine is cos_near of it, and at least `min_others`
  // other clusters lie there (a flat face beside which only slivers lie: the
  // many thin first rows of a small fillet); zero otherwise (a curved
  // tessellation's rows hold comparable weights, a face across a fold holds
  // no such rows, and a cell of a few triangles of a scan may have one large
  // one beside a few small ones).
  Vec3d flat_side(uint32_t v, const Vec3d& key, double cos_near, double share, uint32_t min_others) const;
  uint64_t memory_bytes() const {
    return (heads_.capacity() + recent_.capacity()) * 4 + pool_.capacity() * sizeof(NormalCluster);
  }
  void reserve(size_t vertices, size_t clusters) {
    heads_.reserve(vertices);
    recent_.reserve(vertices);
    pool_.reserve(clusters);
  }

 private:
  std::vector<uint32_t> heads_;
  std::vector<uint32_t> recent_;  // per vertex: the cluster it matched last
  std::vector<NormalCluster> pool_;
};

// cos of a crease angle given in degrees, clamped to [0, 180].
double crease_cosine(double crease_angle_deg);

// The corner's weight in its vertex's normal: the triangle's interior angle
// at corner k, or 0 for a degenerate triangle and for one whose face normal
// float rounding of its corners can turn by more than about 0.01 rad (its
// height under 100 float epsilons of its corners' size: a zero-area cap
// filling a T-junction has a corner angle of pi and a face normal that is
// noise, which tilted a flat face's shading normal by up to 12 degrees).
double corner_angle(const Vec3& a, const Vec3& b, const Vec3& c, int k);
// The three corners' weights of one triangle (corner_angle for k = 0, 1, 2),
// the triangle's conditioning judged once.
std::array<double, 3> corner_angles(const Vec3& a, const Vec3& b, const Vec3& c);

// Per-corner normals of an indexed mesh by the rule above (3 per triangle).
// Vertices must be welded (equal positions share an index) for smoothing to
// reach across triangles. A degenerate triangle's corners get the mean of
// their vertex's clusters (+Y if there is nothing to average).
std::vector<Vec3> crease_corner_normals(std::span<const Vec3> positions, std::span<const uint32_t> indices,
                                        double crease_angle_deg);

}  // namespace raylod
