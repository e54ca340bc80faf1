// Collapsing the cut (method step A5, after Luebke and Erikson 1997): every
// triangle vertex inside a collapsed cell moves to that cell's representative
// vertex (eqs. 3-4, see qem_solve.h); every other vertex is kept exactly.
// Triangles that become degenerate disappear, and so do exact duplicates.
//
// Layers, so that each can be tested without a store file:
//   CutLookup        vertex position -> the cut cell containing it (or none)
//   make_representative  a NodeRecord -> its representative vertex
//   CollapseBuilder  triangle batches + per-vertex cell ids -> indexed mesh
//   prepare_collapse what a batch's triangles become (parallel, no state)
//   simplify()       the thin driver: fold checks, then one building pass.
//
// Decisions (see collapse.cpp for the reasons):
//   * A triangle is dropped if two of its output vertices are the same vertex,
//     if its area is exactly zero (collinear corners, or corners that coincide
//     in position only; slivers are kept so that no crack opens), or
//     if it repeats an earlier triangle with the same three output vertices in
//     the same cyclic order. Its reverse-wound twin (same vertices, opposite
//     orientation) is KEPT: a thin wall collapsed to zero thickness keeps both
//     sides, so every edge keeps its pairing and a closed input stays closed.
//   * Normals follow the crease rule of geometry/crease_normals.h, so that
//     collapsing nothing reproduces the full render. A kept vertex with
//     input normals keeps its input normal exactly. A kept vertex without
//     them gets, per corner, the angle-weighted sum of its input triangles'
//     normals within the crease angle of that corner's input triangle (the
//     full render's rule). A representative whose cell holds one vertex
//     (every corner of the cell's count at one input position) is output
//     as that vertex kept: the cut marks such cells wherever nothing there
//     deviates, and their collapse changes nothing. Its position is the
//     vertex's; without input normals its corners take the rule above, with
//     them each corner the input normal nearest its face's (its own, for
//     per-vertex normals, faceted per-corner normals and normals split at
//     creases alike). Any other representative clusters the
//     normals of every corner merged into it (input vertex normals, else
//     face normals; area weighted). A triangle wholly inside the cell vanishes unexamined (at
//     100M triangles, 9 in 10 under a coarse cut): the corners of the
//     triangles reaching out of the cell are clustered one by one, and the
//     rest come as one sum, the store node's normal sum less theirs, which
//     joins the cluster within 10 degrees of its direction (a smooth cell's
//     mean is then its whole mean) or, across a crease, where it points
//     between the sides, the leftover sum that only a crease angle of 180
//     degrees uses. A corner there gets the clusters within the crease
//     angle of its input triangle's normal: a cell spanning a crease has one
//     normal per side, a flat side exactly its own normal. If nothing is
//     within the angle, the mean of all clusters, then the dominant plane
//     normal of the cell's quadric (dominant_normal), then +Y.
//   * Exact normals (SimplifyConfig::exact_normals): the cluster mean is
//     the normal of the cell's surface on average, not at the
//     representative. Where the normal bends unevenly
//     in the cell (the S-shaped foot of the teapot: a surface that is
//     nearly flat, so the quadric allows the collapse, while its normal
//     swings by 0.4 rad) the two differ by up to 0.03 rad, and glass shows
//     it. The representative then takes the normal the full render shades
//     at the input surface point nearest it, found among the triangles
//     with a corner in its cell: the input's normals interpolated there, or
//     for a mesh without normals the crease rule's corner normals
//     (crease_corner_normals, computed over the page's triangles; a vertex
//     on a page's border misses the triangles of the next page, which on a
//     smooth surface lie within a few degrees: no sample is taken from a
//     triangle with a corner whose fan the page cuts). It applies for the
//     corners whose cluster lies within the crease angle of it (the other
//     side of a crease keeps its cluster); a crease-rule sample only within
//     1 degree of the cluster: further off, samples on abc3.stl's cylinder
//     shaded single long strips as streaks (the cause not pinned down: a
//     neighbouring surface within the crease angle, or a fan the page holds
//     otherwise than the full mesh). On ABC's abc3.stl as a mirror the uncapped
//     samples gave 52.70 dB against 56.31 without any (floor 46.96); capped
//     at 5, 2, 1 and 0.5 degrees 52.70, 55.12, 57.50 and 56.38; as glass
//     46.97 without, 47.44 at 1 degree (floor 38.77); mirror close-ups of
//     the OpenCASCADE pump cover and crank arm went from 43.78 and 38.23 dB
//     to 47.06 and 39.16 (floors 48.76 and 40.72). Input normals' samples
//     take no such cap: at 1 degree the glass scene lost 0.12 dB. Either
//     counts only if its point lies within 1/16 of the cell's side (a page wholly
//     inside the cell is not read, so the nearest point found may be a far
//     one: the mean is kept then).
//   * Triangles turned over against their input triangles (a
//     representative beyond the far edge of a triangle it joins) are
//     unfolded before the output is indexed (unfold.h): the representatives
//     slide within their cells, or an edge of the turned-over triangle
//     collapses, within a few times the deviation the cut allowed the cell.
//     Fold passes (SimplifyConfig::fold_passes) refine what is left first.
//   * Output is indexed: kept vertices with bit-identical position (and
//     input normal, where the input has normals) are one vertex, then every
//     vertex is split by the distinct normals its corners got. Vertex and
//     triangle order follow the input stream, so the output is deterministic.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "geometry/crease_normals.h"
#include "geometry/qem_solve.h"
#include "streaming/cut_file.h"
#include "streaming/draco_io.h"
#include "streaming/octree_store.h"
#include "streaming/page_codec.h"

namespace raylod {

inline constexpr uint32_t kKeepVertex = 0xffffffffu;

// The output vertex of one collapsed cell.
struct Representative {
  Vec3d position{0};         // world coordinates, float-representable, inside the cell
  Vec3d fallback_normal{0, 1, 0};  // unit; used when the merged normals cancel
  // The cell's area-weighted normal sum over all its corners, in the units of
  // PreparedBatch::RepresentativeNormal (twice the area): NodeRecord::normal_sum x 6.
  // Without it (has_normal_sum false) the normals of triangles wholly inside
  // the cell are left out.
  Vec3d normal_sum{0};
  bool has_normal_sum = false;
  int rank = 0;              // rank of the QEM solve (qem_solve.h)
  bool clamped = false;
  double side = 0;           // the cell's edge length (world units); 0 = unknown
  Vec3d cell_lo{0};          // the cell's lowest corner (world), with `side` its box
  double deviation = 0;      // sqrt(12) times its RMS distance from the cell's planes (world)
  // The cell's triangle corners (NodeRecord::corner_count); 0 = unknown. A
  // cell whose corners all lie at one input position holds one vertex, and
  // its collapse changes nothing: it is then output as a kept vertex.
  uint64_t corner_count = 0;
};

// Representative of a stored node: QEM solve relative to the store origin
// around the node's mean vertex, kept inside cell_bounds (world).
Representative make_representative(const NodeRecord& node, const Bbox& cell_bounds_world, const Vec3d& origin,
                                   const QemSolveConfig& config = {});

// Finds the cut cell containing a point. Cells are (level, Morton code) keys
// of the cube (root_lo, root_size); a point's cell at level L is
// floor((p - root_lo) * (2^L / root_size)) per axis, clamped to the grid, i.e.
// the binning the store build uses for corners. The cut is an antichain, so at most one
// of the point's ancestors at the cut's levels is in it.
class CutLookup {
 public:
  CutLookup(const Vec3d& root_lo, double root_size, std::span<const CellKey> cells);
  // Index into `cells` of the cut cell containing p, or kKeepVertex.
  uint32_t find(const Vec3d& p) const { return find_code(code_of(p)); }
  // The two halves of find: p's Morton code at deepest_level(), then the cut
  // cell among that code's ancestors (callers may cache the second).
  uint64_t code_of(const Vec3d& p) const;
  uint32_t find_code(uint64_t deepest_code) const;
  int deepest_level() const { return deepest_; }

 private:
  Vec3d root_lo_;
  double root_size_;
  int deepest_ = 0;
  std::vector<int> levels_;  // levels present, deepest first
  std::vector<std::unordered_map<uint64_t, uint32_t>> by_level_;  // indexed by level
};

struct CollapseStats {
  uint64_t input_triangles = 0;
  uint64_t output_triangles = 0;
  uint64_t dropped_collapsed = 0;   // two corners became the same output vertex
  uint64_t inside_cell = 0;         // of those: all three corners in one cell (not examined further)
  uint64_t dropped_zero_area = 0;   // distinct vertices, exactly zero area
  uint64_t input_degenerate = 0;    // input triangles with exactly zero area, among those not inside one cell
  uint64_t dropped_duplicate = 0;   // same vertices and orientation as an earlier triangle
  uint64_t reverse_twins = 0;       // kept triangles whose reverse-wound twin is also kept
  uint64_t output_vertices = 0;
  uint64_t representatives_used = 0;  // distinct representatives (before splitting by normal)
  uint64_t one_vertex_cells = 0;      // of those: cells of one vertex, output as kept
  uint64_t kept_vertices = 0;         // distinct kept vertices (before splitting by normal)
  uint64_t split_vertices = 0;        // extra output vertices for corners with their own normal
  uint64_t normal_fallbacks = 0;      // corners whose normals cancelled (quadric's normal or +Y used)
  uint64_t exact_normals = 0;         // representatives given the input's normal at their nearest input point
  uint64_t folded = 0;                // kept triangles turned over: facing against their input triangle
  // Unfolding (unfold.h), counted over the whole mesh as it stands (after
  // cells of one vertex are output as kept): 0 when it is off.
  uint64_t folded_before_unfold = 0;  // turned over before unfolding
  uint64_t folded_after_unfold = 0;   // and after
  uint64_t unfold_moved = 0;          // representatives slid
  uint64_t unfold_merged = 0;         // representatives merged into a neighbour
  uint64_t unfold_dropped = 0;        // triangles those merges removed
  uint64_t peak_bytes = 0;          // largest memory_bytes() seen
};

// What collapsing does to each triangle and corner of a page, worked out
// from the page, its vertices' cells and the representatives' positions
// alone (prepare_collapse): pages are prepared in parallel, then added to
// the builder one at a time in order.
enum class TriangleFate : uint8_t {
  kInsideCell,  // all three corners in one collapsed cell: dropped unexamined (its normal comes
                // back through Representative::normal_sum)
  kCollapsed,  // two corners became the same output vertex
  kZeroArea,   // distinct output vertices, exactly zero area
  kKept,
  kKeptFolded,  // kept, with a representative corner, facing against its input triangle
};
struct PreparedBatch {
  std::vector<Vec3d> face;        // per triangle: its input triangle's unit normal (zero without area)
  std::vector<double> area2;      // per triangle: twice its input area (the weight of its corners' normals)
  std::vector<TriangleFate> fate;
  std::vector<uint64_t> hash;     // per page vertex: the kept-vertex table's hash (kept vertices)
  std::vector<double> angle;      // per corner: interior angle (kept corners of inputs without normals)
  // The normals the page adds to representatives' clusters, in order of
  // first use: with input normals one per page vertex (its corners' weights
  // summed); else one per triangle and cell (the face normal, weighted by
  // the corners there).
  struct RepresentativeNormal {
    uint32_t rep;
    double weight;
    Vec3d normal;
  };
  std::vector<RepresentativeNormal> rep_normals;
  // Every corner of a representative outside the triangles wholly inside
  // one cell, with its input position, its angle (inputs without normals;
  // else 0, as without area) and its triangle's unit normal, so that a cell
  // holding one vertex can be output as that vertex is kept (collapse.h).
  struct RepresentativeCorner {
    uint32_t rep;
    Vec3 position;
    float angle;
    Vec3 face;
  };
  std::vector<RepresentativeCorner> rep_corners;
  // With exact normals (SimplifyConfig::exact_normals): per representative
  // the page met, the input surface point nearest it among the page's
  // triangles with a corner in its cell, as the squared distance and the
  // input normal interpolated there (first nearest in triangle order).
  struct RepresentativeSample {
    uint32_t rep;
    float d2;
    Vec3 normal;
  };
  std::vector<RepresentativeSample> rep_samples;
  // Scratch: open addressing from representative to its entry in
  // rep_samples, sized to the page (a page meets few representatives).
  std::vector<std::pair<uint32_t, uint32_t>> rep_slot;
  uint32_t& slot_of(uint32_t rep);
  std::vector<uint32_t> vertex_normal;  // scratch: per page vertex, its entry in rep_normals
  // Per page vertex: 1 if no other page can hold a vertex at its position
  // (mark_page_unique_vertices); such a kept vertex skips the builder's
  // table of kept vertices. Empty: every vertex goes through the table.
  std::vector<uint8_t> unique;
};
// vertex_cell[v] is the representative index of page vertex v, or
// kKeepVertex; rep_pos[i] is representative i's float position;
// input_has_normals as for CollapseBuilder (the page's normals must then be
// decoded, PageMesh::decode_normals).
// exact_normals: also find each representative's nearest input surface point
// (PreparedBatch::rep_samples; the page's normals must all be decoded), and
// the normal the full render shades there: the input's, interpolated, or
// without input normals the crease rule's corner normals
// (crease_corner_normals over the page's triangles, at crease_angle_deg).
void prepare_collapse(const PageMesh& page, std::span<const uint32_t> vertex_cell, std::span<const Vec3> rep_pos,
                      bool input_has_normals, PreparedBatch& out, bool exact_normals = false,
                      double crease_angle_deg = kDefaultCreaseAngleDeg);
// Marks out.unique for the kept vertices (vertex_cell kKeepVertex) of a page
// whose position lies in no box of `other_pages` (the decoded bounds of every
// other page whose bounds meet this page's): no other page has a vertex
// there, so the vertex is new to the mesh. `inner` is a box such that no
// other page's bounds reach into its interior (a fast accept; may be empty).
void mark_page_unique_vertices(const PageMesh& page, std::span<const uint32_t> vertex_cell,
                               std::span<const Bbox> other_pages, const Bbox& inner, PreparedBatch& out);
// Whether triangle t of the page turns over once collapsed: the fate
// prepare_collapse gives is kKeptFolded. Normals are not needed decoded.
bool collapse_turns_over(const PageMesh& page, std::span<const uint32_t> vertex_cell, std::span<const Vec3> rep_pos,
                         size_t t);

// Builds the collapsed, indexed mesh from a stream of triangle batches.
class CollapseBuilder {
 public:
  // reps[i] is the output vertex of cell i; input_has_normals says whether
  // batches carry vertex normals; crease_angle_deg is the crease rule's angle.
  CollapseBuilder(std::span<const Representative> reps, bool input_has_normals,
                  double crease_angle_deg = kDefaultCreaseAngleDeg);
  // cell[k] is the representative index of batch vertex k (3 per triangle),
  // or kKeepVertex. Batch positions must be finite.
  void add(const TriangleBatch& batch, std::span<const uint32_t> cell);
  // A page (normals decoded if the input has them), vertex_cell[v] the
  // representative index of page vertex v or kKeepVertex, prepared by
  // prepare_collapse(page, vertex_cell, representative_positions(), ...).
  void add(const PageMesh& page, std::span<const uint32_t> vertex_cell, const PreparedBatch& prepared);
  // Counts `triangles` wholly inside one collapsed cell that were not read
  // (a page inside one cell): they add nothing else.
  void add_inside_cell(uint64_t triangles);
  std::span<const Vec3> representative_positions() const { return rep_pos_; }
  // Pre-sizes the buffers (avoids rehashing the vertex table while streaming).
  void reserve(uint64_t vertices, uint64_t triangles);
  // Whether finish() unfolds turned-over triangles (unfold.h; default on).
  void set_unfold(bool on) { unfold_ = on; }
  // Unfolds turned-over triangles, drops duplicates, compacts, resolves the
  // normals and returns the mesh (normals always filled).
  IndexedMesh finish(CollapseStats* stats = nullptr);
  // Bytes held by the mesh under construction (capacity of its buffers).
  uint64_t memory_bytes() const;
  uint64_t triangles() const { return tris_.size(); }
  // Per representative: 1 if a triangle using it came out turned over.
  const std::vector<uint8_t>& folding() const { return folding_; }

 private:
  uint32_t kept_vertex(const Vec3& p, const Vec3& n, uint64_t hash);
  uint32_t new_kept_vertex(const Vec3& p, const Vec3& n);  // one no other page has (skips the table)
  void grow_table();

  std::span<const Representative> reps_;
  bool has_normals_;
  double cos_crease_;
  std::vector<Vec3> rep_pos_;            // float positions of the representatives
  std::vector<Vec3> kept_pos_, kept_normal_;  // kept_normal_ only with input normals
  NormalClusterPool clusters_;           // per provisional vertex (reps first, then kept)
  PreparedBatch prepared_;               // scratch of add() with a batch
  PageMesh page_;                        // scratch of add() with a batch
  std::vector<uint32_t> page_kept_;      // scratch: per page vertex, its kept-vertex id once known
  std::vector<uint32_t> table_;          // open addressing into kept_*, kKeepVertex = empty
  size_t table_count_ = 0;               // ids in table_
  std::vector<std::array<uint32_t, 3>> tris_;  // provisional ids: reps first, then kept
  std::vector<Vec3> keys_;               // per triangle: its input triangle's unit normal (crease key)
  std::vector<uint8_t> folding_;         // per representative
  std::vector<Vec3d> reached_sum_;       // per representative: the normals its clusters were given
  std::vector<float> sample_d2_;         // per representative: its nearest input point's squared distance
  std::vector<Vec3> sample_normal_;      // and the input normal there (empty: no samples given)
  // Per representative: its corners seen at one position
  // (kSeveralPositions once a second position comes) and that position;
  // without input normals, those corners' normals angle weighted, as a kept
  // vertex's.
  std::vector<uint32_t> rep_corners_seen_;
  std::vector<Vec3> rep_first_position_;
  NormalClusterPool one_vertex_clusters_;
  bool unfold_ = true;
  CollapseStats stats_;
};

// Bytes per output triangle and vertex that CollapseBuilder and finish() hold
// at their peak (used to check a memory limit before any work).
inline constexpr uint64_t kCollapseBytesPerTriangle = 12 + 12 + 4 + 12 + 12 + 12;
inline constexpr uint64_t kCollapseBytesPerVertex = 12 + 12 + 8 + 4 + 4 + 2 * sizeof(NormalCluster) + 24 + 8;
// With exact normals, per representative: its nearest input point's squared
// distance and normal, whether it is near enough and whether a corner took it.
inline constexpr uint64_t kExactNormalsBytesPerRepresentative = 4 + 12 + 1 + 1;
// Per representative: its corners seen at one position and that position;
// without input normals also its list heads in the one-vertex clusters and
// about two clusters (a cell of several vertices stops adding at the second
// position).
inline constexpr uint64_t kOneVertexBytesPerRepresentative = 4 + 12 + 8 + 2 * sizeof(NormalCluster);

// Bytes the Draco encoder holds on top of the mesh it encodes, per triangle
// (speed 5, with normals, about half as many vertices as triangles):
// `build/tools/bench_draco_memory --side 1500` measured 124.9 and
// `--side 2500` 127.7. The mesh itself stays resident meanwhile.
inline constexpr uint64_t kDracoEncodeBytesPerTriangle = 128;

inline constexpr int kSpecularFoldPasses = 3;

struct SimplifyConfig {
  QemSolveConfig qem;
  // The normal rule (geometry/crease_normals.h) for a store without
  // normals; a store with its own groups them at representatives by the
  // default angle, as the full render ignores the option for it.
  double crease_angle_deg = kDefaultCreaseAngleDeg;
  // Memory the simplified mesh may use while it is built (bytes); 0 = no limit.
  uint64_t memory_limit = 0;
  bool progress = false;  // show a progress bar over the store's pages
  // Passes that replace a cell whose representative turns a triangle over
  // by its children (a finest cell is kept instead); 0 = collapse the cut as
  // given. The pipeline asks for kSpecularFoldPasses on meshes with a mirror
  // or glass material: a turned-over triangle shows there as a sparkle, while
  // opaque shading is two-sided and hides it.
  int fold_passes = 0;
  // Estimated memory (SimplifyEstimate::bytes) the fold passes may let the
  // mesh grow to: a pass whose refined cells would need more is left out,
  // its folds stay and folds_stopped_by_memory says so. 0 = memory_limit.
  uint64_t fold_memory_limit = 0;
  // A representative takes the normal the full render shades at the input
  // surface point nearest it (the input's, interpolated, or the crease
  // rule's without input normals), where the cell's mean normal would
  // otherwise stand (above). The pipeline asks for it on meshes with a
  // mirror or glass material, whose reflected and refracted rays turn with
  // every error in the normal.
  bool exact_normals = false;
  // Turned-over triangles left (after any fold passes) are unfolded: their
  // representatives slide, or their edges collapse, within their cells'
  // deviation (unfold.h). Off: `raylod simplify --no-unfold`, to compare.
  bool unfold = true;
};

struct SimplifyEstimate {
  uint64_t triangles = 0;  // expected output triangles (10M teapot: within 0.01% of the real count)
  uint64_t vertices = 0;
  uint64_t bytes = 0;      // memory to build them
  uint64_t write_bytes = 0;  // memory while they are Draco-encoded (the mesh and the encoder)
  uint64_t collapsed_corners = 0;
};
// Estimate from the store's counts and the cut alone: triangles with no corner
// in a collapsed cell survive, plus about two triangles per representative
// vertex (Euler: T ~ 2V on a closed manifold). Fold passes (glass, mirrors)
// refine cells and so keep more than this: simplify estimates again after
// each and stops refining where the limit would be passed.
SimplifyEstimate estimate_simplify(const OctreeStore& store, const Cut& cut);

struct SimplifyResult {
  IndexedMesh mesh;
  CollapseStats stats;
  uint64_t cut_cells = 0;
  uint64_t cut_cells_missing = 0;     // cut cells the store has no node for (ignored)
  uint64_t clamped_representatives = 0;
  uint64_t fold_passes = 0;           // extra passes over the pages to undo folds
  uint64_t fold_cells_refined = 0;    // cut cells replaced by their children (or kept) for a fold
  uint64_t fold_passes_undone = 0;    // refinements taken back: they left no fewer triangles turned over
  bool folds_stopped_by_memory = false;  // a fold pass's refinement was left out: it would not fit memory_limit
  uint64_t pages_read = 0;
  uint64_t pages_skipped = 0;  // page visits spared: the page lay inside one collapsed cell
  double seconds = 0;          // all of simplify(), of which:
  double fold_seconds = 0;     //   the fold passes' scans (not the builds)
  double finish_seconds = 0;   //   CollapseBuilder::finish (duplicates, normals, output order)
};

// Streams the store's pages and collapses the cut. Vertex clustering can
// turn a triangle over where a large collapsed cell meets finer geometry: its
// representative lands on the far side of a thin triangle's other corners.
// A turned-over triangle faces against its input and shows as a sparkle
// through glass or a dark seam on a mirror, so each such cell is replaced by
// its children in the store (a finest cell is not collapsed), at most
// config.fold_passes times. The cut as given is built first, which finds the
// cells that fold; each refinement is then checked by scans, which build
// nothing, of the pages near the cells it changed. A refinement after which
// the check finds no fewer triangles turned over is taken back, and the
// passes stop (SimplifyResult::fold_passes_undone): refining can fold the
// children against their new neighbours, and a folding finest cell is kept
// whole. If a refinement is kept, one more pass over the pages builds the
// refined cut's mesh; if none is, the first build is the mesh. Fails before reading any page if the
// estimate exceeds config.memory_limit, and during the building pass if the
// mesh under construction does.
StatusOr<SimplifyResult> simplify(const OctreeStore& store, const Cut& cut, const SimplifyConfig& config = {});

// Why a simplified mesh came out empty, for messages that name the input:
// every input triangle degenerate (when the cut collapses nothing), or every
// triangle collapsed by the cut (the whole mesh is finer than the view
// resolves). Empty string if `result` has triangles.
std::string why_simplified_mesh_is_empty(const SimplifyResult& result, const Cut& cut);

}  // namespace raylod
