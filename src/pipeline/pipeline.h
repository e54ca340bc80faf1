// The whole method as `raylod run` performs it: build (or reuse) the octree
// store of every mesh in the scene, probe with test rays, simplify the cut
// (or reuse a cached simplified mesh that is fine enough), and render the
// simplified meshes. Also the building blocks `raylod probe` and
// `raylod report` share.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "core/memory_budget.h"
#include "core/status.h"
#include "core/system.h"
#include "pipeline/simplified_cache.h"
#include "probe/probe.h"
#include "render/renderer.h"
#include "scene/scene.h"
#include "simplify/collapse.h"
#include "streaming/draco_io.h"
#include "streaming/octree_store.h"

namespace raylod {

using LogFn = std::function<void(const std::string&)>;

// Helpers the pipeline's stages share: seconds since t0 (steady clock), and
// a line to the log if there is one.
double seconds_since(std::chrono::steady_clock::time_point t0);
void say(const LogFn& log, const std::string& text);

// The stores of a scene's meshes, opened, with the objects that use them.
struct SceneStores {
  std::vector<std::filesystem::path> meshes;  // one per distinct mesh file
  std::vector<std::filesystem::path> store_paths;
  std::vector<std::shared_ptr<OctreeStore>> stores;
  std::vector<ProbeStore> probe_stores;
  std::vector<ProbeObject> objects;           // one per scene object
  std::vector<BuildReport> builds;            // one per store (reused or built)
  // One per store: the file opened (inode, size, modification time, taken
  // before opening it), which tells a rebuilt store from the one it replaced.
  std::vector<std::string> store_files;
  uint64_t triangles = 0;                     // all stores
  double seconds = 0;
};

// Resolves generated meshes (into cache_dir), applies mesh_override to the
// first object, and builds every store that is missing or stale (saying so
// through log), then opens them. With check_stores false the stores are
// opened as they are, neither checked against their meshes (the content
// hash reads the whole mesh) nor built: for the ranks of an MPI job after
// rank 0 has checked them (open_run_session).
StatusOr<SceneStores> prepare_scene_stores(Scene& scene, const std::optional<std::filesystem::path>& mesh_override,
                                           const StoreOptions& store_options, const std::filesystem::path& cache_dir,
                                           const LogFn& log, bool check_stores = true);
// Refuses an object whose transform puts it beyond the float range (naming
// the scene and objects[i]); adds a warning for one outside the sizes
// single-precision rays render faithfully (size_problem). run and probe
// call it once the stores are open.
Status check_object_placements(const Scene& scene, const SceneStores& stores, std::vector<std::string>& warnings);

struct RunOptions {
  std::optional<std::filesystem::path> mesh_override;
  uint64_t memory_limit = 0;          // bytes for the whole run (memory_budget.h); 0 = no limit
  uint64_t rays = 5000;
  double footprint_scale = kDefaultFootprintScale;  // K (see README, "What accuracy costs": why this default)
  CutCriterion criterion = CutCriterion::Deviation;
  double tolerance_px = kDefaultTolerancePx;        // deviation criterion (probe.h)
  double angle_tolerance_px = kDefaultAngleTolerancePx;  // its mirror/glass normal bound (probe.h)
  double outline_tolerance = kDefaultOutlineTolerance;   // its fraction where an outline may run (probe.h)
  // Unreached mirror and glass cells' bound, times angle_tolerance_px (probe.h).
  double unreached_angle_allowance = kDefaultUnreachedAngleAllowance;
  CutBalance balance = CutBalance::Specular;             // which cuts are graded (probe.h)
  bool unseen_cells = true;  // cells the camera cannot see collapse as their shadows allow (probe.h)
  bool shadow_receivers = true;  // ... as their shadows on what the camera sees allow (ProbeConfig)
  std::filesystem::path cache_dir;    // empty = default_cache_dir()
  uint64_t cache_limit = uint64_t(4) << 30;
  bool use_cache = true;
  bool progress = true;
  int spp = 0;                        // 0 = the scene's
  int max_coarsening_steps = 12;      // K doubles per step when over memory
  std::filesystem::path export_mesh;  // also write the simplified meshes here as .glb (empty: no)
  // The render's color only as 8-bit sRGB (RenderOptions::srgb_color), for
  // an 8-bit output that nothing compares: the result's render.srgb, or the
  // views' images, instead of linear colors.
  bool srgb_color = false;
  // An image the run will write: its writer is checked once the stores are
  // ready (the image codec loads meanwhile, start_loading_image_codec), on
  // every rank, before any probe. Empty: not checked here.
  std::filesystem::path output_image;
};

struct StageTimes {
  double build = 0, probe = 0, simplify = 0, render = 0;  // render includes load and BVH
  double total() const { return build + probe + simplify + render; }
};

struct SimplifiedMesh {
  std::string name;                   // the input mesh's file name, for messages
  std::filesystem::path drc;          // the mesh rendered (in the cache or a temporary); empty if no triangles
  uint64_t triangles = 0;
  std::string empty_reason;           // why there are no triangles (why_simplified_mesh_is_empty)
  uint64_t drc_bytes = 0;
  int position_bits = 0;
  double max_position_error = 0;
  bool cache_hit = false;
  std::string cache_note;             // which entry was reused and why, or why rebuilt
  uint64_t folds_left_for_memory = 0; // triangles left turned over: refining their cells would pass the memory limit
};

struct RunResult {
  RenderResult render;
  uint64_t triangles_in = 0, triangles_out = 0;
  std::vector<SimplifiedMesh> meshes; // one per store
  std::vector<Cut> cuts;              // one per store
  ProbeResult probe;
  StageTimes seconds;
  double footprint_scale = 1;         // K used (after any coarsening for memory)
  int coarsening_steps = 0;
  bool cache_hit = false;             // every simplified mesh came from the cache
  uint64_t peak_rss = 0;
  std::vector<std::string> warnings;  // printed whatever the log level (meshes left out, ...)
  uint64_t exported_bytes = 0;        // RunOptions::export_mesh's size
};

// Where the store of `mesh` lives: beside it (MESH.raylod) when that store is
// current or the mesh's folder is writable; otherwise, for a mesh in a
// read-only folder, under cache_dir/stores/ (named by a hash of the mesh's
// absolute path and its file name). *note says why the cache was chosen.
std::filesystem::path store_path_for(const std::filesystem::path& mesh, const std::filesystem::path& cache_dir,
                                     const StoreOptions& options, std::string* note = nullptr);
// Creates cache_dir/stores, where stores and cuts go whose mesh's folder
// takes no files, and says whether it takes files.
bool cache_store_folder_is_writable(const std::filesystem::path& cache_dir);

StatusOr<RunResult> run_pipeline(Scene scene, const RunOptions& options, const LogFn& log);

// The stages of `raylod run`, shared by one view (run_pipeline) and a view
// sequence (pipeline/views.h). A session holds what they share: the stores
// (built once), the memory budget and the cache.
struct RunSession {
  SceneStores stores;
  MemoryBudget budget;
  uint64_t memory_limit = 0;                 // budget.working(): what simplify and render get
  std::optional<SimplifiedCache> cache;      // none with --no-cache, or when the cache refused
  std::filesystem::path scratch;             // where simplified meshes are staged
  bool repaired = false;                     // a store found corrupt is rebuilt once per session
  std::vector<std::string> warnings;         // printed whatever the log level
  // If set, simplify_or_reuse reuses (beyond exact hits) only the cache
  // entries with these keys: a view sequence sets it to the entries the cache
  // held when the run began, so that no view depends on which views ran
  // before it (or on another rank).
  std::optional<std::set<std::string>> reusable;
  // A view sequence's page cache (keep_pages_between_views): the pages the
  // probe loaded for one view stay for the next, up to retained_pages bytes
  // while simplify and render run (their memory_limit is lowered by as
  // much). None: every trace has its own.
  std::unique_ptr<PageCache> pages;
  uint64_t retained_pages = 0;
  // What a view sequence's cut selections keep of the stores between views
  // (probe.h, SelectionCache; keep_pages_between_views); none: each
  // selection makes its own.
  std::unique_ptr<SelectionCache> selection_cache;
};

// Gives the session a page cache shared by the traces of its views, keeping
// up to an eighth of the working memory between them (all of it without a
// memory limit); simplify and render then plan within the rest. The same on
// every rank, so outputs do not change with the number of ranks. Also keeps
// what the views' cut selections share (SelectionCache: at most 26 bytes a
// node, 95 MiB for the 10M teapot's 3.8M nodes), taken from the memory
// simplify and render plan with as well.
void keep_pages_between_views(RunSession& session);
// Evicts the kept pages down to retained_pages (after a trace, before
// simplify and render); trace_view does it.
void shrink_kept_pages(RunSession& session);

// Builds or reuses the stores (stage A) and opens the cache. Under mpirun
// (core/cluster.h) rank 0 builds, the others wait and then open the stores,
// and every rank takes rank 0's memory budget (so all select the same cuts).
StatusOr<RunSession> open_run_session(Scene& scene, const RunOptions& options, const LogFn& log);
// The probe configuration of options within the session's budget.
StatusOr<ProbeConfig> run_probe_config(const RunSession& session, const Scene& scene, const RunOptions& options);
// Traces the test rays of scene.camera; a store found corrupt is rebuilt and the trace retried.
StatusOr<ProbeTrace> trace_view(RunSession& session, const Scene& scene, const ProbeConfig& probe, const LogFn& log);
// trace_probe with the test rays split across the ranks under mpirun, each
// rank tracing a contiguous share (ProbeConfig::first_ray); every rank gets
// the whole trace, the same as one process's (merge_traces). Collective.
StatusOr<ProbeTrace> trace_probe_across_ranks(const Scene& scene, std::span<const ProbeStore> stores,
                                              std::span<const ProbeObject> objects, const ProbeConfig& probe);
// The test rays of every camera (trace_view per camera, `--shared-cut`):
// under mpirun the cameras are dealt round robin, each rank tracing whole
// views, and the traces gathered on every rank. Collective.
StatusOr<std::vector<ProbeTrace>> trace_views_across_ranks(RunSession& session, const Scene& scene,
                                                           std::span<const Camera> cameras, const ProbeConfig& probe,
                                                           const LogFn& log);
// trace_view with the test rays split across the ranks under mpirun, each
// rank tracing a contiguous share; every rank gets the whole trace, the same
// as one process's (merge_traces). One process: trace_view. Collective.
StatusOr<ProbeTrace> trace_view_across_ranks(RunSession& session, const Scene& scene, const ProbeConfig& probe,
                                             const LogFn& log);

struct FittedCuts {
  ProbeResult probe;
  double footprint_scale = 1;  // K used (after any coarsening for memory)
  int coarsening_steps = 0;
};
// Selects the cuts of the views (select_shared_cuts; one view: select_cuts),
// coarsening them (doubling K and the tolerance) until the simplified meshes
// fit the session's memory.
StatusOr<FittedCuts> select_fitting_cuts(RunSession& session, std::span<const ProbeView> views, const Scene& scene,
                                         ProbeConfig probe, const RunOptions& options, const LogFn& log);

// Files removed when the owner goes (staged simplified meshes), or by
// SIGTERM, SIGINT or SIGHUP before that (register_scratch_file).
class ScratchFiles {
 public:
  ScratchFiles() = default;
  ScratchFiles(ScratchFiles&& other) noexcept;
  ScratchFiles& operator=(ScratchFiles&& other) noexcept;
  ScratchFiles(const ScratchFiles&) = delete;
  ScratchFiles& operator=(const ScratchFiles&) = delete;
  ~ScratchFiles();
  void add(const std::filesystem::path& file) { files_.push_back({file, register_scratch_file(file)}); }

 private:
  void remove_all();
  std::vector<std::pair<std::filesystem::path, int>> files_;  // and their signal-handler slots
};

// The simplified meshes of a set of cuts, staged for rendering.
struct StagedMeshes {
  std::vector<SimplifiedMesh> meshes;  // one per store
  uint64_t triangles = 0;
  bool cache_hit = true;               // every mesh came from the cache
  ScratchFiles scratch;                // the staged files, removed with this
};
// Stage C: per store, the cached mesh of the cut or one at least as fine
// (simplified_cache.h), else simplifies it (and caches it).
StatusOr<StagedMeshes> simplify_or_reuse(RunSession& session, const Scene& scene, std::span<const Cut> cuts,
                                         const RunOptions& options, const LogFn& log);
// simplify_or_reuse for cuts every rank holds (the same on all): rank 0
// first, which puts the meshes in the cache; then the other ranks, which
// find them there (or, without a cache, simplify the same bytes). Collective.
StatusOr<StagedMeshes> simplify_or_reuse_on_ranks(RunSession& session, const Scene& scene, std::span<const Cut> cuts,
                                                  const RunOptions& options, const LogFn& log);
// Stage D: renders scene.camera's view of the simplified meshes; with
// split_across_ranks, the tiles across the ranks (RenderOptions).
StatusOr<RenderResult> render_simplified(const Scene& scene, std::span<const ProbeObject> objects,
                                         std::span<const SimplifiedMesh> meshes, const RunOptions& options,
                                         uint64_t memory_limit, const LogFn& log, bool split_across_ranks = false);

// Writes the simplified meshes (their Draco bytes unchanged, so with the
// .drc's quantisation) as one .glb: one glTF mesh per store with triangles,
// one node per scene object using it, with the object's transform.
StatusOr<uint64_t> export_simplified_glb(const std::filesystem::path& out, const std::vector<SimplifiedMesh>& meshes,
                                          const SceneStores& stores);

// JSON for --stats-json: triangles_in, triangles_out, seconds per stage,
// peak memory, cache hit, and the render's own statistics.
std::string run_stats_json(const RunResult& result, const RunOptions& options);

// The probe configuration within a memory budget: the page cache gets its
// share (MemoryBudget::page_cache: half of what the limit leaves after what is
// resident and the rays' hit records); an error if nothing is left. Without a
// limit the cache has none either. Call after the stores are open. With
// `pages` (a cache kept from earlier traces) the trace uses it, its resident
// pages counted as free.
StatusOr<ProbeConfig> make_probe_config(const Scene& scene, uint64_t rays, double footprint_scale,
                                        const MemoryBudget& budget, bool progress, PageCache* pages = nullptr);

// Simplifies the cut of a store and writes it Draco-compressed to `out`
// (position quantisation from draco_error_bound, normal quantisation from
// max_normal_error); fills triangles, bytes and bits. A simplified mesh with
// no triangles is not an error here: nothing is written, drc stays empty and
// empty_reason says why (the caller decides: `run` leaves the object out).
StatusOr<SimplifiedMesh> simplify_cut_to_draco(const OctreeStore& store, const Cut& cut, const std::filesystem::path& out,
                                               uint64_t memory_limit /* 0 = no limit */, double max_normal_error, bool progress,
                                               double* seconds = nullptr,
                                               double crease_angle_deg = kDefaultCreaseAngleDeg,
                                               int fold_passes = 0);
// SimplifyConfig::fold_passes for store `store` of a scene: kSpecularFoldPasses
// if a mirror or glass object uses it, else 0.
int fold_passes_for(const Scene& scene, std::span<const ProbeObject> objects, size_t store);
// Whether simplify_cut_to_draco gives the store's representatives exact
// normals (SimplifyConfig::exact_normals): where it asks for fold passes (a
// mirror or glass object uses the store), with or without input normals.
// The simplified-mesh cache keys its entries by it.
bool exact_normals_for(int fold_passes);

// What `raylod run` gives simplify for a store, so that `raylod simplify
// STORE CUT` run by hand on a cut from `raylod probe` makes the mesh run
// makes: fold passes (and with them exact normals), the normals'
// quantisation (shading_normal_tolerance) and the crease angle. probe
// records them in the cut's counters (simplify_fold_passes,
// simplify_normal_bits, simplify_crease_angle_udeg); a cut from before
// gives simplify's own defaults (recorded = false).
struct SimplifySettings {
  bool recorded = false;
  int fold_passes = 0;
  int normal_bits = kDefaultNormalBits;
  double crease_angle_deg = kDefaultCreaseAngleDeg;
};
void record_simplify_settings(Cut& cut, const Scene& scene, std::span<const ProbeObject> objects, size_t store);
SimplifySettings simplify_settings_of(const Cut& cut);

// Whether a failed simplify_cut_to_draco into `staged` means the disk refused
// that file (full, read-only, gone): a typed write failure (Status::code) of
// that very path. `run` then stages in the system's temporary folder and
// renders without caching; any other failure -- even one whose message names
// the file -- is not the disk's and is not retried there.
bool staged_write_refused(const Status& status, const std::filesystem::path& staged);

// The largest normal error (radians) the scene's shading cannot show: a
// rotation d of a shading normal changes a Lambert term by up to d and a
// Phong lobe cos^n by about n d, so d < 1 / (2 * 255 * max(1, n)) keeps the
// change under half an 8-bit level; mirrors and glass turn d into a
// direction error of 2 d, kept under an eighth of a pixel's angle.
double shading_normal_tolerance(const Scene& scene);

// The largest tilt (radians) of a face normal that the renderer's use of
// face normals cannot show: they decide which side of the shadow terminator a
// point is on (and where shadow rays start), and a tilt d only changes that
// where the Lambert term is below d, so d < 1 / (2 * 255) keeps the change
// under half an 8-bit level.
inline constexpr double kGeometricNormalTolerance = 1.0 / (2.0 * 255.0);

// Edge length of the equilateral triangle of the store's mean input triangle
// area (total area from the root quadric's trace); 0 if the store is empty.
double mean_input_edge(const OctreeStore& store);

// The largest position error that tilts a face of mean_input_edge(store) by
// no more than kGeometricNormalTolerance; 0 if the store is empty.
double geometric_normal_position_bound(const OctreeStore& store);

// The Draco error bound for a cut: well below the smallest footprint the
// probe measured (an eighth), so quantisation never shows at the probed scale,
// and at most geometric_normal_position_bound(store), so that quantising the
// kept input triangles does not tilt their face normals visibly.
double draco_error_bound(const Cut& cut, const OctreeStore& store);

// On mirrors and glass (the meshes simplify gives exact normals), `bound`
// held to a quarter of the simplified mesh's shortest edge, but no less than
// 2^-22 of root_size (the store's root cell): through glass, sheets that
// quantisation merges or crosses swap the order in which a ray meets them.
// A 12-triangle glass pane 1e-4 of its size thick came out flat from a bound
// of 4.2e-4 (11 bits) and rendered at 21 dB against a 42 dB floor. Returns
// `bound` itself for other meshes, and for one with no edge longer than 0.
double thin_wall_position_bound(double bound, const IndexedMesh& mesh, double root_size, bool specular);

}  // namespace raylod
