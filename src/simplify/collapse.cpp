// Collapse of the cut cells to their representative vertices (method step A5;
// Luebke and Erikson 1997 vertex clustering with Lindstrom 2000 QEM
// representatives, eqs. 3-4).
//
// Why reverse-wound twins are kept: when a cell collapses across a thin wall,
// both sides' triangles land on the same output vertices with opposite
// orientations. Dropping one of them would leave its edges with one incident
// face where the input had two, i.e. open a hole in a closed surface; keeping
// both keeps every edge paired, and a ray tracer sees the same surface from
// either side. Same-orientation duplicates are exact copies and are dropped.
#include "simplify/collapse.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <numeric>
#include <optional>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>


#include "core/ordered_pipeline.h"
#include "core/parallelism.h"
#include "core/progress.h"
#include "core/system.h"
#include "simplify/unfold.h"

namespace raylod {
namespace {

// Float bits with -0 folded into +0, for exact vertex identity.
uint32_t float_bits(float f) {
  f += 0.0f;
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

uint64_t mix64(uint64_t h) {
  h ^= h >> 33; h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33; h *= 0xc4ceb9fe1a85ec53ull;
  return h ^ (h >> 33);
}

uint64_t hash_vertex(const Vec3& p, const Vec3& n, bool with_normal) {
  uint64_t h = mix64((uint64_t(float_bits(p.x)) << 32) ^ float_bits(p.y));
  h = mix64(h ^ (uint64_t(float_bits(p.z)) << 17));
  if (with_normal) {
    h = mix64(h ^ ((uint64_t(float_bits(n.x)) << 32) | float_bits(n.y)));
    h = mix64(h ^ float_bits(n.z));
  }
  return h;
}

bool same_bits(const Vec3& a, const Vec3& b) {
  return float_bits(a.x) == float_bits(b.x) && float_bits(a.y) == float_bits(b.y) && float_bits(a.z) == float_bits(b.z);
}

Vec3 canonical(const Vec3& v) { return Vec3(v.x + 0.0f, v.y + 0.0f, v.z + 0.0f); }

// Zero area, exactly: the corners are collinear (or coincide). For float
// corners the double cross product is exact enough to decide this: the
// differences are exact, each product of two is exact, and a difference of
// exact products rounds to zero only if they are equal. Thin slivers are
// kept: dropping one would open a crack in a closed surface.
bool zero_area(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3d cross = glm::cross(Vec3d(b) - Vec3d(a), Vec3d(c) - Vec3d(a));
  return cross.x == 0 && cross.y == 0 && cross.z == 0;
}

// The input triangle's unit normal (zero if it has no area or its area is
// not finite) and twice its area: the crease key and the weight of its
// corners, and what a collapsed triangle is compared with for a fold.
struct InputFace {
  Vec3d unit{0};
  double area2 = 0;
};

InputFace input_face(const Vec3* p) {
  const Vec3d cross = glm::cross(Vec3d(p[1]) - Vec3d(p[0]), Vec3d(p[2]) - Vec3d(p[0]));
  InputFace f;
  f.area2 = glm::length(cross);
  if (f.area2 > 0 && std::isfinite(f.area2)) f.unit = cross / f.area2;
  return f;
}

// A kept triangle with a representative corner (`collapsed`) is turned over
// when it faces against its input triangle.
bool turned_over(const Vec3& a, const Vec3& b, const Vec3& c, const InputFace& f, bool collapsed) {
  // Finite corners and a unit normal (the input has area): faces_against's
  // test, which unfolding applies to the collapsed mesh.
  if (!collapsed || !(f.area2 > 0)) return false;
  return faces_against(Vec3d(a), Vec3d(b), Vec3d(c), f.unit);
}

std::array<uint32_t, 3> rotate_min_first(const std::array<uint32_t, 3>& t) {
  if (t[1] < t[0] && t[1] < t[2]) return {t[1], t[2], t[0]};
  if (t[2] < t[0] && t[2] < t[1]) return {t[2], t[0], t[1]};
  return t;
}

}  // namespace

Representative make_representative(const NodeRecord& node, const Bbox& cell_bounds_world, const Vec3d& origin,
                                   const QemSolveConfig& config) {
  Representative r;
  const Bbox cell{cell_bounds_world.lo - origin, cell_bounds_world.hi - origin};
  const Vec3d mean = node.corner_count ? node.vertex_sum / double(node.corner_count) : cell.center();
  const QemSolution s = solve_representative_vertex(node.quadric, mean, cell, config);
  const Vec3d world = origin + s.position;
  for (int a = 0; a < 3; ++a) r.position[a] = float_inside(world[a], cell_bounds_world.lo[a], cell_bounds_world.hi[a]);
  r.rank = s.rank;
  r.clamped = s.clamped;
  r.fallback_normal = dominant_normal(node.quadric);
  r.normal_sum = 6.0 * node.normal_sum;  // area / 3 per corner -> twice the area
  r.has_normal_sum = true;
  r.side = cell_bounds_world.hi.x - cell_bounds_world.lo.x;
  r.cell_lo = cell_bounds_world.lo;
  r.corner_count = node.corner_count;
  // The cut's deviation at the representative (collapse_deviation.h): the
  // chord error of the RMS distance from the cell's planes.
  const double w = quadric_weight(node.quadric);
  if (w > 0) r.deviation = std::sqrt(12.0 * std::max(0.0, quadric_error(node.quadric, s.position)) / w);
  return r;
}

// ---------------------------------------------------------------- CutLookup

CutLookup::CutLookup(const Vec3d& root_lo, double root_size, std::span<const CellKey> cells)
    : root_lo_(root_lo), root_size_(root_size), by_level_(22) {
  for (size_t i = 0; i < cells.size(); ++i) {
    const CellKey& k = cells[i];
    assert(k.level <= 21);
    by_level_[k.level].emplace(k.code, uint32_t(i));
    deepest_ = std::max(deepest_, int(k.level));
  }
  for (int l = deepest_; l >= 0; --l) if (!by_level_[l].empty()) levels_.push_back(l);
}

uint64_t CutLookup::code_of(const Vec3d& p) const {
  // Cell coordinates at the deepest cut level, binned exactly as the store
  // build bins corners (floor((p - lo) * (2^L / size))); an ancestor at level
  // L is the code shifted right by 3 (deepest - L): the factors differ by a
  // power of two, so this equals binning at L directly.
  const double inv_cell = double(uint64_t(1) << deepest_) / root_size_;
  const uint32_t max_coord = uint32_t((uint64_t(1) << deepest_) - 1);
  uint32_t c[3];
  for (int a = 0; a < 3; ++a) {
    const double t = std::floor((p[a] - root_lo_[a]) * inv_cell);
    c[a] = t <= 0 ? 0u : (t >= double(max_coord) ? max_coord : uint32_t(t));
  }
  return morton_encode(c[0], c[1], c[2]);
}

uint32_t CutLookup::find_code(uint64_t code) const {
  for (int level : levels_) {
    const auto& m = by_level_[level];
    auto it = m.find(code >> (3 * (deepest_ - level)));
    if (it != m.end()) return it->second;
  }
  return kKeepVertex;
}

// ---------------------------------------------------------- CollapseBuilder

// Clusters a representative keeps: enough for the sides of a cell that
// spans creases (a box corner has 3) and the spread of a curved patch (a
// cell around a whole small bore sees normals all around); more merge into
// the one with the nearest seed, at most about 15 degrees away when 64
// seeds cover the directions.
constexpr uint32_t kRepresentativeClusters = 64;
// CollapseBuilder::rep_corners_seen_: a second position came.
constexpr uint32_t kSeveralPositions = 0xffffffffu;

// A flat side (NormalClusterPool::flat_side): its own cluster holds at least
// this share of the weight within 10 degrees of it, beside at least this
// many other clusters there (the first rows of a fillet).
const double kFlatSideCos = std::cos(10.0 * M_PI / 180.0);
constexpr double kFlatSideShare = 0.8;
constexpr uint32_t kFlatSideSlivers = 4;
// How far a crease-rule sample may turn a representative's normal from its
// cluster (exact normals without input normals, collapse.h): 1 degree.
constexpr double kCreaseSampleMaxTurn = M_PI / 180.0;

CollapseBuilder::CollapseBuilder(std::span<const Representative> reps, bool input_has_normals,
                                 double crease_angle_deg)
    : reps_(reps), has_normals_(input_has_normals), cos_crease_(crease_cosine(crease_angle_deg)),
      clusters_(reps.size()), folding_(reps.size(), 0), reached_sum_(reps.size(), Vec3d(0)) {
  rep_pos_.reserve(reps.size());
  for (const auto& r : reps) rep_pos_.push_back(Vec3(r.position));
  table_.assign(1024, kKeepVertex);
  rep_corners_seen_.assign(reps.size(), 0);
  rep_first_position_.assign(reps.size(), Vec3(0));
  if (!has_normals_) one_vertex_clusters_ = NormalClusterPool(reps.size());
}

void CollapseBuilder::reserve(uint64_t vertices, uint64_t triangles) {
  size_t slots = table_.size();
  while (slots < 2 * vertices) slots *= 2;
  if (slots > table_.size()) {
    table_.assign(slots, kKeepVertex);
    const size_t mask = slots - 1;
    for (uint32_t id = 0; id < kept_pos_.size(); ++id) {
      size_t i = hash_vertex(kept_pos_[id], has_normals_ ? kept_normal_[id] : Vec3(0), has_normals_) & mask;
      while (table_[i] != kKeepVertex) i = (i + 1) & mask;
      table_[i] = id;
    }
    table_count_ = kept_pos_.size();
  }
  kept_pos_.reserve(vertices);
  if (has_normals_) kept_normal_.reserve(vertices);
  clusters_.reserve(reps_.size() + vertices, has_normals_ ? reps_.size() * 2 : 2 * (reps_.size() + vertices));
  tris_.reserve(triangles);
  keys_.reserve(triangles);
}

void CollapseBuilder::grow_table() {
  std::vector<uint32_t> t(table_.size() * 2, kKeepVertex);
  const size_t mask = t.size() - 1;
  for (uint32_t id : table_) {
    if (id == kKeepVertex) continue;
    size_t i = hash_vertex(kept_pos_[id], has_normals_ ? kept_normal_[id] : Vec3(0), has_normals_) & mask;
    while (t[i] != kKeepVertex) i = (i + 1) & mask;
    t[i] = id;
  }
  table_.swap(t);
}

uint32_t CollapseBuilder::kept_vertex(const Vec3& p_in, const Vec3& n_in, uint64_t hash) {
  const Vec3 p = canonical(p_in), n = has_normals_ ? canonical(n_in) : Vec3(0);
  const size_t mask = table_.size() - 1;
  size_t i = hash & mask;
  while (table_[i] != kKeepVertex) {
    const uint32_t id = table_[i];
    if (same_bits(kept_pos_[id], p) && (!has_normals_ || same_bits(kept_normal_[id], n))) return id;
    i = (i + 1) & mask;
  }
  const uint32_t id = new_kept_vertex(p, n);
  table_[i] = id;
  if (2 * ++table_count_ > table_.size()) grow_table();  // load factor <= 1/2
  return id;
}

uint32_t CollapseBuilder::new_kept_vertex(const Vec3& p, const Vec3& n) {
  const uint32_t id = uint32_t(kept_pos_.size());
  assert(uint64_t(id) + reps_.size() < kKeepVertex);
  kept_pos_.push_back(canonical(p));
  if (has_normals_) kept_normal_.push_back(canonical(n));
  clusters_.add_vertex();
  return id;
}

void mark_page_unique_vertices(const PageMesh& page, std::span<const uint32_t> vertex_cell,
                               std::span<const Bbox> other_pages, const Bbox& inner, PreparedBatch& out) {
  out.unique.assign(page.vertices(), 0);
  for (size_t v = 0; v < page.vertices(); ++v) {
    if (vertex_cell[v] != kKeepVertex) continue;
    const Vec3d p(page.positions[v]);
    bool unique = p.x > inner.lo.x && p.x < inner.hi.x && p.y > inner.lo.y && p.y < inner.hi.y && p.z > inner.lo.z &&
                  p.z < inner.hi.z;
    if (!unique) {
      unique = true;
      for (const Bbox& b : other_pages)
        if (b.contains(p)) { unique = false; break; }
    }
    out.unique[v] = unique;
  }
}

namespace {

// Whether two kept corners (page vertices a and b, not in a collapsed cell)
// are one output vertex: bit-identical positions, and normals where the
// page has them (decoded from their codes when `normals` is not given).
bool same_kept_vertex(const PageMesh& page, const Vec3& pa, const Vec3& pb, uint32_t a, uint32_t b,
                      const Vec3* normals) {
  if (a == b) return true;
  if (!same_bits(pa, pb)) return false;
  if (page.normal_codes.empty()) return true;
  const Vec3 na = normals ? normals[a] : decode_octahedral(page.normal_codes[a]);
  const Vec3 nb = normals ? normals[b] : decode_octahedral(page.normal_codes[b]);
  return same_bits(canonical(na), canonical(nb));
}

// The point of triangle (a, b, c) nearest q, as barycentric weights
// (Ericson, Real-Time Collision Detection, 5.1.5: the Voronoi regions of the
// corners, then of the edges, then the face).
Vec3d nearest_on_triangle(const Vec3d& q, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d ab = b - a, ac = c - a, ap = q - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return {1, 0, 0};
  const Vec3d bp = q - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return {0, 1, 0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {1 - v, v, 0};
  }
  const Vec3d cp = q - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return {0, 0, 1};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {1 - w, 0, w};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0, 1 - w, w};
  }
  const double denom = va + vb + vc;
  if (!(denom > 0)) return {1, 0, 0};  // no area: a corner stands in
  const double v = vb / denom, w = vc / denom;
  return {1 - v - w, v, w};
}

// For each representative among the triangle's corners' cells: the
// triangle's point nearest it, if nearer than the page's best so far
// (PreparedBatch::rep_samples).
// n3: the normals at the triangle's three corners.
void sample_nearest_points(const Vec3* p, const Vec3* n3, const uint32_t* c, std::span<const Vec3> rep_pos,
                           PreparedBatch& out) {
  for (int k = 0; k < 3; ++k) {
    const uint32_t r = c[k];
    if (r == kKeepVertex || (k > 0 && r == c[0]) || (k > 1 && r == c[1])) continue;
    const Vec3d q(rep_pos[r]), a(p[0]), b(p[1]), cc(p[2]);
    const Vec3d w = nearest_on_triangle(q, a, b, cc);
    const Vec3d at = w.x * a + w.y * b + w.z * cc;
    const float d2 = float(glm::dot(at - q, at - q));
    uint32_t& slot = out.slot_of(r);
    if (slot != kKeepVertex && !(d2 < out.rep_samples[slot].d2)) continue;
    const Vec3d n = w.x * Vec3d(n3[0]) + w.y * Vec3d(n3[1]) + w.z * Vec3d(n3[2]);
    const double len = glm::length(n);
    if (!(len > 0) || !std::isfinite(len)) continue;
    if (slot == kKeepVertex) {
      slot = uint32_t(out.rep_samples.size());
      out.rep_samples.push_back({r, d2, Vec3(n / len)});
    } else {
      out.rep_samples[slot] = {r, d2, Vec3(n / len)};
    }
  }
}

// Per page vertex, 1 if one of its edges has one triangle on the page: the
// page's border cuts its fan (or the mesh's own rim does), so the crease
// rule over the page's triangles alone misses some of the triangles the
// full render averages there (a cylinder's long strips continue on the
// next page: their corner normals there would be a facet's own).
std::vector<uint8_t> open_fan_vertices(const PageMesh& page) {
  std::vector<uint64_t> edges;
  edges.reserve(page.index.size());
  for (size_t t = 0; t < page.size(); ++t) {
    const uint32_t* f = &page.index[3 * t];
    // A triangle with a repeated corner has no edges of its own: counting
    // (a, b) and (b, a) of (a, a, b) would close a border edge.
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2]) continue;
    for (int k = 0; k < 3; ++k) {
      const uint64_t a = f[k], b = f[(k + 1) % 3];
      edges.push_back(std::min(a, b) << 32 | std::max(a, b));
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<uint8_t> open(page.vertices(), 0);
  for (size_t i = 0; i < edges.size();) {
    size_t j = i + 1;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) open[edges[i] >> 32] = open[edges[i] & 0xffffffffu] = 1;
    i = j;
  }
  return open;
}

}  // namespace

void prepare_collapse(const PageMesh& page, std::span<const uint32_t> vertex_cell, std::span<const Vec3> rep_pos,
                      bool input_has_normals, PreparedBatch& out, bool exact_normals, double crease_angle_deg) {
  assert(vertex_cell.size() == page.vertices());
  const bool page_normals = input_has_normals && page.normals.size() == page.vertices();
  const size_t nt = page.size(), nv = page.vertices();
  out.face.resize(nt);
  out.area2.resize(nt);
  out.fate.resize(nt);
  out.hash.resize(nv);
  out.angle.resize(input_has_normals ? 0 : 3 * nt);
  out.vertex_normal.assign(nv, kKeepVertex);
  out.rep_normals.clear();
  out.rep_corners.clear();
  out.unique.clear();
  out.rep_samples.clear();
  // Samples are taken for representatives alone: only on pages with a
  // collapsed vertex.
  const bool sample = exact_normals && (page_normals || !input_has_normals) &&
                      std::any_of(vertex_cell.begin(), vertex_cell.end(), [](uint32_t c) { return c != kKeepVertex; });
  // Without input normals, what the full render shades: the crease rule's
  // corner normals, over the page's triangles, at vertices whose fan the
  // page holds whole (open_fan_vertices).
  std::vector<Vec3> corner_normals;
  std::vector<uint8_t> open_fan;
  if (sample && !input_has_normals) {
    corner_normals = crease_corner_normals(page.positions, page.index, crease_angle_deg);
    open_fan = open_fan_vertices(page);
  }
  if (sample) {
    size_t size = 16;
    while (size < 2 * nv) size *= 2;
    out.rep_slot.assign(size, {kKeepVertex, kKeepVertex});
  }
  for (size_t v = 0; v < nv; ++v) {
    if (vertex_cell[v] != kKeepVertex) continue;
    const Vec3 n = input_has_normals && page_normals ? canonical(page.normals[v]) : Vec3(0);
    out.hash[v] = hash_vertex(canonical(page.positions[v]), n, input_has_normals);
  }
  const Vec3* normals = page_normals ? page.normals.data() : nullptr;
  for (size_t t = 0; t < nt; ++t) {
    const uint32_t* vi = &page.index[3 * t];
    const Vec3 p[3] = {page.positions[vi[0]], page.positions[vi[1]], page.positions[vi[2]]};
    const uint32_t c[3] = {vertex_cell[vi[0]], vertex_cell[vi[1]], vertex_cell[vi[2]]};
    if (sample) {
      if (normals) {
        const Vec3 n3[3] = {normals[vi[0]], normals[vi[1]], normals[vi[2]]};
        sample_nearest_points(p, n3, c, rep_pos, out);
      } else if (!open_fan[vi[0]] && !open_fan[vi[1]] && !open_fan[vi[2]] && !zero_area(p[0], p[1], p[2])) {
        // (A triangle without area has no normal of its own: the crease
        // rule gives its corners a mean across creases.)
        sample_nearest_points(p, &corner_normals[3 * t], c, rep_pos, out);
      }
    }
    if (c[0] != kKeepVertex && c[0] == c[1] && c[1] == c[2]) {
      // Wholly inside one collapsed cell: it disappears unexamined (most
      // triangles of a coarse cut end here); its normal reaches the cell
      // through the node's sum (CollapseBuilder::finish).
      out.face[t] = Vec3d(0);
      out.area2[t] = 0;
      out.fate[t] = TriangleFate::kInsideCell;
      continue;
    }
    const InputFace input = input_face(p);
    out.face[t] = input.unit;
    out.area2[t] = input.area2;
    // The crease rule's corner weights, without input normals.
    const std::array<double, 3> angle = input_has_normals ? std::array<double, 3>{} : corner_angles(p[0], p[1], p[2]);
    Vec3 pos[3];
    bool collapsed = false;
    for (int k = 0; k < 3; ++k) {
      if (c[k] != kKeepVertex) {
        pos[k] = rep_pos[c[k]];
        collapsed = true;
        out.rep_corners.push_back(
            {c[k], canonical(p[k]),
             !input_has_normals && input.area2 > 0 ? float(angle[size_t(k)]) : 0.0f, Vec3(input.unit)});
        if (!(input.area2 > 0)) continue;  // no weight
        if (normals) {
          uint32_t& entry = out.vertex_normal[vi[k]];
          if (entry != kKeepVertex) {
            out.rep_normals[entry].weight += input.area2;
          } else {
            entry = uint32_t(out.rep_normals.size());
            // A zero (or non-finite) input normal would put NaN into the
            // cluster: the face normal stands in for it.
            const Vec3d n(normals[vi[k]]);
            const double len = glm::length(n);
            out.rep_normals.push_back({c[k], input.area2, len > 0 && std::isfinite(len) ? n / len : input.unit});
          }
        } else if (k == 0 || (c[k] != c[0] && (k == 1 || c[k] != c[1]))) {
          // The corners of one cell share the face normal: one entry, weighted by their count.
          const int same = (c[0] == c[k]) + (c[1] == c[k]) + (c[2] == c[k]);
          out.rep_normals.push_back({c[k], same * input.area2, input.unit});
        }
        continue;
      }
      pos[k] = canonical(p[k]);
      if (!input_has_normals) out.angle[3 * t + k] = angle[size_t(k)];
    }
    // Two corners are one output vertex when they are in one cell, or both
    // kept with bit-identical positions (and normals, with input normals).
    bool repeated = false;
    for (int k = 0; k < 3 && !repeated; ++k) {
      const int l = (k + 1) % 3;
      if (c[k] != c[l]) continue;
      repeated = c[k] != kKeepVertex || same_kept_vertex(page, pos[k], pos[l], vi[k], vi[l], normals);
    }
    if (repeated) out.fate[t] = TriangleFate::kCollapsed;
    else if (zero_area(pos[0], pos[1], pos[2])) out.fate[t] = TriangleFate::kZeroArea;
    else if (turned_over(pos[0], pos[1], pos[2], input, collapsed)) out.fate[t] = TriangleFate::kKeptFolded;
    else out.fate[t] = TriangleFate::kKept;
  }
}

uint32_t& PreparedBatch::slot_of(uint32_t rep) {
  // A page's representatives are among its vertices' cells: at most half the
  // table's size, so a free slot is always found.
  const size_t mask = rep_slot.size() - 1;
  for (size_t i = (rep * 0x9E3779B1u) & mask;; i = (i + 1) & mask) {
    if (rep_slot[i].first == rep) return rep_slot[i].second;
    if (rep_slot[i].first == kKeepVertex) {
      rep_slot[i].first = rep;
      return rep_slot[i].second;  // kKeepVertex: no entry yet
    }
  }
}

bool collapse_turns_over(const PageMesh& page, std::span<const uint32_t> vertex_cell, std::span<const Vec3> rep_pos,
                         size_t t) {
  const uint32_t* vi = &page.index[3 * t];
  const uint32_t c[3] = {vertex_cell[vi[0]], vertex_cell[vi[1]], vertex_cell[vi[2]]};
  // Most triangles: no corner collapsed, or all three in one cell.
  if (c[0] == c[1] && c[1] == c[2]) return false;
  if (c[0] == kKeepVertex && c[1] == kKeepVertex && c[2] == kKeepVertex) return false;
  const Vec3 p[3] = {page.positions[vi[0]], page.positions[vi[1]], page.positions[vi[2]]};
  Vec3 pos[3];
  for (int k = 0; k < 3; ++k) pos[k] = c[k] != kKeepVertex ? rep_pos[c[k]] : canonical(p[k]);
  for (int k = 0; k < 3; ++k) {
    const int l = (k + 1) % 3;
    if (c[k] == c[l] && (c[k] != kKeepVertex || same_kept_vertex(page, pos[k], pos[l], vi[k], vi[l], nullptr)))
      return false;  // collapsed
  }
  if (zero_area(pos[0], pos[1], pos[2])) return false;
  return turned_over(pos[0], pos[1], pos[2], input_face(p), true);
}

void CollapseBuilder::add(const TriangleBatch& batch, std::span<const uint32_t> cell) {
  assert(cell.size() == batch.positions.size());
  // A soup is a page whose every corner is a vertex of its own.
  page_.clear();
  page_.positions = batch.positions;
  if (has_normals_ && batch.normals.size() == batch.positions.size()) page_.normals = batch.normals;
  page_.index.resize(batch.positions.size());
  std::iota(page_.index.begin(), page_.index.end(), 0u);
  prepare_collapse(page_, cell, rep_pos_, has_normals_, prepared_);
  add(page_, cell, prepared_);
}

void CollapseBuilder::add_inside_cell(uint64_t triangles) {
  stats_.input_triangles += triangles;
  stats_.dropped_collapsed += triangles;
  stats_.inside_cell += triangles;
}

void CollapseBuilder::add(const PageMesh& page, std::span<const uint32_t> vertex_cell, const PreparedBatch& prepared) {
  assert(vertex_cell.size() == page.vertices());
  const bool page_normals = has_normals_ && page.normals.size() == page.vertices();
  const uint32_t nreps = uint32_t(reps_.size());
  for (const auto& r : prepared.rep_normals) {
    clusters_.add(r.rep, r.normal, r.weight, kRepresentativeClusters);
    reached_sum_[r.rep] += r.weight * r.normal;
  }
  for (const auto& r : prepared.rep_corners) {  // cells of one vertex (collapse.h)
    uint32_t& seen = rep_corners_seen_[r.rep];
    if (seen == kSeveralPositions) continue;
    if (seen > 0 && !same_bits(rep_first_position_[r.rep], r.position)) {
      seen = kSeveralPositions;
      continue;
    }
    if (seen++ == 0) rep_first_position_[r.rep] = r.position;
    if (r.angle > 0) one_vertex_clusters_.add(r.rep, Vec3d(r.face), r.angle, kNoCluster);
  }
  if (!prepared.rep_samples.empty() && sample_d2_.empty()) {
    sample_d2_.assign(nreps, std::numeric_limits<float>::infinity());
    sample_normal_.assign(nreps, Vec3(0));
  }
  for (const auto& s : prepared.rep_samples) {  // pages come in order: the first nearest stays
    if (!(s.d2 < sample_d2_[s.rep])) continue;
    sample_d2_[s.rep] = s.d2;
    sample_normal_[s.rep] = s.normal;
  }
  page_kept_.assign(page.vertices(), kKeepVertex);
  const Vec3 n_none(0);
  for (size_t t = 0; t < page.size(); ++t) {
    ++stats_.input_triangles;
    if (prepared.fate[t] == TriangleFate::kInsideCell) {
      ++stats_.dropped_collapsed;
      ++stats_.inside_cell;
      continue;
    }
    const uint32_t* vi = &page.index[3 * t];
    // Normals and weights come from the input triangle, before collapse.
    const double area2 = prepared.area2[t];
    const Vec3d& face = prepared.face[t];
    std::array<uint32_t, 3> id;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = vi[k];
      if (const uint32_t c = vertex_cell[v]; c != kKeepVertex) {
        assert(c < nreps);
        id[k] = c;
      } else {
        uint32_t& kv = page_kept_[v];
        if (kv == kKeepVertex) {
          const Vec3& n = page_normals ? page.normals[v] : n_none;
          kv = !prepared.unique.empty() && prepared.unique[v] ? new_kept_vertex(page.positions[v], n)
                                                              : kept_vertex(page.positions[v], n, prepared.hash[v]);
        }
        id[k] = nreps + kv;
        if (!has_normals_ && area2 > 0) clusters_.add(nreps + kv, face, prepared.angle[3 * t + k], kNoCluster);
      }
    }
    stats_.input_degenerate += !(area2 > 0);
    switch (prepared.fate[t]) {
      case TriangleFate::kInsideCell: continue;  // handled above
      case TriangleFate::kCollapsed: ++stats_.dropped_collapsed; continue;
      case TriangleFate::kZeroArea: ++stats_.dropped_zero_area; continue;
      case TriangleFate::kKeptFolded:
        ++stats_.folded;
        for (uint32_t v : id)
          if (v < nreps) folding_[v] = 1;
        break;
      case TriangleFate::kKept: break;
    }
    tris_.push_back(id);
    keys_.push_back(Vec3(face));
  }
  stats_.peak_bytes = std::max(stats_.peak_bytes, memory_bytes());
}

uint64_t CollapseBuilder::memory_bytes() const {
  return rep_pos_.capacity() * sizeof(Vec3) + kept_pos_.capacity() * sizeof(Vec3) +
         kept_normal_.capacity() * sizeof(Vec3) + clusters_.memory_bytes() + table_.capacity() * sizeof(uint32_t) +
         tris_.capacity() * sizeof(tris_[0]) + keys_.capacity() * sizeof(Vec3) +
         reached_sum_.capacity() * sizeof(Vec3d) + sample_d2_.capacity() * sizeof(float) +
         sample_normal_.capacity() * sizeof(Vec3) + rep_corners_seen_.capacity() * sizeof(uint32_t) +
         rep_first_position_.capacity() * sizeof(Vec3) + one_vertex_clusters_.memory_bytes();
}

IndexedMesh CollapseBuilder::finish(CollapseStats* stats_out) {
  const uint32_t nreps = uint32_t(reps_.size());
  // The triangles wholly inside a cell gave it no normals (prepare_collapse):
  // their sum is the cell's whole sum (from the store's node) less what the
  // others gave, and it joins the cluster nearest its direction. On a smooth
  // cell that restores the mean over the whole cell; across a crease the sum
  // points between the sides, no cluster is near it, and it is left out.
  for (uint32_t v = 0; v < nreps; ++v) {
    if (!reps_[v].has_normal_sum) continue;
    const Vec3d inside = reps_[v].normal_sum - reached_sum_[v];
    const double w = glm::length(inside);
    if (w > 1e-9 * (glm::length(reps_[v].normal_sum) + glm::length(reached_sum_[v])))
      clusters_.add_to_nearest(v, inside / w, w);
  }
  // Cells that hold one vertex (every corner of the cell at one position):
  // that vertex, kept (collapse.h).
  std::vector<uint8_t> one_vertex(rep_corners_seen_.size(), 0);
  for (uint32_t v = 0; v < one_vertex.size(); ++v) {
    const uint32_t seen = rep_corners_seen_[v];
    if (seen == kSeveralPositions || seen == 0 || seen != reps_[v].corner_count) continue;
    one_vertex[v] = 1;
    rep_pos_[v] = rep_first_position_[v];
    ++stats_.one_vertex_cells;
  }
  // Turned-over triangles: their corners slide, or their edges collapse,
  // within their cells' deviation (unfold.h).
  UnfoldResult unfolded;
  if (unfold_) {
    const UnfoldStats u = unfold_representatives(
        tris_, keys_, rep_pos_, kept_pos_,
        [&](uint32_t v) { return !(v < one_vertex.size() && one_vertex[v]) && reps_[v].side > 0; },
        [&](uint32_t v) {
          const Representative& r = reps_[v];
          const double allowance = std::max(kUnfoldDeviationFactor * r.deviation, kUnfoldFlatAllowance * r.side);
          // A cell without a quadric (rank 0) has no plane to keep to.
          return UnfoldLimit{Bbox{r.cell_lo, r.cell_lo + Vec3d(r.side)}, r.rank > 0 ? r.fallback_normal : Vec3d(0),
                             allowance};
        },
        unfolded);
    stats_.folded_before_unfold = u.folded_before;
    stats_.folded_after_unfold = u.folded_after;
    stats_.unfold_moved = u.moved;
    stats_.unfold_merged = u.merged;
    stats_.unfold_dropped = u.dropped;
    stats_.peak_bytes = std::max(stats_.peak_bytes, memory_bytes() + u.peak_bytes);
  }
  const std::vector<uint32_t>& unfold_dead = unfolded.dead;
  const std::vector<std::pair<uint64_t, uint32_t>>& renamed = unfolded.renamed;
  // Same-orientation duplicates: sort the triangles by their rotation that
  // starts at the smallest id, then by their index, so the first occurrence
  // comes first (a total order: any parallel sort gives the same result).
  struct Keyed {
    std::array<uint32_t, 3> key;
    uint32_t triangle;
    // Element by element: std::array's == and != call memcmp, which
    // profiled at 8% of a 100M simplify through this sort.
    bool operator<(const Keyed& o) const {
      if (key[0] != o.key[0]) return key[0] < o.key[0];
      if (key[1] != o.key[1]) return key[1] < o.key[1];
      if (key[2] != o.key[2]) return key[2] < o.key[2];
      return triangle < o.triangle;
    }
    bool same_key(const Keyed& o) const { return key[0] == o.key[0] && key[1] == o.key[1] && key[2] == o.key[2]; }
  };
  std::vector<Keyed> sorted(tris_.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, tris_.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) sorted[i] = {rotate_min_first(tris_[i]), uint32_t(i)};
  });
  tbb::parallel_sort(sorted.begin(), sorted.end());
  std::vector<bool> keep(tris_.size(), true);
  size_t unique = 0;  // the distinct keys, compacted to the front of `sorted`
  for (size_t j = 0; j < sorted.size(); ++j) {
    if (!unfold_dead.empty() && std::binary_search(unfold_dead.begin(), unfold_dead.end(), sorted[j].triangle)) {
      keep[sorted[j].triangle] = false;
      continue;
    }
    if (unique > 0 && sorted[j].same_key(sorted[unique - 1])) {
      keep[sorted[j].triangle] = false;
      ++stats_.dropped_duplicate;
    } else {
      sorted[unique++] = sorted[j];
    }
  }
  // Reverse-wound twins: the reverse of (a, b, c) with a smallest is (a, c,
  // b), also a-first, so it lies among the keys that start with a.
  for (size_t g = 0; g < unique;) {
    size_t end = g + 1;
    while (end < unique && sorted[end].key[0] == sorted[g].key[0]) ++end;
    const auto less = [](const Keyed& x, const std::array<uint32_t, 3>& k) { return x.key < k; };
    for (size_t j = g; j < end; ++j) {
      const std::array<uint32_t, 3> reverse{sorted[j].key[0], sorted[j].key[2], sorted[j].key[1]};
      const auto it = std::lower_bound(sorted.begin() + ptrdiff_t(g), sorted.begin() + ptrdiff_t(end), reverse, less);
      stats_.reverse_twins += it != sorted.begin() + ptrdiff_t(end) && it->key == reverse;
    }
    g = end;
  }
  std::vector<Keyed>().swap(sorted);

  // Representatives whose nearest input point was found near enough to stand
  // for the input there (collapse.h).
  std::vector<uint8_t> exact(sample_d2_.empty() ? 0 : nreps, 0);
  for (size_t v = 0; v < exact.size(); ++v) {
    const double reach = reps_[v].side / 16;
    exact[v] = std::isfinite(sample_d2_[v]) && double(sample_d2_[v]) <= reach * reach;
  }
  // A representative unfolding slid left the point its sample was taken for.
  for (uint32_t v : unfolded.slid)
    if (v < exact.size()) exact[v] = 0;
  std::vector<uint8_t> took(exact.size(), 0);  // representatives a corner took the sample of

  // Resolve every corner's normal, then split each provisional vertex by the
  // distinct normals its corners got; output vertices in order of first use.
  IndexedMesh mesh;
  const size_t provisional = size_t(nreps) + kept_pos_.size();
  std::vector<uint32_t> first_out(provisional, kKeepVertex);  // provisional -> its first output vertex
  std::vector<uint32_t> next_out;                             // output vertex -> next split of the same vertex
  size_t kept_count = 0;
  for (size_t i = 0; i < tris_.size(); ++i) if (keep[i]) ++kept_count;
  mesh.indices.reserve(3 * kept_count);
  // A corner's normal: a function of its provisional vertex and its input
  // face's normal alone, so the corners are resolved in parallel, a chunk
  // of triangles at a time, and split into output vertices in order.
  std::atomic<uint64_t> fallbacks{0};
  // A sample stands in for a corner's cluster within the crease angle of
  // it; one from the crease rule (no input normals) only within
  // kCreaseSampleMaxTurn (collapse.h).
  const double sample_cos = has_normals_ ? cos_crease_ : std::max(cos_crease_, std::cos(kCreaseSampleMaxTurn));
  const auto resolve_corner = [&](uint32_t v, const Vec3d& key) -> Vec3 {
    if (v >= nreps && has_normals_) return kept_normal_[v - nreps];  // input normals are kept exactly
    if (v < one_vertex.size() && one_vertex[v]) {  // as the vertex kept (collapse.h)
      // Input normals: the corner's own, the one nearest its face's normal.
      Vec3d nd = has_normals_ ? clusters_.nearest_seed(v, key) : one_vertex_clusters_.resolve(v, key, cos_crease_);
      if (glm::length(nd) == 0) nd = has_normals_ ? clusters_.mean(v) : one_vertex_clusters_.mean(v);
      if (glm::length(nd) == 0) {
        fallbacks.fetch_add(1, std::memory_order_relaxed);
        nd = glm::length(key) > 0 ? key : Vec3d(0, 1, 0);
      }
      return Vec3(nd);
    }
    Vec3d nd(0);
    // Without input normals, a representative on a flat face that only
    // slivers border (a pin's flat end beside the strips of its small
    // fillet) keeps the face's own normal: the crease angle's band
    // would tilt it towards the fillet by as much as the cell holds
    // of it, differently from cell to cell (radial streaks).
    // (Not for crease angles of 90 degrees or more, which ask to smooth
    // across real edges: a box's faces at a corner are no slivers.)
    if (v < nreps && !has_normals_ && cos_crease_ > 0 && glm::length(key) > 0)
      nd = clusters_.flat_side(v, key, kFlatSideCos, kFlatSideShare, kFlatSideSlivers);
    if (glm::length(nd) == 0 && glm::length(key) > 0) nd = clusters_.resolve(v, key, cos_crease_);
    if (glm::length(nd) == 0) nd = clusters_.mean(v);
    if (glm::length(nd) == 0) {
      fallbacks.fetch_add(1, std::memory_order_relaxed);
      const Vec3d fallback = v < nreps ? reps_[v].fallback_normal : key;
      nd = glm::length(fallback) > 0 ? glm::normalize(fallback) : Vec3d(0, 1, 0);
    }
    // The input's normal at the representative (exact normals, collapse.h).
    if (v < exact.size() && exact[v] && glm::dot(Vec3d(sample_normal_[v]), nd) >= sample_cos) {
      nd = sample_normal_[v];
      std::atomic_ref<uint8_t>(took[v]).store(1, std::memory_order_relaxed);
    }
    return Vec3(nd);
  };
  // A corner an unfolding merge moved takes its new vertex's normal (the
  // surface is smooth there), unless that lies beyond the crease angle of
  // its face (the merge crossed a crease): then the normal of the vertex it
  // had (unfold.h).
  const auto corner_normal = [&](size_t i, int k, const Vec3d& key) -> Vec3 {
    const Vec3 n = resolve_corner(tris_[i][size_t(k)], key);
    if (renamed.empty() || !(glm::length(key) > 0) || glm::dot(Vec3d(n), key) >= cos_crease_) return n;
    const uint64_t corner = 3 * uint64_t(i) + uint64_t(k);
    const auto it = std::lower_bound(renamed.begin(), renamed.end(), std::pair<uint64_t, uint32_t>(corner, 0));
    if (it == renamed.end() || it->first != corner) return n;
    return resolve_corner(it->second, key);
  };
  constexpr size_t kChunk = size_t(1) << 18;  // triangles
  std::vector<Vec3> units(3 * std::min(kChunk, tris_.size()));
  for (size_t c0 = 0; c0 < tris_.size(); c0 += kChunk) {
    const size_t c1 = std::min(tris_.size(), c0 + kChunk);
    tbb::parallel_for(tbb::blocked_range<size_t>(c0, c1, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        if (!keep[i]) continue;
        const Vec3d key(keys_[i]);
        for (int k = 0; k < 3; ++k) units[3 * (i - c0) + size_t(k)] = corner_normal(i, k, key);
      }
    });
    for (size_t i = c0; i < c1; ++i) {
      if (!keep[i]) continue;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = tris_[i][size_t(k)];
        const Vec3& unit = units[3 * (i - c0) + size_t(k)];
        uint32_t out = first_out[v];
        while (out != kKeepVertex && !same_bits(mesh.normals[out], unit)) out = next_out[out];
        if (out == kKeepVertex) {
          out = uint32_t(mesh.positions.size());
          if (first_out[v] == kKeepVertex) {
            first_out[v] = out;
            if (v < nreps) ++stats_.representatives_used;
            else ++stats_.kept_vertices;
          } else {
            ++stats_.split_vertices;
            uint32_t last = first_out[v];
            while (next_out[last] != kKeepVertex) last = next_out[last];
            next_out[last] = out;
          }
          mesh.positions.push_back(v < nreps ? rep_pos_[v] : kept_pos_[v - nreps]);
          mesh.normals.push_back(unit);
          next_out.push_back(kKeepVertex);
        }
        mesh.indices.push_back(out);
      }
    }
  }
  stats_.normal_fallbacks += fallbacks.load();
  for (size_t v = 0; v < took.size(); ++v) stats_.exact_normals += took[v] && first_out[v] != kKeepVertex;  // output ones
  stats_.output_triangles = mesh.triangle_count();
  stats_.output_vertices = mesh.positions.size();
  stats_.peak_bytes = std::max(stats_.peak_bytes, memory_bytes() + first_out.size() * 4 + next_out.capacity() * 4 +
                                                      exact.size() + took.size() + units.size() * sizeof(Vec3) +
                                                      tris_.size() / 8 + mesh.positions.capacity() * 24 +
                                                      mesh.indices.capacity() * 4);
  if (stats_out) *stats_out = stats_;
  return mesh;
}

// ---------------------------------------------------------------- simplify

namespace {

// The estimate for collapsing the cells key_of(c) of `cells` (those the store
// has no node for are ignored).
template <class Cells, class KeyOf>
SimplifyEstimate estimate_cells(const OctreeStore& store, const Cells& cells, KeyOf key_of) {
  SimplifyEstimate e;
  uint64_t found = 0;
  for (const auto& c : cells)
    if (const NodeRecord* n = store.find(key_of(c))) { e.collapsed_corners += n->corner_count; ++found; }
  const uint64_t t = store.header().triangle_count;
  const uint64_t removed = std::min<uint64_t>(t, e.collapsed_corners / 3);
  e.triangles = std::min<uint64_t>(t, t - removed + 2 * found);
  e.vertices = e.triangles / 2 + found;
  e.bytes = e.triangles * kCollapseBytesPerTriangle + e.vertices * kCollapseBytesPerVertex +
            found * (sizeof(Representative) + 72 +
                     (store.header().has_normals ? 4 + 12 : kOneVertexBytesPerRepresentative));
  e.write_bytes = e.triangles * (12 + kDracoEncodeBytesPerTriangle) + e.vertices * 2 * sizeof(Vec3);
  return e;
}

}  // namespace

SimplifyEstimate estimate_simplify(const OctreeStore& store, const Cut& cut) {
  return estimate_cells(store, cut.cells, [](const auto& c) { return c.key; });
}

namespace {

// A page in flight through collapse_pass: its triangles and the cut cell of
// each of its vertices.
struct PageWork {
  PageMesh page;
  std::vector<uint32_t> vertex_cell;  // per page vertex
  // Neighbouring vertices mostly share a cell: a small direct-mapped cache
  // of code -> cut cell saves most of the hash lookups (one per level of the
  // cut).
  static constexpr size_t kCache = 1 << 12;
  std::vector<uint64_t> cache_code = std::vector<uint64_t>(kCache, ~uint64_t(0));
  std::vector<uint32_t> cache_cell = std::vector<uint32_t>(kCache, kKeepVertex);
  PreparedBatch prepared;
  bool inside_one_cell = false;  // the page lies in one collapsed cell: not read

  // The normals of the vertices of triangles not wholly inside one cell (the
  // only ones prepare_collapse and the builder read, unless exact normals
  // read them all: PageMesh::decode_normals); the others stay zero.
  std::vector<uint8_t> needed;
  void decode_needed_normals() {
    const size_t nv = page.vertices();
    needed.assign(nv, 0);
    for (size_t t = 0; t < page.size(); ++t) {
      const uint32_t* vi = &page.index[3 * t];
      const uint32_t c = vertex_cell[vi[0]];
      if (c != kKeepVertex && c == vertex_cell[vi[1]] && c == vertex_cell[vi[2]]) continue;
      needed[vi[0]] = needed[vi[1]] = needed[vi[2]] = 1;
    }
    page.normals.assign(nv, Vec3(0));
    for (size_t v = 0; v < nv; ++v)
      if (needed[v]) page.normals[v] = decode_octahedral(page.normal_codes[v]);
  }

  void look_up_cells(const CutLookup& lookup) {
    vertex_cell.resize(page.vertices());
    for (size_t v = 0; v < page.vertices(); ++v) {
      const uint64_t code = lookup.code_of(Vec3d(page.positions[v]));
      const size_t slot = (code ^ (code >> 17)) & (kCache - 1);
      if (cache_code[slot] != code) {
        cache_code[slot] = code;
        cache_cell[slot] = lookup.find_code(code);
      }
      vertex_cell[v] = cache_cell[slot];
    }
  }
};

// Whether every vertex of the page lies in one collapsed cell (then every
// triangle of it is inside that cell, and the page need not be read): its
// bounds' corners are in the same cut cell. Binning is monotone per axis, so
// every point between them is in that cell too.
bool page_inside_one_cell(const PageInfo& page, const CutLookup& lookup) {
  if (page.bounds.empty()) return false;
  const uint32_t c = lookup.find(page.bounds.lo);
  return c != kKeepVertex && c == lookup.find(page.bounds.hi);
}

// Marks folding[c] = 1 for every cut cell c that a triangle of the pages
// `page_list` turns over once collapsed, and sets page_folds[p] to the
// number of such triangles on each page p of the list, deciding each triangle as
// CollapseBuilder::add does (collapse_turns_over, prepare_collapse's fate) but building nothing: the
// fold passes need only which cells fold, and each triangle decides alone,
// so pages are scanned in parallel (the same marks for any thread count).
Status mark_folding_cells(const OctreeStore& store, std::span<const CellKey> keys,
                          std::span<const Representative> reps, std::span<const uint32_t> page_list,
                          std::vector<uint8_t>& folding, std::vector<uint32_t>& page_folds, uint64_t& pages_read,
                          uint64_t& pages_skipped) {
  const StoreHeader& h = store.header();
  const CutLookup lookup(h.root_lo, h.root_size, keys);
  std::vector<Vec3> rep_pos;
  rep_pos.reserve(reps.size());
  for (const auto& r : reps) rep_pos.push_back(Vec3(r.position));
  folding.assign(reps.size(), 0);
  tbb::enumerable_thread_specific<PageWork> work;
  std::atomic<uint64_t> skipped{0};
  std::mutex error_mutex;
  size_t error_page = page_list.size();
  Status error;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, page_list.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    PageWork& w = work.local();
    for (size_t j = r.begin(); j != r.end(); ++j) {
      page_folds[page_list[j]] = 0;
      if (page_inside_one_cell(store.pages()[page_list[j]], lookup)) {
        skipped.fetch_add(1, std::memory_order_relaxed);
        continue;  // no triangle of it turns over: all collapse
      }
      if (Status st = store.read_page(page_list[j], w.page); !st.ok()) {
        std::lock_guard lock(error_mutex);
        if (j < error_page) { error_page = j; error = st; }  // the first failing page, whatever the threads
        return;
      }
      w.look_up_cells(lookup);
      for (size_t t = 0; t < w.page.size(); ++t) {
        if (!collapse_turns_over(w.page, w.vertex_cell, rep_pos, t)) continue;
        ++page_folds[page_list[j]];
        for (int k = 0; k < 3; ++k)
          if (const uint32_t c = w.vertex_cell[w.page.index[3 * t + k]]; c != kKeepVertex)
            std::atomic_ref<uint8_t>(folding[c]).store(1, std::memory_order_relaxed);
      }
    }
  });
  pages_skipped += skipped.load();
  pages_read += page_list.size() - skipped.load();
  return error_page < page_list.size() ? error : Status::ok();
}

// Pages whose triangles may have a corner in one of the cells `changed`
// (world boxes): their bounds meet a cell's box, grown by a hair for the
// rounding of the corner binning.
std::vector<uint32_t> pages_touching(const OctreeStore& store, std::span<const Bbox> changed) {
  const auto pages = store.pages();
  const double hair = 1e-9 * store.header().root_size;
  std::vector<uint8_t> touch(pages.size(), 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, pages.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const Bbox& p = pages[i].bounds;
      for (const Bbox& c : changed) {
        if (p.lo.x <= c.hi.x + hair && c.lo.x - hair <= p.hi.x && p.lo.y <= c.hi.y + hair &&
            c.lo.y - hair <= p.hi.y && p.lo.z <= c.hi.z + hair && c.lo.z - hair <= p.hi.z) {
          touch[i] = 1;
          break;
        }
      }
    }
  });
  std::vector<uint32_t> out;
  for (size_t i = 0; i < pages.size(); ++i)
    if (touch[i]) out.push_back(uint32_t(i));
  return out;
}

// For each page, the bounds of the other pages whose bounds meet its own
// (only they can hold a vertex at a position of this page's), and its cell
// shrunk by the farthest any of them reaches out of its own cell (no other
// page's bounds reach into that box's interior).
class PageNeighbours {
 public:
  explicit PageNeighbours(const OctreeStore& store) {
    const auto pages = store.pages();
    const StoreHeader& h = store.header();
    // The page-level cells a box covers (the store's binning, clamped to the cube).
    auto for_cells = [&](const Bbox& b, auto&& f) {
      uint32_t lo[3], hi[3];
      morton_decode(store.cell_of(b.lo, h.page_level).code, lo[0], lo[1], lo[2]);
      morton_decode(store.cell_of(b.hi, h.page_level).code, hi[0], hi[1], hi[2]);
      for (uint32_t x = lo[0]; x <= hi[0]; ++x)
        for (uint32_t y = lo[1]; y <= hi[1]; ++y)
          for (uint32_t z = lo[2]; z <= hi[2]; ++z) f(morton_encode(x, y, z));
    };
    std::unordered_map<uint64_t, std::vector<uint32_t>> by_cell;
    std::vector<double> spill(pages.size(), 0);
    for (size_t i = 0; i < pages.size(); ++i) {
      if (pages[i].bounds.empty()) continue;
      for_cells(pages[i].bounds, [&](uint64_t c) { by_cell[c].push_back(uint32_t(i)); });
      const Bbox own = store.cell_bounds({uint32_t(h.page_level), pages[i].code});
      for (int a = 0; a < 3; ++a)
        spill[i] = std::max({spill[i], own.lo[a] - pages[i].bounds.lo[a], pages[i].bounds.hi[a] - own.hi[a]});
    }
    start_.assign(1, 0);
    inner_.resize(pages.size());
    std::vector<uint32_t> found;
    for (size_t i = 0; i < pages.size(); ++i) {
      found.clear();
      if (!pages[i].bounds.empty())
        for_cells(pages[i].bounds, [&](uint64_t c) {
          for (uint32_t j : by_cell[c]) found.push_back(j);
        });
      std::sort(found.begin(), found.end());
      found.erase(std::unique(found.begin(), found.end()), found.end());
      double margin = 0;
      for (uint32_t j : found) {
        if (j == i || !meet(pages[i].bounds, pages[j].bounds)) continue;
        boxes_.push_back(pages[j].bounds);
        margin = std::max(margin, spill[j]);
      }
      start_.push_back(uint32_t(boxes_.size()));
      Bbox inner = store.cell_bounds({uint32_t(h.page_level), pages[i].code});
      inner.lo += margin;
      inner.hi -= margin;
      inner_[i] = inner;
    }
  }
  std::span<const Bbox> others(size_t page) const {
    return std::span<const Bbox>(boxes_).subspan(start_[page], start_[page + 1] - start_[page]);
  }
  const Bbox& inner(size_t page) const { return inner_[page]; }

 private:
  static bool meet(const Bbox& a, const Bbox& b) {
    return a.lo.x <= b.hi.x && b.lo.x <= a.hi.x && a.lo.y <= b.hi.y && b.lo.y <= a.hi.y && a.lo.z <= b.hi.z &&
           b.lo.z <= a.hi.z;
  }
  std::vector<uint32_t> start_;
  std::vector<Bbox> boxes_;
  std::vector<Bbox> inner_;
};

// One pass over the store's pages collapsing `keys` (cells the store has
// nodes for) to the builder's representatives. Pages are read, decoded and looked up in parallel
// and added to the builder one at a time in page order, so the mesh does not
// depend on the thread count.
Status collapse_pass(const OctreeStore& store, std::span<const CellKey> keys, const SimplifyConfig& config,
                     const SimplifyEstimate& estimate, CollapseBuilder& builder, uint64_t& pages_read,
                     uint64_t& pages_skipped) {
  const StoreHeader& h = store.header();
  const CutLookup lookup(h.root_lo, h.root_size, keys);
  builder.reserve(estimate.vertices + estimate.vertices / 4, estimate.triangles);
  const auto pages = store.pages();
  const PageNeighbours neighbours(store);
  std::optional<Progress> progress;
  if (config.progress) progress.emplace("simplify", pages.size(), "pages");

  const size_t ntokens = std::clamp<size_t>(2 * size_t(ambient_parallelism()), 2, 8);
  Status done = ordered_pipeline<PageWork>(
      pages.size(), ntokens,
      [&](PageWork& w, size_t i) -> Status {
        w.inside_one_cell = page_inside_one_cell(pages[i], lookup);
        if (w.inside_one_cell) return {};  // its triangles' normals come through the node's sum
        RAYLOD_RETURN_IF_ERROR(store.read_page(i, w.page));
        w.look_up_cells(lookup);
        if (store.header().has_normals) {
          if (config.exact_normals) w.page.decode_normals();
          else w.decode_needed_normals();
        }
        prepare_collapse(w.page, w.vertex_cell, builder.representative_positions(), store.header().has_normals,
                         w.prepared, config.exact_normals, config.crease_angle_deg);
        mark_page_unique_vertices(w.page, w.vertex_cell, neighbours.others(i), neighbours.inner(i), w.prepared);
        return {};
      },
      [&](PageWork& w, size_t i) -> Status {
        if (w.inside_one_cell) {
          ++pages_skipped;
          builder.add_inside_cell(pages[i].triangle_count);
        } else {
          ++pages_read;
          builder.add(w.page, w.vertex_cell, w.prepared);
        }
        if (config.memory_limit && builder.memory_bytes() > config.memory_limit)
          return Status::error("the simplified mesh outgrew the memory limit of " + format_bytes(config.memory_limit) +
                               " after " + std::to_string(builder.triangles()) + " triangles (page " +
                               std::to_string(i + 1) + " of " + std::to_string(pages.size()) +
                               "); raise --memory-limit or collapse more cells");
        if (progress) progress->advance(1);
        return {};
      });
  RAYLOD_RETURN_IF_ERROR(done);
  if (progress) progress->finish();
  return Status::ok();
}

}  // namespace

StatusOr<SimplifyResult> simplify(const OctreeStore& store, const Cut& cut, const SimplifyConfig& config) {
  const auto start = std::chrono::steady_clock::now();
  const StoreHeader& h = store.header();
  SimplifyResult result;
  result.cut_cells = cut.cells.size();

  // Exact normals keep a sample per representative (CollapseBuilder).
  const uint64_t per_cell = config.exact_normals ? kExactNormalsBytesPerRepresentative : 0;
  SimplifyEstimate estimate = estimate_simplify(store, cut);
  estimate.bytes += per_cell * cut.cells.size();
  if (config.memory_limit && estimate.bytes > config.memory_limit)
    return Status::error("the simplified mesh (about " + std::to_string(estimate.triangles) + " triangles) needs about " +
                         format_bytes(estimate.bytes) + ", over the memory limit of " +
                         format_bytes(config.memory_limit) + "; raise --memory-limit or collapse more cells");

  // Representatives of the cut cells the store has nodes for.
  std::vector<CellKey> keys;
  std::vector<Representative> reps;
  keys.reserve(cut.cells.size());
  reps.reserve(cut.cells.size());
  auto add_cell = [&](const CellKey& key, const NodeRecord& node) {
    keys.push_back(key);
    reps.push_back(make_representative(node, store.cell_bounds(key), h.origin, config.qem));
  };
  for (const auto& c : cut.cells) {
    const NodeRecord* node = c.key.level <= uint32_t(h.quadric_depth) ? store.find(c.key) : nullptr;
    if (!node) { ++result.cut_cells_missing; continue; }
    add_cell(c.key, *node);
  }
  // The cut as given is built first, in one pass over every page, which
  // also finds the cells that turn a triangle over. Fold passes then refine
  // those: which cells turn a triangle over under a refined cut is decided
  // by a scan that builds nothing, of only the pages near the cells the last
  // pass changed (a triangle with no corner there decides as before, and it
  // did not fold then, or its cells would have changed). A refinement is
  // kept only if the scan after it finds fewer triangles turned over in all
  // (on those pages: elsewhere nothing changed). If any is kept, one more
  // pass builds the mesh of the refined cut; if none, the first build is the
  // mesh (the 100M glass teapot: its first refinement is taken back, and
  // this saves a scan of every page).
  const auto seconds_since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  // A mesh with normals of its own is shaded by them in the full render,
  // whatever --crease-angle says (crease_normals.h): its representatives
  // group them by the default angle, so the option does not change the
  // simplified mesh alone (a faceted PLY at 180 degrees got one smooth
  // normal per representative: radial streaks, 14 dB below the floor).
  const double crease_angle = h.has_normals ? kDefaultCreaseAngleDeg : config.crease_angle_deg;
  // The builder holds a span of the representatives: the cut as given keeps
  // its own while the passes swap `reps` for refined ones.
  const std::vector<Representative> first_reps = reps;
  std::optional<CollapseBuilder> first(std::in_place, first_reps, h.has_normals, crease_angle);
  RAYLOD_RETURN_IF_ERROR(collapse_pass(store, keys, config, estimate, *first, result.pages_read, result.pages_skipped));

  const auto fold_start = std::chrono::steady_clock::now();
  std::vector<uint32_t> page_list;
  // Turned-over triangles per page under the cut as it stands, for the pages
  // scanned: a large folding cell's children can fold against their new
  // neighbours in turn, and a folding finest cell kept whole brings every
  // triangle it holds (the 100M teapot, whose finest cells hold about a
  // hundred triangles each: 5,671 turned over before any pass, 11,636 after
  // the first refinement, 5,931 after three, for 1.6M -> 4.85M triangles).
  std::vector<uint32_t> page_folds(config.fold_passes > 0 ? store.pages().size() : 0, 0);
  std::vector<CellKey> kept_keys;  // the cut before the last refinement, until a scan judges it
  std::vector<Representative> kept_reps;
  uint64_t kept_refined = 0;
  SimplifyEstimate kept_estimate;
  // Whether the scan of page_list under the current cut finds fewer
  // triangles turned over than under the cut before the last refinement
  // (page_folds holds those counts), and the cells to refine.
  auto scan_fewer = [&](std::vector<uint8_t>& folding, bool& fewer) -> Status {
    uint64_t before = 0, after = 0;
    for (const uint32_t p : page_list) before += page_folds[p];
    RAYLOD_RETURN_IF_ERROR(mark_folding_cells(store, keys, reps, page_list, folding, page_folds, result.pages_read,
                                              result.pages_skipped));
    for (const uint32_t p : page_list) after += page_folds[p];
    fewer = after < before;
    return {};
  };
  // Keeps the last refinement, or takes it back.
  auto judge_last_refinement = [&](bool fewer) {
    if (!fewer) {
      keys.swap(kept_keys);
      reps.swap(kept_reps);
      estimate = kept_estimate;
      result.fold_cells_refined -= kept_refined;
      --result.fold_passes;
      ++result.fold_passes_undone;
    }
    std::vector<CellKey>().swap(kept_keys);
    std::vector<Representative>().swap(kept_reps);
  };
  for (int pass = 0; pass < config.fold_passes; ++pass) {
    std::vector<uint8_t> folding;
    if (pass == 0) {
      folding = first->folding();
    } else {
      bool fewer = false;
      RAYLOD_RETURN_IF_ERROR(scan_fewer(folding, fewer));
      judge_last_refinement(fewer);
      if (!fewer) break;
    }
    if (std::find(folding.begin(), folding.end(), uint8_t(1)) == folding.end()) break;
    // Each folding cell gives way to its children (the cut stays an
    // antichain: children of a cut cell are in no other cut cell).
    std::vector<CellKey> next_keys;
    std::vector<Representative> next_reps;
    std::vector<Bbox> changed;
    for (size_t i = 0; i < keys.size(); ++i) {
      if (!folding[i]) {
        next_keys.push_back(keys[i]);
        next_reps.push_back(reps[i]);
        continue;
      }
      changed.push_back(store.cell_bounds(keys[i]));
      if (keys[i].level >= uint32_t(h.quadric_depth)) continue;
      for (uint64_t c = 0; c < 8; ++c) {
        const CellKey child{keys[i].level + 1, (keys[i].code << 3) | c};
        if (const NodeRecord* node = store.find(child)) {
          next_keys.push_back(child);
          next_reps.push_back(make_representative(*node, store.cell_bounds(child), h.origin, config.qem));
        }
      }
    }
    // Refined cells keep more triangles (at 100M, 6.6M -> 9.4M over three
    // passes): the refinement stops where it would outgrow the memory limit,
    // leaving those folds, rather than fail in the building pass.
    SimplifyEstimate refined = estimate_cells(store, next_keys, [](const CellKey& k) { return k; });
    refined.bytes += per_cell * next_keys.size();
    const uint64_t fold_limit = config.fold_memory_limit ? config.fold_memory_limit : config.memory_limit;
    if (fold_limit && refined.bytes > fold_limit) {
      result.folds_stopped_by_memory = true;
      break;
    }
    page_list = pages_touching(store, changed);
    if (pass == 0) {
      // The counts the refinement is judged against, on the pages it
      // touches, under the cut as given: by the scan's rule, as every later
      // count is (the build's own count is not per page, and it tells two
      // kept corners at one position apart by their normals, which the scan
      // does not).
      std::vector<uint8_t> unused;
      RAYLOD_RETURN_IF_ERROR(mark_folding_cells(store, keys, reps, page_list, unused, page_folds, result.pages_read,
                                                result.pages_skipped));
    }
    kept_estimate = estimate;
    estimate = refined;  // the building pass reserves for what comes
    kept_refined = changed.size();
    result.fold_cells_refined += changed.size();  // one box per folding cell
    kept_keys = std::move(keys);
    kept_reps = std::move(reps);
    keys = std::move(next_keys);
    reps = std::move(next_reps);
    ++result.fold_passes;
  }
  // The last refinement, judged by one more scan of the pages it touched.
  if (!kept_keys.empty()) {
    std::vector<uint8_t> folding;
    bool fewer = false;
    RAYLOD_RETURN_IF_ERROR(scan_fewer(folding, fewer));
    judge_last_refinement(fewer);
  }
  result.fold_seconds = seconds_since(fold_start);
  if (result.fold_passes > 0) {
    first.reset();  // its memory, before the refined cut's build
    first.emplace(reps, h.has_normals, crease_angle);
    RAYLOD_RETURN_IF_ERROR(collapse_pass(store, keys, config, estimate, *first, result.pages_read, result.pages_skipped));
  }
  const auto finish_start = std::chrono::steady_clock::now();
  first->set_unfold(config.unfold);
  result.mesh = first->finish(&result.stats);
  result.finish_seconds = seconds_since(finish_start);
  for (const Representative& r : reps) result.clamped_representatives += r.clamped;
  result.mesh.origin = h.mesh_origin;  // the store's coordinates are the mesh's, relative to it
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string why_simplified_mesh_is_empty(const SimplifyResult& result, const Cut& cut) {
  if (result.mesh.triangle_count() > 0) return {};
  const CollapseStats& s = result.stats;
  const std::string n = std::to_string(s.input_triangles);
  if (s.input_triangles == 0) return "the store holds no triangles";
  if (cut.cells.empty() || s.dropped_zero_area == s.input_triangles || s.input_degenerate == s.input_triangles)
    return "all " + n + " triangles are degenerate (zero area or repeated corners)";
  return "all " + n + " triangles collapsed: the cut merged every vertex into " + std::to_string(result.cut_cells) +
         " cell(s) finer than the view resolves (the whole mesh is about a pixel or less here)";
}

}  // namespace raylod
