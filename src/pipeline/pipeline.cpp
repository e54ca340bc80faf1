#include "pipeline/pipeline.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <cstring>
#include <tuple>
#include <type_traits>

#include <nlohmann/json.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "core/cluster.h"
#include "core/fault_point.h"
#include "core/system.h"
#include "geometry/crease_normals.h"
#include "gen/generate.h"
#include "pipeline/simplified_cache.h"
#include "scene/mesh_framing.h"
#include "streaming/draco_io.h"
#include "streaming/gltf_io.h"

namespace raylod {
namespace fs = std::filesystem;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void say(const LogFn& log, const std::string& text) {
  if (log) log(text);
}

namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace

double mean_input_edge(const OctreeStore& store) {
  // Each corner adds area / 3 times n n^T with |n| = 1 to its cell's quadric,
  // so trace(A) of the root is the total area of the input.
  const auto root = store.level(0);
  const uint64_t triangles = store.header().triangle_count;
  if (root.empty() || triangles == 0) return 0;
  const Quadric& q = root[0].quadric;
  const double area = quadric_weight(q);
  if (!(area > 0) || !std::isfinite(area)) return 0;
  // Edge of the equilateral triangle of the mean area: A = (sqrt(3) / 4) l^2.
  return std::sqrt(4.0 * (area / double(triangles)) / std::sqrt(3.0));
}

double geometric_normal_position_bound(const OctreeStore& store) {
  // Moving the corners of a triangle with edge l (altitude sqrt(3)/2 l) by up
  // to e each tilts its face normal by up to about 2 e / (sqrt(3)/2 l); keep
  // that under kGeometricNormalTolerance.
  const double edge = mean_input_edge(store);
  if (!(edge > 0)) return 0;
  return kGeometricNormalTolerance * (std::sqrt(3.0) / 4.0) * edge;
}

double draco_error_bound(const Cut& cut, const OctreeStore& store) {
  // An eighth of the finest footprint keeps quantisation far below what any
  // probed ray resolves; without measured hits, 1e-5 of the model size. That
  // alone is not enough: the cut keeps input triangles (at small K, most of
  // them) that can be several times smaller than the footprint, and Draco
  // moves every vertex, kept ones included. A shift that no camera ray
  // resolves still tilts those triangles' face normals (by tens of degrees at
  // footprint / 8 on a 10M-triangle teapot), and the renderer's face normals
  // decide which side of the shadow terminator a point is on and where
  // shadow rays start: the result is dark speckles along terminators and
  // silhouettes. So the bound is also kept below what tilts a face of the
  // input's mean size by more than kGeometricNormalTolerance.
  double bound = cut.min_footprint > 0 ? double(cut.min_footprint) / 8.0 : store.header().root_size * 1e-5;
  const double geometric = geometric_normal_position_bound(store);
  if (geometric > 0) bound = std::min(bound, geometric);
  return bound;
}

double thin_wall_position_bound(double bound, const IndexedMesh& mesh, double root_size, bool specular) {
  if (!specular) return bound;
  double shortest2 = std::numeric_limits<double>::infinity();
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const Vec3d a(mesh.positions[mesh.indices[t + size_t(k)]]);
      const Vec3d b(mesh.positions[mesh.indices[t + size_t((k + 1) % 3)]]);
      const double l2 = glm::dot(a - b, a - b);
      if (l2 > 0) shortest2 = std::min(shortest2, l2);
    }
  if (!std::isfinite(shortest2)) return bound;
  const double floor = root_size * 0x1p-22;
  return std::min(bound, std::max(floor, std::sqrt(shortest2) / 4));
}

namespace {

// What the probe keeps free for its test rays' hit records.
uint64_t probe_reserve_bytes(uint64_t rays, const Scene& scene) {
  return rays * 64 * uint64_t(std::max(1, scene.max_depth + 1)) + (uint64_t(32) << 20);
}

}  // namespace

StatusOr<ProbeConfig> make_probe_config(const Scene& scene, uint64_t rays, double footprint_scale,
                                        const MemoryBudget& budget, bool progress, PageCache* pages) {
  ProbeConfig probe;
  probe.rays = rays;
  probe.seed = scene.seed;
  probe.footprint_scale = footprint_scale;
  probe.progress = progress;
  // The page cache's share (memory_budget.h): half of what the limit leaves
  // after what is already resident (the stores' node tables) and a reserve
  // for the test rays' hit records.
  // A cache kept from earlier views counts as free: it is this cache.
  const uint64_t held = pages ? pages->resident_bytes() : 0;
  // What an earlier view freed (its render, its simplify) is not resident
  // for this one: the allocator gives it back first.
#if defined(__GLIBC__)
  if (budget.limited()) malloc_trim(0);
#endif
  const uint64_t rss_now = current_rss_bytes();
  const uint64_t rss = rss_now > held ? rss_now - held : 0;
  probe.pages = pages;
  const uint64_t reserve = probe_reserve_bytes(rays, scene);
  probe.cache_bytes = budget.page_cache(rss, reserve);
  if (budget.limited() && probe.cache_bytes == 0)
    return Status::error("the memory limit of " + format_bytes(budget.total) + " leaves nothing for the probe's pages: " +
                         format_bytes(rss) + " is already resident (the stores' node tables and the program) and the " +
                         "test rays need " + format_bytes(reserve) + "; raise --memory-limit");
  return probe;
}

double shading_normal_tolerance(const Scene& scene) {
  double tolerance = 1.0 / (2.0 * 255.0);
  for (const auto& m : scene.materials) {
    if (m.type == MaterialType::Glossy) tolerance = std::min(tolerance, 1.0 / (2.0 * 255.0 * std::max(1.0f, m.shininess)));
    if (scene.traces_specular(m)) {
      const double pixel = 2.0 * std::tan(glm::radians(scene.camera.fov_y_deg) / 2) / scene.camera.height;
      tolerance = std::min(tolerance, pixel / 16.0);
    }
  }
  return tolerance;
}

int fold_passes_for(const Scene& scene, std::span<const ProbeObject> objects, size_t store) {
  for (const ProbeObject& o : objects) {
    if (o.store != store) continue;
    const Material& m = scene.materials[size_t(o.material)];
    if (scene.traces_specular(m)) return kSpecularFoldPasses;
  }
  return 0;
}

bool exact_normals_for(int fold_passes) { return fold_passes > 0; }

void record_simplify_settings(Cut& cut, const Scene& scene, std::span<const ProbeObject> objects, size_t store) {
  cut.counters["simplify_fold_passes"] = uint64_t(fold_passes_for(scene, objects, store));
  cut.counters["simplify_normal_bits"] = uint64_t(choose_normal_bits(shading_normal_tolerance(scene)));
  cut.counters["simplify_crease_angle_udeg"] = uint64_t(std::llround(scene.crease_angle_deg * 1e6));
}

SimplifySettings simplify_settings_of(const Cut& cut) {
  SimplifySettings s;
  const auto f = cut.counters.find("simplify_fold_passes"), b = cut.counters.find("simplify_normal_bits"),
             a = cut.counters.find("simplify_crease_angle_udeg");
  if (f == cut.counters.end() || b == cut.counters.end() || a == cut.counters.end()) return s;
  s.recorded = true;
  s.fold_passes = int(std::min<uint64_t>(f->second, 64));
  s.normal_bits = int(std::clamp<uint64_t>(b->second, 2, kMaxNormalBits));
  s.crease_angle_deg = std::min(180.0, double(a->second) * 1e-6);
  return s;
}

StatusOr<SimplifiedMesh> simplify_cut_to_draco(const OctreeStore& store, const Cut& cut, const fs::path& out,
                                               uint64_t memory_limit, double max_normal_error, bool progress,
                                               double* seconds, double crease_angle_deg, int fold_passes) {
  auto t0 = std::chrono::steady_clock::now();
  SimplifyConfig sc;
  sc.crease_angle_deg = crease_angle_deg;
  sc.fold_passes = fold_passes;
  sc.exact_normals = exact_normals_for(fold_passes);
  sc.memory_limit = memory_limit;
  sc.progress = progress;
  RAYLOD_ASSIGN_OR_RETURN(SimplifyResult simplified, simplify(store, cut, sc));
  if (simplified.mesh.triangle_count() == 0) {
    SimplifiedMesh empty;
    empty.empty_reason = why_simplified_mesh_is_empty(simplified, cut);
    if (seconds) *seconds = seconds_since(t0);
    return empty;
  }
  DracoOptions dopt;
  dopt.max_position_error =
      thin_wall_position_bound(draco_error_bound(cut, store), simplified.mesh, store.header().root_size,
                               sc.exact_normals);
  dopt.normal_bits = 0;
  dopt.max_normal_error = max_normal_error;
  const uint64_t triangles = simplified.mesh.triangle_count();
  dopt.speed = draco_speed_for(triangles);
  dopt.parts = draco_parts_for(triangles);  // a part file from 2M triangles: encoded and decoded in parallel
  RAYLOD_ASSIGN_OR_RETURN(DracoWriteReport written, write_draco(out, std::move(simplified.mesh), dopt));
  SimplifiedMesh sm;
  sm.drc = out;
  sm.triangles = triangles;
  if (simplified.folds_stopped_by_memory) sm.folds_left_for_memory = simplified.stats.folded;
  sm.drc_bytes = written.bytes;
  sm.position_bits = written.position_bits;
  sm.max_position_error = written.max_position_error;
  if (seconds) *seconds = seconds_since(t0);
  return sm;
}

bool staged_write_refused(const Status& status, const fs::path& staged) {
  return status.is_write_failure() && fs::path(status.path()) == staged;
}

bool cache_store_folder_is_writable(const fs::path& cache_dir) {
  std::error_code ec;
  fs::create_directories(cache_dir / "stores", ec);
  return !ec && folder_is_writable(cache_dir / "stores");
}

fs::path store_path_for(const fs::path& mesh, const fs::path& cache_dir, const StoreOptions& options,
                        std::string* note) {
  const fs::path beside = default_store_path(mesh);
  const fs::path folder = fs::absolute(mesh).parent_path();
  // A mesh name so long that the store's check record beside it
  // (MESH.raylod.checked) would pass a file name's 255 bytes: the cache,
  // under a shortened name.
  const bool fits = beside.filename().string().size() + std::strlen(".checked") <= 255;
  if ((fits && folder_is_writable(folder)) || store_is_current(mesh, beside, options)) return beside;
  const std::string absolute = fs::absolute(mesh).lexically_normal().string();
  char hash[17];
  std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(fnv1a64(absolute.data(), absolute.size())));
  const std::string name = std::string(hash) + "-" + temporary_stem(mesh.filename().string()) + ".raylod";
  const fs::path in_cache = cache_dir / "stores" / name;
  const std::string why = fits ? folder.string() + " is not writable"
                               : mesh.filename().string().substr(0, 40) + "...: the name is too long for a store beside it";
  if (cache_store_folder_is_writable(cache_dir) || store_is_current(mesh, in_cache, options)) {
    if (note) *note = why + ": the store goes to " + in_cache.string();
    return in_cache;
  }
  // Neither the mesh's folder nor the cache takes files (a read-only cache
  // shared by others): the system's temporary folder, per user.
  const fs::path in_temp =
      temporary_folder() / ("raylod-stores-" + std::to_string(::getuid())) / name;
  std::error_code ec;
  fs::create_directories(in_temp.parent_path(), ec);
  if (note)
    *note = folder.string() + " and " + in_cache.parent_path().string() + " are not writable: the store goes to " +
            in_temp.string();
  return in_temp;
}

StatusOr<SceneStores> prepare_scene_stores(Scene& scene, const std::optional<fs::path>& mesh_override,
                                           const StoreOptions& store_options, const fs::path& cache_dir,
                                           const LogFn& log, bool check_stores) {
  auto t0 = std::chrono::steady_clock::now();
  if (mesh_override) RAYLOD_RETURN_IF_ERROR(replace_first_mesh(scene, *mesh_override));
  RAYLOD_RETURN_IF_ERROR(resolve_generated_meshes(scene, cache_dir));

  SceneStores out;
  std::map<fs::path, size_t> index;
  for (const auto& obj : scene.objects) {
    fs::path mesh = fs::absolute(obj.mesh).lexically_normal();
    auto [it, fresh] = index.emplace(mesh, out.meshes.size());
    if (fresh) out.meshes.push_back(mesh);
    out.objects.push_back(ProbeObject{it->second, obj.transform, obj.material});
  }
  for (const auto& mesh : out.meshes) {
    std::string where;
    fs::path store_path = store_path_for(mesh, cache_dir, store_options, &where);
    if (!where.empty()) say(log, where);
    BuildReport report;
    report.reused = true;
    if (check_stores) {
      // An existing store is reused under this memory limit only if a fresh
      // build under it would make the same store (store_is_current).
      // One check, under the build's lock: concurrent runs wait for one build.
      RAYLOD_ASSIGN_OR_RETURN(report, build_store(mesh, store_path, store_options, false, false, [&](const std::string& reason) {
                                say(log, "building store " + store_path.string() + " (" + reason + ")");
                              }));
    }
    // The store file's status before it was opened: the check's, if it
    // found the store current and hands its open store on.
    std::shared_ptr<OctreeStore> store = std::move(report.opened);
    FileStatus status = report.opened_status;
    if (!store) {
      RAYLOD_ASSIGN_OR_RETURN(status, file_status(store_path));
      RAYLOD_ASSIGN_OR_RETURN(store, OctreeStore::open(store_path));
    }
    out.store_files.push_back(std::to_string(status.inode) + " " + std::to_string(status.bytes) + " " +
                              std::to_string(status.mtime_ns));
    out.triangles += store->header().triangle_count;
    out.store_paths.push_back(store_path);
    out.builds.push_back(report);
    out.stores.push_back(std::move(store));
  }
  for (size_t i = 0; i < out.stores.size(); ++i) out.probe_stores.push_back(ProbeStore{out.stores[i].get(), out.store_paths[i]});
  out.seconds = seconds_since(t0);
  return out;
}

namespace {

// Simplified meshes staged in the system temp folder (--no-cache, or a cache
// that refused them) by runs that were killed: nobody else removes them.
void remove_dead_staged_meshes(const fs::path& dir) {
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("simplified-", 0) == 0 && is_dead_process_temporary(name)) {
      std::error_code rm;
      fs::remove(it->path(), rm);
    }
  }
}

// After a probe or simplify failure: every store in which a reader found a
// corrupt page (it recorded that in STORE.corrupt) is rebuilt and reopened in
// place, at most once per run (`repaired`). True if the caller should retry;
// false if no store was found corrupt (the failure was something else).
StatusOr<bool> repair_corrupt_stores(SceneStores& stores, const std::string& stage,
                                     bool& repaired, const LogFn& log) {
  // Under mpirun a store is not rebuilt in the middle of the job: the other
  // ranks have it open (on NFS, a file replaced under another node fails its
  // reads). The corruption, recorded beside the store, ends the job; the
  // next run's check on rank 0 rebuilds the store.
  if (repaired || cluster::active()) return false;
  bool rebuilt = false;
  for (size_t i = 0; i < stores.stores.size(); ++i) {
    const fs::path& path = stores.store_paths[i];
    const std::optional<std::string> recorded = store_corruption(path);
    if (!stores.stores[i]->found_corruption() && !recorded) continue;
    say(log, stage + " found " + path.string() + " corrupt (" + (recorded ? *recorded : "checksum mismatch") +
                 "); rebuilding it and retrying the " + stage);
    // The same options as the open store: the rebuilt store is byte-identical
    // to the one the cuts were made for, had it not been damaged.
    StoreOptions options = stores.stores[i]->header().options;
    RAYLOD_ASSIGN_OR_RETURN(BuildReport report, build_store(stores.meshes[i], path, options));
    RAYLOD_ASSIGN_OR_RETURN(auto reopened, OctreeStore::open(path));
    stores.stores[i] = std::move(reopened);
    stores.probe_stores[i].store = stores.stores[i].get();
    stores.builds[i] = report;
    rebuilt = true;
  }
  repaired = rebuilt;
  return rebuilt;
}

}  // namespace

StatusOr<uint64_t> export_simplified_glb(const fs::path& out, const std::vector<SimplifiedMesh>& meshes,
                                          const SceneStores& stores) {
  // The .drc bytes go into the .glb as they are: the same quantisation.
  std::vector<GlbMesh> glb_meshes;
  std::vector<size_t> glb_index(meshes.size(), SIZE_MAX);
  for (size_t i = 0; i < meshes.size(); ++i) {
    if (meshes[i].triangles == 0) continue;
    std::ifstream in(meshes[i].drc, std::ios::binary);
    if (!in) return Status::error(meshes[i].drc.string() + ": cannot open the simplified mesh");
    GlbMesh m;
    m.name = stores.meshes[i].filename().string();
    const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    // A part file's parts become the primitives of one glTF mesh.
    RAYLOD_ASSIGN_OR_RETURN(const auto parts, draco_parts(bytes.data(), bytes.size(), meshes[i].drc.string()));
    m.draco.assign(parts[0].begin(), parts[0].end());
    for (size_t p = 1; p < parts.size(); ++p) m.more_parts.emplace_back(parts[p].begin(), parts[p].end());
    glb_index[i] = glb_meshes.size();
    glb_meshes.push_back(std::move(m));
  }
  std::vector<GlbNode> nodes;
  for (size_t o = 0; o < stores.objects.size(); ++o) {
    const ProbeObject& obj = stores.objects[o];
    if (glb_index[obj.store] == SIZE_MAX) continue;
    // The Draco positions are relative to the mesh origin (a far mesh's); glTF
    // readers know nothing of its metadata, so the node carries it.
    const Vec3d origin = stores.stores[obj.store]->header().mesh_origin;
    nodes.push_back(GlbNode{"objects[" + std::to_string(o) + "]", glb_index[obj.store],
                            obj.transform * glm::translate(glm::dmat4(1.0), origin)});
  }
  if (nodes.empty()) return Status::error(out.string() + ": no simplified mesh has triangles; nothing was exported");
  return write_glb(out, glb_meshes, nodes);
}

ScratchFiles::ScratchFiles(ScratchFiles&& other) noexcept : files_(std::move(other.files_)) { other.files_.clear(); }

ScratchFiles& ScratchFiles::operator=(ScratchFiles&& other) noexcept {
  if (this != &other) {
    remove_all();
    files_ = std::move(other.files_);
    other.files_.clear();
  }
  return *this;
}

ScratchFiles::~ScratchFiles() { remove_all(); }

void ScratchFiles::remove_all() {
  for (auto& [file, slot] : files_) {
    std::error_code ec;
    fs::remove(file, ec);
    release_scratch_file(slot);
  }
  files_.clear();
}

namespace {

// What tells stores apart: their paths and files (a rebuilt store is a new
// file), sources (path, size, time, content hash), sizes and layout, one
// line each. The inode, not the device: NFS clients agree on the first only.
std::string store_identities(const SceneStores& stores) {
  std::string ids;
  for (size_t i = 0; i < stores.stores.size(); ++i) {
    const StoreHeader& h = stores.stores[i]->header();
    ids += stores.store_paths[i].string() + " " + stores.store_files[i] + " " + h.source_path + " " +
           std::to_string(h.source_bytes) + " " +
           std::to_string(h.source_mtime_ns) + " " + std::to_string(h.source_hash) + " " +
           std::to_string(h.triangle_count) + " " + std::to_string(h.file_bytes) + " " +
           std::to_string(h.quadric_depth) + " " + std::to_string(h.page_level) + "\n";
  }
  return ids;
}

}  // namespace

Status check_object_placements(const Scene& scene, const SceneStores& stores, std::vector<std::string>& warnings) {
  // An object its transform puts beyond the float range cannot be rendered
  // (the full render refuses it too); one outside the sizes single-precision
  // rays render faithfully is warned about.
  for (size_t o = 0; o < stores.objects.size(); ++o) {
    const ProbeObject& obj = stores.objects[o];
    const StoreHeader& h = stores.stores[obj.store]->header();
    const Bbox world = world_bounds(obj.transform * glm::translate(glm::dmat4(1.0), h.mesh_origin), h.bounds);
    const std::string& mesh = stores.meshes[obj.store].string();
    double reach = 0;
    for (int a = 0; a < 3; ++a) reach = std::max({reach, std::abs(world.lo[a]), std::abs(world.hi[a])});
    if (!(reach <= double(std::numeric_limits<float>::max())))
      return Status::error(object_context(scene, o) + "the object's transform puts " + mesh +
                           " beyond the float range (its bounds reach " + fmt("%.3g", reach) + ")");
    if (const std::string problem = size_problem(world); !problem.empty()) warnings.push_back(mesh + " " + problem);
  }
  return Status::ok();
}

StatusOr<RunSession> open_run_session(Scene& scene, const RunOptions& options, const LogFn& log) {
  RunSession session;
  const fs::path cache_dir = options.cache_dir.empty() ? default_cache_dir() : options.cache_dir;
  // One budget for the whole run (memory_budget.h): the build plans within
  // its total; simplify and render share what the program itself leaves.
  session.budget = MemoryBudget::of(options.memory_limit);
  // A limit that leaves the probe nothing even before any store is open
  // fails now, not after rebuilding a good store for it.
  if (const uint64_t reserve = probe_reserve_bytes(options.rays, scene);
      session.budget.limited() && session.budget.total <= session.budget.baseline + reserve)
    return Status::error("the memory limit of " + format_bytes(session.budget.total) + " leaves nothing for the probe: " +
                         "the program's own " + format_bytes(session.budget.baseline) + " and the test rays' " +
                         format_bytes(reserve) + " already take it; raise --memory-limit");
  StoreOptions store_options;
  store_options.memory_limit = session.budget.total;
  session.memory_limit = session.budget.working();

  // A. Stores (method step A1), reused when current.
  say(log, "[1/4] build: octree stores");
  // Under mpirun rank 0 builds (or checks) the stores. The others do not
  // check them again (that hashes every mesh: a second per rank on a
  // 10M-triangle mesh): they open the stores as they are meanwhile, and
  // again once rank 0 is done if those were not the very stores it checked
  // (it built them, or another budget names other stores).
  StatusOr<SceneStores> stores = Status::error("the stores were not prepared");
  const Scene unresolved = scene;
  if (cluster::is_root()) stores = prepare_scene_stores(scene, options.mesh_override, store_options, cache_dir, log);
  else stores = prepare_scene_stores(scene, options.mesh_override, store_options, cache_dir, LogFn(), false);
  RAYLOD_RETURN_IF_ERROR(cluster::agree(cluster::is_root() ? stores.status() : Status::ok()));
  if (cluster::active()) {
    // Rank 0's budget everywhere: the same store paths, the same coarsening
    // and the same BVH layout on every rank.
    cluster::broadcast_value(session.budget);
    session.memory_limit = session.budget.working();
    store_options.memory_limit = session.budget.total;
    std::string checked = cluster::is_root() ? store_identities(*stores) : std::string();
    cluster::broadcast(checked);
    if (!cluster::is_root() && (!stores.is_ok() || store_identities(*stores) != checked)) {
      stores = Status::error("the stores were not prepared");  // the early ones closed first
      scene = unresolved;
      stores = prepare_scene_stores(scene, options.mesh_override, store_options, cache_dir, LogFn(), false);
      if (stores.is_ok() && store_identities(*stores) != checked)
        stores = Status::error("the stores were replaced after rank 0 checked them (rebuilt by another run?): " +
                               stores->store_paths[0].string());
    }
    RAYLOD_RETURN_IF_ERROR(cluster::agree(stores.status()));
  }
  session.stores = std::move(stores.value());
  // A mesh put in place of the first object of a scene made for another:
  // say if that scene's camera and ground do not show it.
  if (options.mesh_override && !session.stores.objects.empty()) {
    const ProbeObject& obj = session.stores.objects[0];
    const StoreHeader& h = session.stores.stores[obj.store]->header();
    const Bbox world = world_bounds(obj.transform * glm::translate(glm::dmat4(1.0), h.mesh_origin), h.bounds);
    if (const std::string problem = placement_problem(scene, world); !problem.empty())
      session.warnings.push_back(options.mesh_override->string() + " " + problem +
                                 " in this scene; `raylod scene " + options.mesh_override->string() +
                                 "` writes a scene that frames it");
  }
  RAYLOD_RETURN_IF_ERROR(check_object_placements(scene, session.stores, session.warnings));
  // What a store build had to say (a position grid made coarse by a few
  // far-away vertices; a memory limit below its minimum).
  for (size_t i = 0; i < session.stores.builds.size(); ++i)
    if (!session.stores.builds[i].reused && !session.stores.builds[i].warning.empty())
      session.warnings.push_back(session.stores.meshes[i].string() + ": " + session.stores.builds[i].warning);
  // The cut's bounds take a representative's normals as the default crease
  // rule makes them (smooth within a CAD face, split at its edges): flat
  // shading (0) shows each collapsed cell's facets, 90 to 180 smooth across
  // edges over a cell rather than a triangle (a nut 10 to 14 dB below its
  // noise floor). Meshes with normals of their own keep the default.
  if (scene.crease_angle_deg != kDefaultCreaseAngleDeg)
    for (size_t i = 0; i < session.stores.stores.size(); ++i)
      if (!session.stores.stores[i]->header().has_normals) {
        session.warnings.push_back(
            "crease angle " + fmt("%g", scene.crease_angle_deg) + " degrees: the cut's error bounds assume the "
            "default of " + fmt("%g", kDefaultCreaseAngleDeg) + ", so collapsed parts of " +
            session.stores.meshes[i].string() + " (no normals of its own) may shade differently from the full render "
            "(check with --compare)");
        break;
      }
  if (!options.output_image.empty()) RAYLOD_RETURN_IF_ERROR(cluster::agree(check_output_image(options.output_image)));
  say(log, "stores ready: " + std::to_string(session.stores.triangles) + " triangles in " +
               std::to_string(session.stores.stores.size()) + " store(s), " + fmt("%.2f s", session.stores.seconds));
  if (options.use_cache) {
    auto c = SimplifiedCache::open(cache_dir, options.cache_limit);
    if (c.is_ok()) session.cache.emplace(std::move(c.value()));
    else session.warnings.push_back("cannot use the cache (" + c.status().message() + "); rendering without caching");
  }
  session.scratch = session.cache ? session.cache->dir() / "simplified" : temporary_folder();
  remove_dead_staged_meshes(temporary_folder());
  return session;
}

StatusOr<ProbeConfig> run_probe_config(const RunSession& session, const Scene& scene, const RunOptions& options) {
  RAYLOD_ASSIGN_OR_RETURN(ProbeConfig probe, make_probe_config(scene, options.rays, options.footprint_scale,
                                                              session.budget, options.progress, session.pages.get()));
  probe.criterion = options.criterion;
  probe.tolerance_px = options.tolerance_px;
  probe.angle_tolerance_px = options.angle_tolerance_px;
  probe.outline_tolerance = options.outline_tolerance;
  probe.unreached_angle_allowance = options.unreached_angle_allowance;
  probe.balance = options.balance;
  probe.unseen_cells = options.unseen_cells;
  probe.shadow_receivers = options.shadow_receivers;
  probe.selection_cache = session.selection_cache.get();
  return probe;
}

StatusOr<ProbeTrace> trace_view(RunSession& session, const Scene& scene, const ProbeConfig& probe, const LogFn& log) {
  SceneStores& stores = session.stores;
  auto traced = trace_probe(scene, stores.probe_stores, stores.objects, probe);
  if (!traced.is_ok()) {
    RAYLOD_ASSIGN_OR_RETURN(bool retry, repair_corrupt_stores(stores, "probe", session.repaired, log));
    if (retry && session.pages) session.pages->clear();  // the pages of the replaced store
    if (retry) traced = trace_probe(scene, stores.probe_stores, stores.objects, probe);
  }
  shrink_kept_pages(session);
  return traced;
}

void shrink_kept_pages(RunSession& session) {
  if (session.pages) session.pages->set_capacity(session.budget.limited() ? std::max<uint64_t>(session.retained_pages, 1) : 0);
}

void keep_pages_between_views(RunSession& session) {
  const uint64_t working = session.budget.working();
  session.retained_pages = session.budget.limited() ? working / 8 : 0;
  if (session.budget.limited()) session.memory_limit = std::max<uint64_t>(working - working / 8, 1);
  session.pages = std::make_unique<PageCache>(0);
  session.selection_cache = std::make_unique<SelectionCache>();
  std::vector<const OctreeStore*> stores;
  for (const auto& store : session.stores.stores) stores.push_back(store.get());
  const uint64_t kept = SelectionCache::bytes_for(stores);
  if (session.budget.limited())
    session.memory_limit = std::max<uint64_t>(session.memory_limit - std::min(session.memory_limit, kept), 1);
}

namespace {

// A trace as bytes, for gathering the ranks' shares: the hits as they are
// (plain values; every rank runs the same binary), then the counters.
std::string pack_trace(const ProbeTrace& t) {
  static_assert(std::is_trivially_copyable_v<ProbeHit>);
  std::string b = cluster::to_bytes(uint64_t(t.hits.size())) + cluster::to_bytes(t.trace_seconds) +
                  cluster::to_bytes(t.rays) + cluster::to_bytes(t.seed) + cluster::to_bytes(t.magnification);
  b.append(reinterpret_cast<const char*>(t.hits.data()), t.hits.size() * sizeof(ProbeHit));
  b += cluster::to_bytes(uint64_t(t.ground_hits.size()));
  static_assert(std::is_trivially_copyable_v<GroundHit>);
  b.append(reinterpret_cast<const char*>(t.ground_hits.data()), t.ground_hits.size() * sizeof(GroundHit));
  for (const auto& [name, value] : t.counters)
    b += cluster::to_bytes(uint64_t(name.size())) + name + cluster::to_bytes(value);
  return b;
}

// A byte string preceded by its length.
std::string packed_size(const std::string& b) { return cluster::to_bytes(uint64_t(b.size())) + b; }

ProbeTrace unpack_trace(const std::string& b) {
  ProbeTrace t;
  const uint64_t hits = cluster::from_bytes<uint64_t>(b, 0);
  t.trace_seconds = cluster::from_bytes<double>(b, 8);
  t.rays = cluster::from_bytes<uint64_t>(b, 16);
  t.seed = cluster::from_bytes<uint64_t>(b, 24);
  t.magnification = cluster::from_bytes<double>(b, 32);
  size_t at = 40;
  t.hits.resize(hits);
  std::memcpy(t.hits.data(), b.data() + at, hits * sizeof(ProbeHit));
  at += hits * sizeof(ProbeHit);
  const uint64_t ground = cluster::from_bytes<uint64_t>(b, at);
  at += 8;
  t.ground_hits.resize(ground);
  std::memcpy(t.ground_hits.data(), b.data() + at, ground * sizeof(GroundHit));
  at += ground * sizeof(GroundHit);
  while (at + 8 <= b.size()) {
    const uint64_t n = cluster::from_bytes<uint64_t>(b, at);
    std::string name = b.substr(at + 8, n);
    t.counters[name] = cluster::from_bytes<uint64_t>(b, at + 8 + n);
    at += 16 + n;
  }
  return t;
}

}  // namespace

StatusOr<ProbeTrace> trace_probe_across_ranks(const Scene& scene, std::span<const ProbeStore> stores,
                                              std::span<const ProbeObject> objects, const ProbeConfig& probe) {
  if (!cluster::active()) return trace_probe(scene, stores, objects, probe);
  ProbeConfig mine = probe;
  std::tie(mine.first_ray, mine.end_ray) = cluster::share(probe.rays, cluster::rank(), cluster::size());
  auto traced = trace_probe(scene, stores, objects, mine);
  RAYLOD_RETURN_IF_ERROR(cluster::agree(traced.status()));
  const std::vector<std::string> parts = cluster::allgather(pack_trace(*traced));
  traced = ProbeTrace{};
  std::vector<ProbeTrace> shares;
  for (const std::string& p : parts) shares.push_back(unpack_trace(p));
  return merge_traces(std::move(shares), probe);
}

StatusOr<std::vector<ProbeTrace>> trace_views_across_ranks(RunSession& session, const Scene& scene,
                                                           std::span<const Camera> cameras, const ProbeConfig& probe,
                                                           const LogFn& log) {
  std::vector<ProbeTrace> traces(cameras.size());
  const size_t ranks = size_t(cluster::size()), rank = size_t(cluster::rank());
  Status status;
  std::string mine;
  for (size_t i = rank; i < cameras.size() && status; i += ranks) {
    say(log, "view " + std::to_string(i + 1) + "/" + std::to_string(cameras.size()) + ": probe, " +
                 std::to_string(probe.rays) + " test rays");
    Scene view_scene = scene;
    view_scene.camera = cameras[i];
    // No store repair under mpirun: ranks rebuilding a store at once would race.
    auto traced = cluster::active()
                      ? trace_probe(view_scene, session.stores.probe_stores, session.stores.objects, probe)
                      : trace_view(session, view_scene, probe, log);
    status = traced.status();
    if (!status) break;
    if (cluster::active()) mine += cluster::to_bytes(uint64_t(i)) + packed_size(pack_trace(*traced));
    else traces[i] = std::move(traced.value());
    // Every view's hits are held until the shared cut is selected: past the
    // memory limit, stop and say so rather than grow without bound.
    if (const uint64_t rss = current_rss_bytes(); session.budget.limited() && rss > session.budget.total) {
      status = Status::error("--shared-cut holds every view's test-ray hits until the cut is selected: after " +
                             std::to_string(i + 1) + " of " + std::to_string(cameras.size()) + " views this process uses " +
                             format_bytes(rss) + ", more than the memory limit of " + format_bytes(session.budget.total) +
                             "; use fewer views or --rays, raise --memory-limit, or leave out --shared-cut (each "
                             "view then gets its own cut)");
      break;
    }
  }
  RAYLOD_RETURN_IF_ERROR(cluster::agree(status));
  if (!cluster::active()) return traces;
  for (const std::string& part : cluster::allgather(mine))
    for (size_t at = 0; at < part.size();) {
      const uint64_t i = cluster::from_bytes<uint64_t>(part, at), n = cluster::from_bytes<uint64_t>(part, at + 8);
      traces.at(i) = unpack_trace(part.substr(at + 16, n));
      at += 16 + n;
    }
  return traces;
}

StatusOr<ProbeTrace> trace_view_across_ranks(RunSession& session, const Scene& scene, const ProbeConfig& probe,
                                             const LogFn& log) {
  if (!cluster::active()) return trace_view(session, scene, probe, log);
  // No store repair here: ranks rebuilding a store at once would race.
  return trace_probe_across_ranks(scene, session.stores.probe_stores, session.stores.objects, probe);
}

StatusOr<FittedCuts> select_fitting_cuts(RunSession& session, std::span<const ProbeView> views, const Scene& scene,
                                         ProbeConfig probe, const RunOptions& options, const LogFn& log) {
  const SceneStores& stores = session.stores;
  const MemoryBudget& budget = session.budget;
  const uint64_t memory_limit = session.memory_limit;
  FittedCuts fitted;
  uint64_t previous_estimate = UINT64_MAX;
  uint64_t input_triangles = 0;
  for (const auto& st : stores.stores) input_triangles += st->header().triangle_count;
  // The render's need counts its frame (renderer.h, estimate_image_memory);
  // a frame that alone outgrows the limit leaves no cut that helps.
  RenderOptions frame;
  frame.srgb_color = options.srgb_color;  // as render_simplified will render it
  const uint64_t image = estimate_image_memory(scene.camera.width, scene.camera.height, frame);
  if (budget.limited() && image >= memory_limit)
    return Status::error("the " + std::to_string(scene.camera.width) + " x " + std::to_string(scene.camera.height) +
                         " image needs about " + format_bytes(image) + ", more than the " + format_bytes(memory_limit) +
                         " the memory limit of " + format_bytes(budget.total) + " leaves after the program's own " +
                         format_bytes(budget.baseline) + "; render a smaller image or raise --memory-limit");
  // The cells' needs are computed once; each coarsening step only decides.
  RAYLOD_ASSIGN_OR_RETURN(CutSelection selection,
                          CutSelection::make(views, scene, stores.probe_stores, stores.objects, probe));
  for (;;) {
    RAYLOD_ASSIGN_OR_RETURN(fitted.probe, selection.select(probe));
    // What the later stages need: simplifying one store at a time (its mesh
    // under construction, then Draco-encoded) beside the stores' node tables,
    // then rendering all the simplified meshes (the node tables freed).
    uint64_t estimate = 0, simplify_need = 0, node_tables = 0;
    for (size_t i = 0; i < stores.stores.size(); ++i) {
      const SimplifyEstimate e = estimate_simplify(*stores.stores[i], fitted.probe.cuts[i]);
      estimate += e.triangles;
      simplify_need = std::max({simplify_need, e.bytes, e.write_bytes});
      node_tables += stores.stores[i]->header().node_table_bytes;
    }
    simplify_need += node_tables;
    const uint64_t scene_triangles = estimate + 2;  // and the ground's two
    const uint64_t need = std::max(
        simplify_need, image + estimate_render_memory(scene_triangles, bvh_for_memory_limit(
                                                                        scene_triangles,
                                                                        memory_limit > image ? memory_limit - image : 1)));
    if (!budget.limited() || need <= memory_limit) break;
    // Stop once coarsening no longer helps (the estimate bottoms out at the
    // renderer's fixed overhead) or after max_coarsening_steps doublings.
    // While no cell collapses yet (every cell finer than K footprints), the
    // next doubling may still: that is not bottoming out.
    const bool nothing_collapsed = estimate >= input_triangles;
    if (fitted.coarsening_steps >= options.max_coarsening_steps || (estimate >= previous_estimate && !nothing_collapsed))
      return Status::error("even at footprint scale " + fmt("%g", probe.footprint_scale) + " the simplified mesh (" +
                           std::to_string(estimate) + " triangles, " + format_bytes(need) + ") does not fit in the " +
                           format_bytes(memory_limit) + " the memory limit of " + format_bytes(budget.total) +
                           " leaves after the program's own " + format_bytes(budget.baseline));
    previous_estimate = estimate;
    ++fitted.coarsening_steps;
    // Both limits double: under the deviation criterion K alone may not bind.
    say(log, "the simplified mesh would need " + format_bytes(need) + " (about " + std::to_string(estimate) +
                 " triangles), over the " + format_bytes(memory_limit) + " the memory limit leaves" +
                 ": coarsening the cut, footprint scale " + fmt("%g", probe.footprint_scale) + " -> " +
                 fmt("%g", probe.footprint_scale * 2) +
                 (probe.criterion == CutCriterion::Deviation
                      ? ", tolerance " + fmt("%g", probe.tolerance_px) + " -> " + fmt("%g", probe.tolerance_px * 2) +
                            " px (angle " + fmt("%g", probe.angle_tolerance_px) + " -> " +
                            fmt("%g", probe.angle_tolerance_px * 2) + " px)"
                      : std::string()));
    probe.footprint_scale *= 2;
    probe.tolerance_px *= 2;
    probe.angle_tolerance_px *= 2;
  }
  fitted.footprint_scale = probe.footprint_scale;
  return fitted;
}

StatusOr<StagedMeshes> simplify_or_reuse(RunSession& session, const Scene& scene, std::span<const Cut> cuts,
                                         const RunOptions& options, const LogFn& log) {
  SceneStores& stores = session.stores;
  std::optional<SimplifiedCache>& cache = session.cache;
  const uint64_t memory_limit = session.memory_limit;
  StagedMeshes out;
  // This view's entries stay while it inserts its others (SimplifiedCache::hold).
  if (cache) cache->release_held();
  for (size_t i = 0; i < stores.stores.size(); ++i) {
    const Cut& cut = cuts[i];
    SimplifiedMesh sm;
    // The store keeps positions on a grid (page_codec.h); a view that
    // resolves less than twice its error shows the rounding of kept vertices.
    {
      const StoreHeader& h = stores.stores[i]->header();
      const double grid_error = page_grid_max_error(page_grid(h.root_lo, h.root_size, h.grid_bits));
      if (cut.min_footprint > 0 && grid_error > 0.5 * double(cut.min_footprint)) {
        char text[320];
        std::snprintf(text, sizeof text,
                      ": its store keeps positions to within %.3g, and this view resolves %.3g (one pixel): the "
                      "simplified mesh's vertices may show up to %.1f pixels from where they are; `raylod render` "
                      "draws the mesh itself",
                      grid_error, double(cut.min_footprint), grid_error / double(cut.min_footprint));
        session.warnings.push_back(stores.meshes[i].string() + text);
      }
    }
    // Exact normals change the mesh (simplify_cut_to_draco): the cache keeps it apart.
    const int fold_passes = fold_passes_for(scene, stores.objects, i);
    const bool exact_normals = exact_normals_for(fold_passes);
    // The normals' quantisation follows the materials (shading_normal_tolerance):
    // part of the key, so a glossier scene never takes a coarser entry.
    const int normal_bits = choose_normal_bits(shading_normal_tolerance(scene));
    if (cache) {
      const std::string key = SimplifiedCache::key_for(cut, scene.crease_angle_deg, exact_normals, normal_bits);
      std::string note;
      std::optional<CacheEntry> entry = cache->find_exact(key, &note);
      if (entry) {
        note = "cache hit: " + entry->key + " was made for this cut";
      } else {
        if (!note.empty()) say(log, note);
        std::string why;
        entry = cache->find_reusable(cut, draco_error_bound(cut, *stores.stores[i]), &why, scene.crease_angle_deg,
                                     session.reusable ? &*session.reusable : nullptr, exact_normals, normal_bits);
        if (entry) note = "reusing " + entry->key + ": " + why;
      }
      if (entry) {
        cache->touch(*entry);
        cache->hold(entry->key);
        // Render from a link of our own: another run's eviction cannot pull it away.
        auto checkout_to = [&](const fs::path& dir) {
          AtomicOutput tmp(dir / ("cached-" + std::to_string(::getpid()) + "-" + std::to_string(i) + ".drc"));
          sm.drc = tmp.temp_path();
          sm.drc += ".drc";
          out.scratch.add(sm.drc);
          return cache->checkout(*entry, sm.drc);
        };
        Status checked = checkout_to(session.scratch);
        if (!checked.is_ok() && checked.is_write_failure() && session.scratch != temporary_folder()) {
          // A cache this user may read but not write (a shared, read-only
          // one): its entries are used from copies in the system's
          // temporary folder, and what this run simplifies is not cached.
          session.warnings.push_back("cannot write into the cache (" + checked.message() +
                                     "); using its entries from the system's temporary folder");
          session.scratch = temporary_folder();
          checked = checkout_to(session.scratch);
        }
        RAYLOD_RETURN_IF_ERROR(checked);
        sm.triangles = entry->triangles;
        sm.max_position_error = entry->max_position_error;
        sm.position_bits = entry->position_bits;
        sm.cache_hit = true;
        sm.cache_note = note;
      }
    }
    if (!sm.cache_hit) {
      out.cache_hit = false;
      auto staged_in = [&](const fs::path& dir) {
        AtomicOutput tmp(dir / ("simplified-" + std::to_string(::getpid()) + "-" + std::to_string(i) + ".drc"));
        fs::path staged = tmp.temp_path();
        staged += ".drc";
        out.scratch.add(staged);  // removed after rendering, or after a failed write
        return staged;
      };
      fs::path staged = staged_in(session.scratch);
      auto simplify_store = [&] {
        return simplify_cut_to_draco(*stores.stores[i], cut, staged, memory_limit, shading_normal_tolerance(scene),
                                     options.progress, nullptr, scene.crease_angle_deg, fold_passes);
      };
      auto simplified = simplify_store();
      if (!simplified.is_ok() && cache && staged_write_refused(simplified.status(), staged)) {
        // The cache's disk refused the file (full, read-only): render from
        // the system's temporary folder, without caching.
        session.warnings.push_back("cannot write into the cache (" + simplified.status().message() +
                                   "); rendering without caching");
        cache.reset();
        session.scratch = temporary_folder();
        staged = staged_in(session.scratch);
        simplified = simplify_store();
      }
      if (!simplified.is_ok()) {
        RAYLOD_ASSIGN_OR_RETURN(bool retry, repair_corrupt_stores(stores, "simplify", session.repaired, log));
        if (retry && session.pages) session.pages->clear();  // the pages of the replaced store
        if (retry) simplified = simplify_store();
      }
      RAYLOD_ASSIGN_OR_RETURN(sm, std::move(simplified));
      if (sm.folds_left_for_memory)
        session.warnings.push_back(stores.meshes[i].string() + ": " + std::to_string(sm.folds_left_for_memory) +
                                   " triangles stay turned over (they may sparkle through glass or on mirrors): "
                                   "refining their cells would not fit the memory limit; raise --memory-limit");
      if (sm.triangles == 0) {
        // Nothing to cache or render: the object is left out, and the user told why.
        sm.cache_note = "not cached (no triangles)";
        sm.name = stores.meshes[i].filename().string();
        std::string why = sm.empty_reason;
        // Every triangle flat on the store's grid: say how coarse that grid
        // is and what set it (the bounding box, which one stray vertex
        // stretches).
        if (why.find("degenerate") != std::string::npos) {
          const StoreHeader& h = stores.stores[i]->header();
          const Vec3d lo = h.bounds.lo + h.mesh_origin, hi = h.bounds.hi + h.mesh_origin;
          why += " on " + describe_position_grid(page_grid(h.root_lo, h.root_size, h.grid_bits).step, h.bounds,
                                                 h.mesh_origin);
          // A mesh a few float steps across, far from the origin: its own
          // coordinates lost the detail (single precision keeps steps of
          // about 2^-23 of the distance: a millimetre part at 1e6 rounds to
          // a few points in a float32 PLY or STL).
          const double where = std::max({std::abs(lo.x), std::abs(lo.y), std::abs(lo.z), std::abs(hi.x),
                                         std::abs(hi.y), std::abs(hi.z)});
          const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
          if (where > 0 && std::isfinite(where) && extent <= where * 0x1p-16)
            why += "; single-precision coordinates this far from the origin are " +
                   fmt("%.3g", float_spacing_at(where)) + " apart, so a mesh stored as float there loses any smaller detail (write it in double precision, "
                   "or nearer the origin)";
        }
        sm.empty_reason = why;
        session.warnings.push_back(stores.meshes[i].string() + ": " + why + "; it is left out of the image");
        out.meshes.push_back(sm);
        continue;
      }
      // Rendered from the staged file, which lives until after rendering.
      sm.cache_note = options.use_cache ? "simplified; not cached" : "simplified (cache disabled)";
      if (cache) {
        auto entry =
            cache->insert(cut, staged, sm.triangles, sm.max_position_error, scene.crease_angle_deg, exact_normals,
                          normal_bits, sm.position_bits);
        if (!entry.is_ok()) {
          // A full cache disk costs the reuse, not the image.
          session.warnings.push_back("cannot cache the simplified mesh (" + entry.status().message() +
                                     "); rendering without caching");
        } else {
          cache->hold(entry->key);
          std::error_code ec;
          sm.cache_note = fs::is_regular_file(entry->mesh, ec) ? "simplified and cached as " + entry->key
                                                               : "simplified; not cached (larger than the cache limit)";
        }
      }
    }
    std::error_code ec;
    sm.drc_bytes = fs::file_size(sm.drc, ec);
    sm.name = stores.meshes[i].filename().string();
    out.triangles += sm.triangles;
    say(log, stores.meshes[i].filename().string() + ": " + std::to_string(stores.stores[i]->header().triangle_count) +
                 " -> " + std::to_string(sm.triangles) + " triangles; " + sm.cache_note);
    out.meshes.push_back(sm);
  }
  return out;
}

StatusOr<StagedMeshes> simplify_or_reuse_on_ranks(RunSession& session, const Scene& scene, std::span<const Cut> cuts,
                                                  const RunOptions& options, const LogFn& log) {
  if (!cluster::active()) return simplify_or_reuse(session, scene, cuts, options, log);
  StatusOr<StagedMeshes> staged = Status::error("the simplified meshes were not staged");
  RAYLOD_RETURN_IF_ERROR(cluster::rank0_first([&] {
    staged = simplify_or_reuse(session, scene, cuts, options, log);
    return staged.status();
  }));
  return staged;
}

StatusOr<RenderResult> render_simplified(const Scene& scene, std::span<const ProbeObject> objects,
                                         std::span<const SimplifiedMesh> meshes, const RunOptions& options,
                                         uint64_t memory_limit, const LogFn& log, bool split_across_ranks) {
  RenderOptions ro;
  ro.split_across_ranks = split_across_ranks;
  ro.srgb_color = options.srgb_color;
  ro.spp = options.spp;
  ro.memory_limit = memory_limit;
  ro.progress = options.progress;
  ro.log = log;
  ro.warn_about_meshes = false;  // said from the stores (open_run_session), not of the simplified mesh's temporary
  for (const auto& obj : objects) {
    const SimplifiedMesh& sm = meshes[obj.store];
    ro.mesh_override.push_back(sm.drc);
    ro.omit_object.push_back(sm.triangles == 0);
  }
  fault_point("run.render");
  return render(scene, ro);
}

StatusOr<RunResult> run_pipeline(Scene scene, const RunOptions& options, const LogFn& log) {
  RunResult result;
  RAYLOD_ASSIGN_OR_RETURN(RunSession session, open_run_session(scene, options, log));
  result.seconds.build = session.stores.seconds;
  result.triangles_in = session.stores.triangles;

  // B. Probe (A2-A4); if the simplified meshes would not fit the memory
  // limit, coarsen by doubling K until they do. The rays are traced once;
  // coarsening only selects coarser cuts from them.
  say(log, "[2/4] probe: " + std::to_string(options.rays) + " test rays");
  // Under mpirun the ranks agree after each step that can fail on one of them.
  auto probe_config = run_probe_config(session, scene, options);
  RAYLOD_RETURN_IF_ERROR(cluster::agree(probe_config.status()));
  const ProbeConfig probe = probe_config.value();
  auto t_probe = std::chrono::steady_clock::now();
  RAYLOD_ASSIGN_OR_RETURN(ProbeTrace trace, trace_view_across_ranks(session, scene, probe, log));
  const ProbeView view{&trace, scene.camera};
  auto selected = select_fitting_cuts(session, std::span<const ProbeView>(&view, 1), scene, probe, options, log);
  RAYLOD_RETURN_IF_ERROR(cluster::agree(selected.status()));
  FittedCuts fitted = std::move(selected.value());
  result.probe = std::move(fitted.probe);
  result.footprint_scale = fitted.footprint_scale;
  result.coarsening_steps = fitted.coarsening_steps;
  result.cuts = result.probe.cuts;
  result.seconds.probe = seconds_since(t_probe);

  // C. Simplify (A5), or reuse a cached simplified mesh that is fine enough.
  // The probe's page cache is gone: give its memory back to the system, or
  // the allocator's arenas keep it resident beside simplify's.
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
  say(log, "[3/4] simplify");
  auto t_simplify = std::chrono::steady_clock::now();
  RAYLOD_ASSIGN_OR_RETURN(StagedMeshes staged, simplify_or_reuse_on_ranks(session, scene, result.cuts, options, log));
  result.meshes = staged.meshes;
  result.triangles_out = staged.triangles;
  result.cache_hit = staged.cache_hit;
  result.seconds.simplify = seconds_since(t_simplify);
  if (!options.export_mesh.empty()) {
    // Rank 0 writes it (the others' meshes are the same bytes).
    StatusOr<uint64_t> exported = uint64_t(0);
    if (cluster::is_root()) exported = export_simplified_glb(options.export_mesh, result.meshes, session.stores);
    RAYLOD_RETURN_IF_ERROR(cluster::agree(exported.status()));
    result.exported_bytes = exported.value();
    say(log, "exported the simplified meshes to " + options.export_mesh.string() + " (" + format_bytes(result.exported_bytes) + ")");
  }

  // D. Render the simplified meshes. The stores' node tables and the trace
  // are not needed any more: the render gets their memory.
  session.stores.probe_stores.clear();
  session.stores.stores.clear();
  trace = ProbeTrace{};
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
  // Every object left out and no ground: nothing to render, and the
  // reasons (each mesh's empty_reason) are the error, which the run's
  // warnings would otherwise not reach.
  if (!scene.ground && std::all_of(result.meshes.begin(), result.meshes.end(),
                                   [](const SimplifiedMesh& sm) { return sm.triangles == 0; })) {
    std::string why;
    for (size_t i = 0; i < result.meshes.size(); ++i)
      why += (i ? "; " : ": ") + session.stores.meshes[i].string() + ": " + result.meshes[i].empty_reason;
    return Status::error("nothing to render: every object is left out" + why);
  }
  say(log, "[4/4] render");
  auto t_render = std::chrono::steady_clock::now();
  RAYLOD_ASSIGN_OR_RETURN(result.render, render_simplified(scene, session.stores.objects, result.meshes, options,
                                                           session.memory_limit, log, /*split_across_ranks=*/true));
  result.seconds.render = seconds_since(t_render);
  result.peak_rss = peak_rss_bytes();
  result.warnings = session.warnings;
  return result;
}

std::string run_stats_json(const RunResult& r, const RunOptions& options) {
  nlohmann::json j;
  j["triangles_in"] = r.triangles_in;
  j["triangles_out"] = r.triangles_out;
  j["reduction"] = r.triangles_out ? double(r.triangles_in) / double(r.triangles_out) : 0.0;
  j["seconds"] = {{"build", r.seconds.build}, {"probe", r.seconds.probe}, {"simplify", r.seconds.simplify},
                  {"render", r.seconds.render}, {"total", r.seconds.total()}};
  j["peak_rss_bytes"] = r.peak_rss;
  j["cache_hit"] = r.cache_hit;
  j["footprint_scale"] = r.footprint_scale;
  j["footprint_scale_requested"] = options.footprint_scale;
  j["coarsening_steps"] = r.coarsening_steps;
  j["rays"] = options.rays;
  nlohmann::json meshes = nlohmann::json::array();
  for (const auto& m : r.meshes)
    meshes.push_back({{"mesh", m.name}, {"triangles", m.triangles}, {"drc_bytes", m.drc_bytes},
                      {"position_bits", m.position_bits}, {"max_position_error", m.max_position_error},
                      {"cache_hit", m.cache_hit}, {"cache_note", m.cache_note}});
  j["meshes"] = meshes;
  j["probe_counters"] = r.probe.counters;
  j["warnings"] = r.warnings;
  j["render"] = nlohmann::json::parse(render_stats_json(r.render.stats));
  return j.dump(2) + "\n";
}

}  // namespace raylod
