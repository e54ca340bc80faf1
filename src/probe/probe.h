// The probe (method steps A2-A4): trace test rays with Igehy ray
// differentials through the scene against the full-resolution triangles in
// the stores, and mark the octree cells that no ray can resolve.
//
// Test rays: N rays through uniformly random positions inside uniformly
// random pixels (seeded per ray, so the result does not depend on threads).
// Reflection rays are traced only from mirror and glass surfaces, refraction
// rays only from glass (Material::reflects / refracts), up to scene.max_depth
// bounces; glass spawns both, as a Whitted renderer does; total internal
// reflection is a reflection. A ray is followed only if the renderer traces
// it: its throughput (the path's Fresnel terms, mirror reflectances and
// tints, as render/integrator.cpp weighs it) is at least kMinThroughput. The ground plane is traced (it occludes and
// may be a mirror) but never marked: it is not simplified.
//
// At every hit the footprint f = ||dP|| (METHOD.md eq. 2, ray_differential.h)
// is measured in the store's (object) coordinates and attached to the hit
// triangle (A3); the triangle's corners lie in the cells whose collapse
// would move them, so each hit constrains the cells of its three corners.
// A cell may be collapsed iff its diagonal < K * need(cell), where need is
// the smallest footprint any ray may have inside it (A4, "finest need wins");
// the cut is the set of largest such cells (levels <= quadric_depth).
//
// need() of a finest cell (level quadric_depth):
//   - with hits: the smallest measured footprint among them;
//   - without hits (most cells: a few thousand rays miss most of them), the
//     policy below. need() of a coarser cell is the minimum over its children,
//     so one finely needed child keeps all its ancestors uncollapsed.
//
// Policy for cells no test ray reached. A visible cell must not be collapsed
// more coarsely than the view can afford, and we do not know which unreached
// cells are visible, so every cell a ray path could reach gets a LOWER BOUND
// of its footprint, from the pinhole model: a pixel's beam from the eye has
// width (distance * pixel angle) and its footprint on any surface is at least
// that (a slanted surface only stretches it by 1/cos). With
//   d = distance from the eye to the cell's box (0 if the eye is inside),
//   a = the smallest angle between neighbouring pixels' rays in the image
//       (at its corners); in a scene without mirrors or glass, where a cell
//       is seen directly only, the smallest over the pixels its bounding
//       ball projects to (geometry/pinhole_camera.h), which in a wide view
//       is far larger near the centre than at the corners,
//   m = min(1, the calibration_quantile of f / (a_ray * path length) over
//       all measured secondary hits),
// the estimate is m * a * d. m < 1 only where measured reflection/refraction
// paths focus (a concave mirror or glass lens magnifies the view); then
// unreached cells are assumed to be as magnified as the most magnified
// measured paths. Secondary paths are never shorter than d, so the bound
// also holds for cells reached through mirrors and glass.
// Two criteria decide which cells collapse (ProbeConfig::criterion):
//   - diagonal (the paper's): diagonal(cell) < K * need(cell);
//   - deviation (the default): diagonal(cell) < K * need(cell) AND the
//     surface deviation the collapse causes (geometry/collapse_deviation.h:
//     chord error from the cell's quadric, 0 on flat regions, creases and
//     corners; and the largest RMS distance from the representative of the
//     planes of any node up to kDescendantLevels = 4 levels below the cell,
//     descendant_deviation, which sees small features that the area
//     weighting of the cell's own quadric lets large triangles outweigh) is
//     at most tolerance_px * need(cell), i.e. the collapsed
//     surface stays within tolerance_px pixels of the input wherever a ray
//     sees it, silhouettes included. These tests (and the rim, fold and
//     far-end tests below) take each hit's shift footprint
//     (ProbeHit::shift_footprint: the beam's width across the ray over the
//     sine of the incidence angle, at most ||dP||), not ||dP||: near a
//     silhouette ||dP|| is drawn out along the surface many times over what
//     the pixel resolves, and collapses it allowed moved the outline of a
//     close-up of the pump cover's wall by most of a pixel, pixel after
//     pixel along it (58.55 dB against a 60.88 dB floor; 63.82 dB with the
//     shift footprint, at 36,928 triangles instead of 36,396). The
//     unreached cells' estimate below bounds a beam's width already; AND,
//     on mirror and glass objects, the
//     normal_deviation is at most angle_tolerance_px times the tilt the
//     cell's hits tolerate (ProbeHit::tilt): a tilt t turns a reflected ray
//     by 2t and a transmitted one by Refraction::tilt_gain * t, which shows
//     in the image as that turn over the ray's angular spread ||dD|| (in
//     pixels), the spread taken as the smallest along the rest of the path
//     (a later surface may focus the beam while the error stays); only the
//     rays the renderer traces count (throughput at least kMinThroughput,
//     within max_depth), and the test rays follow no others; the smallest
//     over the hits in the cell, else for unreached cells
//     unreached_angle_allowance times the larger of
//     a_min * m / 2 (a flat mirror's turn) and c * kappa * f: on a curved
//     surface the beam leaving it spreads with the curvature times the
//     beam's width (a convex mirror of curvature kappa widens a beam of
//     width w by about 2 kappa w), so a tilt there shows less. kappa is the
//     finest cell's normal spread over its side (normal_spread_angle; 0
//     where it holds one vertex of a mesh with normals, which then keeps
//     the flat bound: read one or two levels up, kappa let the 2M mirror
//     teapot fall below its noise floor, README), f the view's footprint
//     estimate for the unreached cell (before the shadow bound), and c,
//     per view and store, the
//     calibration_quantile of tilt / (kappa f) over the measured finest
//     cells with curvature (at least kMinCurvatureSamples of them, else c =
//     0), as m is calibrated from the measured footprints: where measured
//     paths focus (concave mirrors, lenses) c is small, and across creases
//     (normals spread without curvature: CAD parts, c about 1e-5 to 3e-4)
//     it is tiny, so the flat bound stands (crease cells on mirrors and
//     glass keep the rim's rule, below). On the glass scene's teapot c =
//     0.16, and the finest cells kept for the normal bound fall from 36,624
//     to 105. Like m, c is a statistic of the measured paths: a concave
//     region no test ray reached on an otherwise convex object takes the
//     convex parts' c (a region large enough in the image to matter is hit
//     by some of the test rays). The cut records the least c over the
//     views (counter curvature_factor_ppm, printed by `raylod probe`).
//     ProbeConfig::curved_unreached_tilt = false keeps the flat bound
//     alone; AND, for a cell holding an
//     open boundary vertex (OctreeStore::touches_boundary: a hole's rim, the
//     edge of an open surface), which a quadric does not see and the
//     representative may pull anywhere in the cell, diagonal(cell) is at
//     most tolerance_px * need(cell); the same for a cell holding a fold
//     (collapse_deviation.h: a knife edge or a plate thinner than the cell,
//     opposite-facing sheets its quadric takes for one plane); AND, for a
//     cell holding a corner of a triangle some ray hit more than
//     kFarReach = 2 cell diagonals from that corner, b * diagonal(cell) is
//     at most tolerance_px * need(cell), with b the corner's largest
//     barycentric weight at such hits, unless the cell is flat (b times
//     collapse_deviation.h's far_normal at most 1e-3 rad): the triangle
//     carries the representative's normal, the mean of the cell's, along
//     its whole length, weighted by b at the hit, so a curved cell off the
//     view (the fillet at the end of a cylinder's long strips) shades every
//     visible strip that ends in it. A curved cell's far_normal is about
//     its curvature times its side, as a near hit's normal error is the
//     curvature times the position error the tolerance allows: the bound
//     holds the far end to what the near one is held to. K then only caps
//     how large a cell may get relative to the footprint.
//
// Unseen cells. Cells that no ray path can reach -- in a scene with no
// mirror or glass (so no secondary ray can turn towards them), those outside
// the view frustum, and on a closed mesh (no open boundary) whose normals
// point outwards those facing away from the eye -- only matter for shadows.
// A cell faces away if, from every point of its box, at most
// kUnseenFrontShare of its triangles' area may face the eye: with x = n . u
// (u the unit direction from the eye to the cell's centre, n the area's
// normals, their mean resultant length R from the node's sums), x exceeds
// 2 sin(beta / 2) (beta: the box's angular radius from the eye, how far u
// turns over the box) on all but a share Var / (Var + (E x - 2 sin(beta /
// 2))^2) of the area (Cantelli's inequality, Var at most 1 - R^2). Front
// faces of a closed surface hide its back faces, so a view sees none of
// them; the mesh is taken to be outward-facing only if none of the view's
// camera rays met a back face (ProbeHit::back_facing) and some met the
// store. With lights, an unseen cell whose shadow from some light may reach
// the view (its box swept away from the light is not wholly outside one of
// the frustum's planes: a separating plane) and that may lie between the
// light and a surface the camera sees gets shadow_factor times the estimate
// (its silhouette keeps shadows within a few pixels); one whose shadows
// cannot reach the view or fall on nothing it sees, or any unseen cell
// without lights, is collapsed hard (need = infinity) but for the ground's
// shadows below. What the camera sees is where the view's test rays met a
// mesh or the ground, each hit standing for the surface out to twice the
// mean spacing of the test rays in the image (its footprint times that many
// pixels): a cell matters for a light if some point of it is nearer the
// light than such a surface and in line with it (ShadowReceivers,
// cell_visibility.h: per light, the receivers binned on a grid across its
// rays). The crank arm's eight random close-ups, lit by a key and a fill
// light whose shadows reach every part in view, went from 6.5x-10.0x to
// 7.2x-15.3x this way, each still above its noise floor (by 1.5 to 14.4 dB;
// two lost 3.6 and 3.9 dB of their 13 to 18 dB margins, on a shadow's
// edge), the pump cover's eight from 10.5x-32.2x to 10.7x-45.8x
// (tools/MEASUREMENTS.md, "Shadows on what the camera sees").
// (ProbeConfig::unseen_cells = false: only cells outside the view are
// unseen, and they take shadow_factor wherever there are lights.)
// Shadows on the ground, for every cell, reached or not: a light casts the
// cell's shadow onto the ground plane (its corners moved along the light to
// y = height). Where that shadow lies in a view, a deviation d at the cell
// moves the shadow's edge on the ground by up to d / sin(alpha) (alpha: the
// light's elevation above the ground), times s_r / s_o for a point light
// (how much farther from the light the shadow is than the cell), so need()
// is at most m * a * (distance from the eye to the shadow) * sin(alpha) *
// s_o / s_r (a over the shadow's pixels without mirrors or glass, as
// above). This binds cells outside the view whose shadows are seen, and
// visible cells under a low light, whose shadows stretch. Only where the
// view's test rays met the ground (directly or through mirrors and glass),
// on a grid over their ground hits (about one a cell, at most 128 x 128), in
// or next to a cell one of them hit: ground the object hides from the
// camera shows no shadow. And only where the light reaches that ground: each
// ground hit traces a shadow ray to each light against the full meshes, as
// the renderer does (GroundHit::lit), and the grid marks, per light, the
// cells in or next to one of the hits it lights; a cell whose shadow falls
// only where every hit around lies in the shadow of other parts moves no
// shadow's edge a test ray saw (ProbeConfig::unseen_cells; the close-ups of
// the crank arm, whose ground is mostly its own shadow, went from 3.6x to
// 7.8x to 6.5x to 10.0x, README "Close-ups at random triangles"). Not for a
// mirror or glass ground (it shows no shadows), nor for shadows on other
// objects.
// A coarser cell is checked as a whole where some cell inside it took the
// unseen cells' bound (need() alone is the minimum over its children): its
// collapse puts a vertex anywhere in its own box, which may be in view,
// facing the eye or casting a shadow, so the cell's own box takes the
// policy too (unseen, facing away or neither, and its ground shadow).
// Hits whose differentials were dropped (grazing, critical angle, degenerate
// normals; ray_differential.h) get the same estimate along their own path:
// m * a_ray * path length.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/status.h"
#include "geometry/collapse_deviation.h"
#include "probe/page_cache.h"
#include "geometry/ray_differential.h"
#include "scene/scene.h"
#include "streaming/cut_file.h"
#include "streaming/octree_store.h"

namespace raylod {

enum class CutCriterion { Deviation, Diagonal };
const char* to_string(CutCriterion c);
// Parses "deviation" or "diagonal".
StatusOr<CutCriterion> parse_cut_criterion(const std::string& name);

// Which stores' cuts are graded (cut_balance.h: no cut cell beside one two
// or more levels coarser): those of objects on mirrors and glass, where a
// triangle's interpolated normal is what the image shows (default); every
// store's; or none.
enum class CutBalance { Specular, All, Off };
const char* to_string(CutBalance b);
// Parses "specular", "all" or "off".
StatusOr<CutBalance> parse_cut_balance(const std::string& name);

// Defaults shared by `raylod probe`, `run` and `report` (README, "What
// accuracy costs", for how they were chosen).
// Measured with tools/accuracy.sh and raylod report on the 10M teapot, the
// OpenCASCADE parts (whole views and close-ups), the bunny scan and both
// glass scenes: with the deviation criterion at 0.5 px every one stays at or
// above its noise floor at K = 64 (the closest, the pump cover's whole view,
// by 0.4 dB when this was chosen, 1.6 dB on 2026-11-29), and the close-ups
// need it: the pump cover's goes from 8.9x at K = 32 to 18.3x. The deviation
// bound decides; K only caps what a quadric cannot see (open rims). The
// diagonal criterion alone needs a small K (its cells grow with the footprint
// whatever their curvature).
inline constexpr double kDefaultFootprintScale = 64.0;
inline constexpr double kDefaultDiagonalFootprintScale = 10.0;
inline constexpr double kDefaultTolerancePx = 0.5;
// Outlines. Where a surface's outline runs against what lies behind it, a
// shift of the outline by s pixels flips about s of each edge pixel's
// samples between the surface and its background, where the renderer's own
// noise there is the variance of a pixel's coverage over its samples: at a
// few samples per pixel about a third of a pixel of shift, on average along
// the outline, costs as much as the noise (an estimate: the tests below
// decide). The deviation tests bound the largest shift, which the average
// sits well under on curved surfaces but not everywhere: a close-up of the
// pump cover's rounded edge against a dark wall (README, "Close-ups at
// random triangles", p_2) stayed 1.21 dB below its floor at 0.5 px, every
// difference on the outline. So in the finest cells an outline may run
// through in a view -- the cap of the cell's normals (normal_spread_angle
// around their mean) reaches across the direction from the eye, |mean . d|
// <= sin(spread) -- the tests take outline_tolerance times the tolerance,
// and so does every coarser cell holding one (through the min over its
// subtree). Outlines are lines in the image, so this costs few triangles
// (1 to 11% on the CAD close-ups, 3% on the default view). The direction is
// the camera's: outlines seen only in a mirror or through glass are not
// singled out (their cells keep the normal bound, above). Tested on the
// teapot against a brute-force search of the store's finest nodes
// (ProbeDeviation.OutlinesTakeAFractionOfTheTolerance).
inline constexpr double kDefaultOutlineTolerance = 0.5;
// Unseen cells (above): the largest share of a cell's triangle area that may
// face the eye in a cell taken to face away from it.
inline constexpr double kUnseenFrontShare = 0.01;
// On mirror and glass objects a collapse may turn a ray leaving the surface
// by at most this many pixels' angular spread ||dD|| (ProbeHit::tilt).
// Measured on data/glass_scene.json and the paper bottle (README, "Accuracy
// across meshes"): at 0.5 (the position tolerance, which this bound used
// before) they stay 4.8 and 6.4 dB above their noise floors (1.8x and 3.1x
// fewer triangles); at 1, 2.7 and 4.1 dB (2.2x and 4.2x); at 2, 0.7 and
// 1.8 dB; at 4 both fall below. 1 was the largest that kept both more
// than 2.5 dB above. Since representatives on mirrors and glass take the
// input's normal where it has one (SimplifyConfig::exact_normals): at 1,
// 4.2 and 6.5 dB above (2.1x and 4.2x); at 2, 2.6 and 3.6 dB (2.6x and
// 6.5x); at 4, 1.3 and 0.9 dB (3.3x and 9.9x). 2 is now the largest that
// keeps both more than 2.5 dB above; checked on two scenes it was not
// chosen on (README, "Exact normals on mirrors and glass"). With the cut
// graded on mirrors and glass (CutBalance): at 2, 3.1 and 3.8 dB (2.6x and
// 6.3x); at 4, 1.7 and 4.1 dB (3.3x and 9.5x): still 2 by that rule.
// 2 held for every cell until 2026-11-28, when close-ups of CAD parts as
// mirrors at random triangles (README, "Close-ups at random triangles")
// fell 1.54 and 1.69 dB below their floors at 2. Their errors come from cells
// test rays hit: held at 1 there (and at 2 where no ray hit) both are
// above (42.87 and 49.47 dB, floors 40.77 and 48.76, at 1.65x and 1.99x
// instead of 1.71x and 1.99x), while holding unreached cells to 1 as well
// fixed neither (40.69 and 47.31 dB) and cost the glass scene 25% of its
// reduction (4.86x -> 3.64x). The glass scenes are decided by unreached
// cells (143,306 of the teapot's 151,581 marked cells): with measured cells
// at 1 they keep 4.86x and 6.32x (6.53x before) at 34.74 and 48.24 dB.
// So the tolerance is 1 pixel angle for measured cells, and cells no test
// ray reached keep the bound they had, kDefaultUnreachedAngleAllowance
// times it: theirs is already a lower bound on the spread of any ray there
// (the smallest pixel angle of the frame, the calibration quantile of the
// measured cells' tilts), where a measured cell's is the spread its rays met.
inline constexpr double kDefaultAngleTolerancePx = 1.0;
inline constexpr double kDefaultUnreachedAngleAllowance = 2.0;
// Both defaults were chosen on scenes rendered at 2 to 4 samples per pixel.
// More samples lower the renderer's noise, and with it the floor under which
// a collapse's error hides: above 4 spp the default tolerances scale by
// (4 / spp)^0.75. Measured (README, "Accuracy across meshes"): at 64 spp the
// glossy teapot, the crank arm and the bunny fell 7.5 to 15 dB below their
// floors at 0.5 px; with the scaled tolerance every one is at or above. An
// explicit --tolerance or --angle-tolerance is taken as given.
double default_tolerance_scale(int spp);
inline double default_tolerance_px(int spp) { return kDefaultTolerancePx * default_tolerance_scale(spp); }
inline double default_angle_tolerance_px(int spp) {
  return kDefaultAngleTolerancePx * default_tolerance_scale(spp);
}

// What cut selections keep of a store between them (a view sequence's
// views, RunSession::selection_cache): each level's node codes in a compact array
// (the loops over every node read 8 bytes a node rather than the 144 of its
// NodeRecord), and the collapse deviations (geometry/collapse_deviation.h)
// of the nodes a selection tested, computed the first time one does.
// Neither depends on the view, K, the tolerances or the criterion.
// A selection tests few of a store's nodes (those not inside a cell already
// collapsed, whose cell is small enough for K), so the deviations are kept
// densely, in the order they were first computed, and each node holds only
// a 4-byte slot into them: 12 bytes a node with its code, plus the
// deviations kept, where a deviation for every node (56 bytes) made each
// process write 214 MB for the 10M-triangle teapot's store before its first
// view.
// Stores are told apart by their fingerprint and node counts (a store
// rebuilt from the same mesh with the same options has the same nodes).
// Selections that share one run one at a time.
class SelectionCache {
 public:
  struct Store {
    std::vector<std::vector<uint64_t>> codes;  // per level, in node order
    // Per level, per node: 1 + the index of its deviation in `computed`, or 0
    // (not computed yet).
    std::vector<std::vector<uint32_t>> slot;
    std::vector<CollapseDeviation> computed;
    // The most deviations kept (nodes / kComputedShare): a selection that
    // starts with more clears them first, so the memory stays bounded.
    size_t max_computed = 0;
    const CollapseDeviation& deviation(int level, size_t i) const { return computed[slot[size_t(level)][i] - 1]; }
    // Per finest node, what the outline test reads (probe.h, "Outlines"):
    // the unit mean of its normals (0 if they cancel) and the sine of their
    // spread (1 from a right angle on), 16 bytes where the test otherwise
    // reads the node's 144 for every view.
    struct NormalCone {
      float mean[3] = {0, 0, 0};
      float reach = 1;
    };
    std::vector<NormalCone> finest_cones;
  };
  static constexpr size_t kComputedShare = 4;
  // The most deviations kept for a store of `nodes` nodes.
  static uint64_t most_computed(uint64_t nodes) { return std::max<uint64_t>(nodes / kComputedShare, 1); }
  Store& of(const OctreeStore& store);
  // What a cache for these stores holds at most: 12 bytes a node (a code and
  // a slot), 16 more for each finest node (its normal cone), and a deviation
  // for every kComputedShare-th.
  static uint64_t bytes_for(std::span<const OctreeStore* const> stores);
  // A cache's entry for one selection alone (none shared).
  static Store make_entry(const OctreeStore& store);

 private:
  std::map<std::pair<uint64_t, std::vector<uint64_t>>, Store> by_store_;
};

struct ProbeConfig {
  uint64_t rays = 5000;            // test rays (the paper uses 5,000)
  uint64_t seed = 1;
  CutCriterion criterion = CutCriterion::Deviation;
  double footprint_scale = kDefaultFootprintScale;  // K: collapse cells with diagonal < K * footprint
  double tolerance_px = kDefaultTolerancePx;        // deviation criterion: surface deviation, in pixels
  double angle_tolerance_px = kDefaultAngleTolerancePx;  // and a mirror or glass ray's turn, in pixel angles
  // The fraction of tolerance_px the deviation tests allow where an outline
  // may run (kDefaultOutlineTolerance), in (0, 1]; 1: no difference.
  double outline_tolerance = kDefaultOutlineTolerance;
  CutBalance balance = CutBalance::Specular;             // which cuts are graded
  uint64_t cache_bytes = uint64_t(256) << 20;  // page cache budget; 0 = no limit
  // A page cache that outlives the trace (a view sequence's, so that a view
  // reuses the pages the views before it loaded), resized to cache_bytes
  // before tracing; none = a cache of the trace's own. The trace's cache
  // counters are then this trace's share. It never changes the result.
  PageCache* pages = nullptr;
  // What earlier selections kept of the stores (SelectionCache); none = the
  // selection makes its own. It never changes the result.
  SelectionCache* selection_cache = nullptr;
  DifferentialLimits limits;
  double calibration_quantile = 0.02;  // of the secondary hits' magnification (policy above)
  // Unreached curved mirror and glass cells take the tilt c kappa f (policy
  // above); false: the flat mirror's bound alone.
  bool curved_unreached_tilt = true;
  // Unreached mirror and glass cells are held to this many times
  // angle_tolerance_px (kDefaultUnreachedAngleAllowance).
  double unreached_angle_allowance = kDefaultUnreachedAngleAllowance;
  double shadow_factor = 4.0;          // unreachable cells in scenes with lights
  // Cells the camera cannot see ("Unseen cells", above): back-facing cells of
  // a closed mesh whose normals point outwards, and cells outside the view;
  // where no light's shadow from them can fall in the view either, they
  // collapse as far as the ground's shadows allow. false: only cells outside
  // the view count, and they keep shadow_factor wherever there are lights
  // (the rule before 2026-11-29).
  bool unseen_cells = true;
  // With unseen_cells: an unseen cell keeps shadow_factor only where it may
  // lie between a light and a surface the view's test rays met (the
  // receivers of "Unseen cells", above). false: wherever its shadow may
  // fall in the view's frustum (the rule before 2026-11-30).
  bool shadow_receivers = true;
  bool progress = false;               // progress bar on stderr
  // Trace only test rays [first_ray, end_ray) of the `rays` (one rank's share
  // under mpirun; merge_traces joins the shares); end_ray 0 = all of them.
  uint64_t first_ray = 0, end_ray = 0;
};

// A store to probe, and where it lives (recorded in the cut).
struct ProbeStore {
  const OctreeStore* store = nullptr;
  std::filesystem::path path;
};

// One scene object: its store (index into the stores span), its transform
// from mesh coordinates to world (the probe composes it with the store's
// mesh origin, StoreHeader::mesh_origin), its material (index into
// scene.materials).
struct ProbeObject {
  size_t store = 0;
  glm::dmat4 transform{1.0};
  int material = 0;
};

struct ProbeResult {
  std::vector<Cut> cuts;  // one per store, in the order of the stores span
  // Global counters: rays_primary, rays_reflection, rays_refraction,
  // total_internal_reflections, hits, hits_ground, misses,
  // differentials_dropped, page_visits, triangle_tests, pages_read,
  // bytes_read, cache_hits, cache_misses, cache_evictions, cache_peak_bytes.
  std::map<std::string, uint64_t> counters;
  double magnification = 1;  // m of the policy
  double trace_seconds = 0, cut_seconds = 0;
};

// One mesh hit of a test ray: what selecting a cut needs of it.
struct ProbeHit {
  uint32_t object = 0;             // index into the objects span
  std::array<Vec3d, 3> corners{};  // hit triangle's corners, store coordinates
  double b1 = 0, b2 = 0;            // the hit point's barycentric coordinates on corners 1 and 2
  double footprint = 0;            // ||dP|| in store units; if estimated, without the factor m
  // The footprint across the ray: dP with its part along the ray removed
  // (store units; if estimated, the footprint). What one pixel resolves
  // there, which at grazing incidence the footprint on the surface, drawn
  // out along the ray, overstates many times (the cut's min_footprint, and
  // so the Draco quantisation of the simplified mesh, take this).
  double width = 0;
  // What a deviation along the surface's normal is compared with (the
  // deviation criterion's tests, above): a surface moved by d along its
  // normal moves in the image by d sin(theta) across the ray (theta: the
  // incidence angle), at a silhouette by d itself, where the footprint,
  // stretched by 1 / cos(theta) along the surface, would let it move many
  // pixels. So width / sin(theta), but at most the footprint (below 45
  // degrees, where the collapse's normal error, not its shift, is what
  // shows, and the tolerances were chosen against the footprint). Store
  // units; if estimated, the footprint.
  double shift_footprint = 0;
  double ratio = -1;               // f / (a_ray * path length) of a measured secondary hit
  // Mirror/glass hit: the largest normal tilt (radians) that turns no ray
  // leaving it by more than one pixel's spread anywhere along its path:
  // min over its rays b of s_b / gain_b, where gain_b is how far b turns
  // per radian of tilt (2 reflected, Refraction::tilt_gain transmitted) and
  // s_b the smallest ||dD|| over b and every ray after it. Rays the renderer
  // does not trace (throughput below kMinThroughput, beyond max_depth) do
  // not count. Infinite on other materials and where no ray leaves.
  double tilt = std::numeric_limits<double>::infinity();
  int32_t parent = -1;             // index in ProbeTrace::hits of the hit whose ray made this one, or -1
  bool estimated = false;          // differentials dropped: footprint from the beam
  // The ray met the side of the triangle its normal faces away from (the
  // geometric normal, oriented as the shading normal). A camera ray that
  // does tells the probe that this view sees inside its object or that its
  // normals point inwards ("Unseen cells", above).
  bool back_facing = false;
};

// Where a test ray's path met the ground plane (world), and which of the
// scene's lights reach that point past the meshes (bit l for lights[l], as
// the renderer's shadow rays find it against the full meshes; lights from
// the 33rd on are taken to reach every point): the ground shadows' bound
// looks only where a cell's shadow may border lit ground ("Shadows on the
// ground", above).
struct GroundHit {
  Vec3d point{0};
  uint32_t lit = ~0u;
};

// The traced test rays (A2, A3): independent of K, the tolerance and the
// criterion, so sweeps and memory coarsening select cuts from one trace.
struct ProbeTrace {
  std::vector<ProbeHit> hits;      // every mesh hit, by ray index, then along the path
  std::vector<GroundHit> ground_hits;  // where paths met the ground plane, in the same order
  std::map<std::string, uint64_t> counters;
  double magnification = 1;        // m of the policy
  double trace_seconds = 0;
  uint64_t rays = 0, seed = 0;
};

// Traces the test rays. Fails with a clear message if a page of a store
// cannot be read (a corrupt store is reported, never traced through).
StatusOr<ProbeTrace> trace_probe(const Scene& scene, std::span<const ProbeStore> stores,
                                 std::span<const ProbeObject> objects, const ProbeConfig& config);
// The shares of one probe traced separately (ProbeConfig::first_ray/end_ray),
// in ray order, joined into the trace of all the rays: the same hits in the
// same order, the same magnification and the same ray counters as tracing
// them at once (each test ray's outcome depends only on its index and the
// seed). Page-cache counters add up (each share read its own pages).
ProbeTrace merge_traces(std::vector<ProbeTrace> shares, const ProbeConfig& config);

// The page-cache counters of a trace (pages_read, bytes_read, cache_*): how
// the pages were read, not what the rays found. They are left out of the
// cuts, so a cut's bytes depend only on the test rays.
bool is_page_cache_counter(const std::string& name);

// Selects one cut per store from a trace (A4) by config's criterion, K and
// tolerance (config's rays and seed are not used: the trace's are recorded).
StatusOr<ProbeResult> select_cuts(const ProbeTrace& trace, const Scene& scene, std::span<const ProbeStore> stores,
                                  std::span<const ProbeObject> objects, const ProbeConfig& config);

// One view of several (`raylod run --shared-cut`): its traced test rays and
// the camera they were traced from (trace_probe with scene.camera = camera).
struct ProbeView {
  const ProbeTrace* trace = nullptr;
  Camera camera;
};

// One cut per store for all the views at once: a cell's need is the finest
// over the views, each view contributing what select_cuts would use for it
// alone (its measured footprints, or for a cell its rays did not reach, the
// policy's estimate from its own eye, frustum and magnification; likewise the
// tilt allowance on mirrors and glass). Since every test is monotone in the
// need, every cell the shared cut collapses is also collapsed (itself or
// through an ancestor) by each view's own cut. The result does not depend on
// the order of the views or on threads. With one view it is select_cuts
// exactly (same cells and key).
StatusOr<ProbeResult> select_shared_cuts(std::span<const ProbeView> views, const Scene& scene,
                                         std::span<const ProbeStore> stores, std::span<const ProbeObject> objects,
                                         const ProbeConfig& config);

// select_shared_cuts in two parts, for selecting several cuts from the same
// traces (the memory limit's coarsening, K and tolerance sweeps): make()
// computes what does not depend on the criterion, K or the tolerances
// (every cell's need and tilt allowance from the traces and the unreached-cell
// policy), and each select() decides the cut for one configuration, the
// nodes' collapse deviations computed once and kept for the next. select(c)
// gives exactly select_shared_cuts(views, ..., c) (the same cells, key and
// counters), for any c with make()'s shadow_factor, curved_unreached_tilt
// and calibration_quantile (select() refuses others). The views' traces, the
// scene, the stores and the objects must outlive the selection.
class CutSelection {
 public:
  static StatusOr<CutSelection> make(std::span<const ProbeView> views, const Scene& scene,
                                     std::span<const ProbeStore> stores, std::span<const ProbeObject> objects,
                                     const ProbeConfig& config);
  StatusOr<ProbeResult> select(const ProbeConfig& config);

  CutSelection();
  ~CutSelection();
  CutSelection(CutSelection&&) noexcept;
  CutSelection& operator=(CutSelection&&) noexcept;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// Both: trace, then select.
StatusOr<ProbeResult> run_probe(const Scene& scene, std::span<const ProbeStore> stores,
                                std::span<const ProbeObject> objects, const ProbeConfig& config);

// Fingerprint of a store's content and layout (what a cut is valid for).
uint64_t store_fingerprint(const OctreeStore& store);
// What the rules that select a cut are: raised whenever they change what
// cut the same inputs give, so that cut files an earlier raylod left beside
// the stores are not reused for them. (Simplified meshes are cached by their
// cut's cells and their normal rule, SimplifiedCache::key_for: a change to
// the collapse alone must change that rule.) 1: the rules before the
// version was kept; 2: the deviation tests take the shift footprint
// (ProbeHit::shift_footprint), 2026-11-28; 3: cells the camera cannot see
// and no shadow brings into view collapse (ProbeConfig::unseen_cells),
// 2026-11-29; 4: their shadows count only where they may fall on a surface
// the test rays met (ProbeConfig::shadow_receivers), 2026-11-30.
inline constexpr uint32_t kCutRulesVersion = 4;

// The cut's key: a hash of the store fingerprint, the camera, the scene's
// specular set-up (materials, max depth, ground), the object's placements,
// the probe options and kCutRulesVersion, as 16 hex digits.
std::string probe_key(const Scene& scene, const OctreeStore& store, std::span<const ProbeObject> objects,
                      size_t store_index, const ProbeConfig& config);

}  // namespace raylod
