// The render driver: meshes -> memory check -> Embree BVH -> parallel tiles
// -> image files. Determinism: every pixel draws its samples from its own
// generator seeded by (scene seed, pixel), and sums them in a fixed order, so
// the image does not depend on the thread count or the tile schedule.
#include "render/renderer.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <mutex>
#include <optional>

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_for_each.h>
#include <glm/gtc/matrix_transform.hpp>

#include "core/cluster.h"
#include "core/fault_point.h"
#include "core/parallelism.h"
#include "core/progress.h"
#include "core/random.h"
#include "core/system.h"
#include "render/image_codec.h"
#include "render/srgb.h"
#include "scene/mesh_framing.h"
#include "scene/scene_camera.h"
#include "streaming/mesh_reader.h"

namespace raylod {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}


// The per-pixel generator's start state: a hash of the scene seed and the pixel.
uint64_t pixel_state(uint64_t seed, int x, int y) {
  uint64_t s = seed ^ 0x5851f42d4c957f2dull;
  splitmix64(s);
  s ^= (uint64_t(uint32_t(y)) << 32) | uint32_t(x);
  splitmix64(s);
  return s;
}

// spp = sx * sy strata, as square as the divisors of spp allow.
void strata(int spp, int& sx, int& sy) {
  sx = 1;
  for (int d = 1; d * d <= spp; ++d)
    if (spp % d == 0) sx = d;
  sy = spp / sx;
}

}  // namespace

namespace {

// path's extension in lower case (".PNG" -> ".png"): what formats are told by.
std::string lower_case_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  return ext;
}

}  // namespace

bool is_float_image_format(const std::filesystem::path& path) {
  const std::string ext = lower_case_extension(path);
  return ext == ".exr" || ext == ".hdr" || ext == ".tif" || ext == ".tiff" || ext == ".pfm";
}

namespace {

// A device or FIFO without an extension (`-o /dev/null`, a pipe) takes a
// PNG: the name has no format to give, and the bytes only pass through.
bool is_extensionless_device(const std::filesystem::path& path) {
  return !path.has_extension() && is_pass_through_output(path);
}

// What the image codec chooses the writer from: the file name, or the
// format for an extensionless device.
std::string image_writer_for(const std::filesystem::path& path) {
  return is_extensionless_device(path) ? std::string("png") : path.string();
}

// Encodes the pixels (request.layout, request.pixels) through the image
// codec under a temporary name, then renames it into place, or with a batch
// leaves the rename to the batch's commit. Some writers (libpng's, on a full
// disk) report success for a truncated file, so a file is kept only if it
// decodes to the image that was written; on any failure the temporary is
// removed and the destination left as it was.
Status write_pixels(const std::filesystem::path& path, EncodeRequest request, ImageBatch* batch) {
  RAYLOD_ASSIGN_OR_RETURN(const ImageCodec* codec, image_codec());
  // Made first so that it outlives the writer: a writer that still holds
  // the temporary open closes it before the temporary is removed.
  auto staged = std::make_unique<AtomicOutput>(path);
  AtomicOutput& atomic = *staged;
  // The writer is chosen from the destination's name; the temporary name
  // ("out.png.tmp-...") is then only the file it writes to.
  request.writer = image_writer_for(path);
  request.file = atomic.temp_path().string();
  const Encoded encoded = codec->encode(request);
  if (!encoded.error.empty()) return Status::error(path.string() + ": " + encoded.error);
  if (encoded.in_memory) {
    RAYLOD_RETURN_IF_ERROR(write_temporary(
        atomic, std::string_view(reinterpret_cast<const char*>(encoded.bytes.data()), encoded.bytes.size())));
    // Every byte went through the checked write above; the file must hold
    // all of them (commit's fsync then reports what the disk refuses).
    std::error_code ec;
    if (std::filesystem::file_size(atomic.temp_path(), ec) != encoded.bytes.size() || ec)
      return Status::error(path.string() + ": write failed: the file is shorter than the encoded image (disk full?)");
  } else {
    // A writer that wrote the file itself is read back: it must decode
    // whole, with the size written (some writers report success for a file
    // cut short). An image encoded in memory was checked byte for byte
    // above, and is not decoded again (for a 3840 x 2160 PNG that took 0.2 s).
    const Decoded back = codec->decode(atomic.temp_path().string());
    if (back.layout.width == 0 && !back.error.empty())
      return Status::error(path.string() + ": the written image cannot be read back (disk full?): " + back.error);
    if (back.layout.width != request.layout.width || back.layout.height != request.layout.height ||
        back.layout.channels != request.layout.channels)
      return Status::error(path.string() + ": the written image reads back as " + std::to_string(back.layout.width) +
                           " x " + std::to_string(back.layout.height) + " with " + std::to_string(back.layout.channels) +
                           " channels, not the " + std::to_string(request.layout.width) + " x " +
                           std::to_string(request.layout.height) + " with " + std::to_string(request.layout.channels) +
                           " written (the format cannot hold this image, or the disk is full)");
    if (!back.error.empty()) return Status::error(path.string() + ": the written image is truncated (disk full?): " + back.error);
  }
  if (fault_point("image.before_rename"))
    return Status::error(path.string() + ": could not rename into place: failed at fault point image.before_rename");
  if (batch) {
    batch->add(std::move(staged));
    return {};
  }
  return atomic.commit();
}

}  // namespace

std::string render_stats_json(const RenderStats& s) {
  nlohmann::json j;
  j["width"] = s.width;
  j["height"] = s.height;
  j["spp"] = s.spp;
  j["threads"] = s.threads;
  j["triangles"] = s.triangles;
  j["vertices"] = s.vertices;
  j["effects"] = {{"lights", s.effects.lights}, {"diffuse", s.effects.diffuse}, {"glossy", s.effects.glossy},
                  {"shadows", s.effects.shadows}, {"reflection", s.effects.reflection},
                  {"refraction", s.effects.refraction}};
  j["rays"] = {{"camera", s.rays.camera}, {"shadow", s.rays.shadow}, {"reflection", s.rays.reflection},
               {"refraction", s.rays.refraction}, {"total", s.rays.total()}};
  j["seconds"] = {{"load", s.load_seconds}, {"bvh", s.bvh_seconds}, {"render", s.render_seconds}};
  j["rays_per_second"] = s.rays_per_second();
  j["bytes"] = {{"estimated", s.estimated_bytes}, {"mesh", s.mesh_bytes}, {"bvh", s.bvh_bytes},
                {"bvh_build_peak", s.bvh_peak_bytes}, {"peak_rss", s.peak_rss}};
  j["bvh_quality"] = s.bvh_quality;
  return j.dump(2);
}

// Per triangle: the welded mesh arrays (12 B of indices plus ~0.5 vertices
// of 24 B with normals, and vector slack; measured 34-36 B) and Embree's
// allocation peak during the build (BVH plus the builder's temporary
// primitive references). Measured with tools/bench_render on the teapots:
// high quality (1M) 99 B, medium (10M) 119 B, medium+compact (30M) 38 B,
// low (10M) 103 B, low+compact (30M) 58 B per triangle; rounded up here so
// the check errs on the side of refusing.
uint64_t estimate_render_memory(uint64_t triangles, const BvhConfig& config) {
  const double mesh = 40.0;
  const bool compact = triangles >= config.compact_from;
  double bvh = 130.0;                                        // medium or low quality
  if (triangles < config.high_quality_below) bvh = 110.0;    // spatial splits, smaller scenes
  else if (compact) bvh = choose_bvh_quality(triangles, config) == BvhQuality::Low ? 65.0 : 50.0;  // index-only leaves
  return uint64_t(16ull << 20) + uint64_t(double(triangles) * (mesh + bvh));
}

uint64_t estimate_image_memory(int width, int height, const RenderOptions& options) {
  const uint64_t per_pixel = (options.srgb_color ? 6 : 18) + (options.aov_depth ? 8 : 0) + (options.aov_normal ? 15 : 0) +
                             (options.aov_triangle_id ? 8 : 0);
  return uint64_t(std::max(width, 0)) * uint64_t(std::max(height, 0)) * per_pixel;
}

BvhConfig smallest_bvh_layout(BvhConfig config) {
  config.high_quality_below = 0;
  config.compact_from = 0;
  config.camera_rays = 0;  // the medium builder, whose compact build peaks lower than the low one's
  return config;
}

BvhConfig bvh_for_memory_limit(uint64_t triangles, uint64_t limit, BvhConfig config) {
  if (limit == 0 || estimate_render_memory(triangles, config) <= limit) return config;
  BvhConfig compact = config;
  compact.high_quality_below = 0;
  compact.compact_from = 0;
  if (estimate_render_memory(triangles, compact) <= limit) return compact;
  const BvhConfig smallest = smallest_bvh_layout(config);
  return estimate_render_memory(triangles, smallest) <= limit ? smallest : config;
}

uint64_t triangles_that_fit(uint64_t bytes, const BvhConfig& config) {
  // With the layout bvh_for_memory_limit picks, the estimate grows with the
  // count, so bisect for the largest count that fits.
  auto fits = [&](uint64_t n) { return estimate_render_memory(n, bvh_for_memory_limit(n, bytes, config)) <= bytes; };
  if (!fits(0)) return 0;
  uint64_t lo = 0, hi = uint64_t(1) << 40;
  while (lo < hi) {
    const uint64_t mid = lo + (hi - lo + 1) / 2;
    if (fits(mid)) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

namespace {

// Whether any triangle has a non-zero area (stops at the first).
bool has_area(const TriangleMesh& m) {
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const Vec3d a(m.positions[m.indices[t]]), b(m.positions[m.indices[t + 1]]), c(m.positions[m.indices[t + 2]]);
    { const Vec3d n = glm::cross(b - a, c - a); if (glm::dot(n, n) > 0) return true; }
  }
  return false;
}

// The mesh file of each object (empty for objects left out), and the
// triangles the files declare, the ground's included.
struct ScenePaths {
  std::vector<std::filesystem::path> paths;
  uint64_t declared = 0;
};

StatusOr<ScenePaths> scene_mesh_paths(const Scene& scene, const RenderOptions& options) {
  if (options.mesh_override.size() > scene.objects.size())
    return Status::error(std::to_string(options.mesh_override.size()) + " replacement meshes given, but the scene has " +
                         std::to_string(scene.objects.size()) + " object(s)");
  ScenePaths out;
  out.declared = scene.ground ? 2 : 0;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    if (i < options.omit_object.size() && options.omit_object[i]) {
      out.paths.emplace_back();
      continue;
    }
    std::filesystem::path p = scene.objects[i].mesh;
    if (i < options.mesh_override.size() && !options.mesh_override[i].empty()) p = options.mesh_override[i];
    if (p.empty()) {
      const auto& g = scene.objects[i].generate;
      return Status::error("objects[" + std::to_string(i) + "]: the generated mesh" +
                           (g ? " '" + g->generator + "' (" + std::to_string(g->triangles) + " triangles)" : std::string()) +
                           " has not been generated yet (resolve_generated_meshes)");
    }
    RAYLOD_ASSIGN_OR_RETURN(uint64_t n, declared_triangle_count(p));
    out.declared += n;
    out.paths.push_back(p);
  }
  return out;
}

}  // namespace

StatusOr<uint64_t> declared_scene_triangles(const Scene& scene, const RenderOptions& options) {
  RAYLOD_ASSIGN_OR_RETURN(ScenePaths sp, scene_mesh_paths(scene, options));
  return sp.declared;
}

Scene in_render_frame(const Scene& scene) {
  Scene s = scene;
  // A scene built in code rather than parsed has none: a reader's local
  // origin rule (from 4096 units out) from its camera, which leaves meshes
  // built in the world frame near zero where they are.
  const Vec3d r = scene.render_origin != Vec3d(0) ? scene.render_origin : local_origin_for(scene.camera.look_at);
  if (r == Vec3d(0)) return s;
  s.camera.eye -= r;
  s.camera.look_at -= r;
  for (Light& light : s.lights) light.position -= r;  // directional lights ignore it
  if (s.ground) s.ground->height -= r.y;
  const glm::dmat4 shift = glm::translate(glm::dmat4(1.0), -r);
  for (SceneObject& o : s.objects) o.transform = shift * o.transform;
  s.render_origin = Vec3d(0);
  return s;
}

StatusOr<std::vector<TriangleMesh>> load_scene_meshes(const Scene& world_scene, const RenderOptions& options,
                                                      RenderStats& stats, BvhConfig* bvh) {
  const Scene scene = in_render_frame(world_scene);
  const auto start = std::chrono::steady_clock::now();
  RAYLOD_ASSIGN_OR_RETURN(ScenePaths sp, scene_mesh_paths(scene, options));
  const std::vector<std::filesystem::path>& paths = sp.paths;
  const uint64_t declared = sp.declared;
  auto omitted = [&](size_t i) { return paths[i].empty(); };
  BvhConfig wanted = options.bvh;
  if (wanted.camera_rays == 0)
    wanted.camera_rays = uint64_t(scene.camera.width) * uint64_t(scene.camera.height) *
                         uint64_t(options.spp > 0 ? options.spp : scene.spp);
  // The frame first: what it leaves is the mesh's and the BVH's.
  const uint64_t image = estimate_image_memory(scene.camera.width, scene.camera.height, options);
  if (options.memory_limit > 0 && image >= options.memory_limit)
    return Status::error("the " + std::to_string(scene.camera.width) + " x " + std::to_string(scene.camera.height) +
                         " image" + (options.aov_depth || options.aov_normal || options.aov_triangle_id ? " and its AOVs need" : " needs") +
                         " about " + format_bytes(image) + ", more than the memory limit of " +
                         format_bytes(options.memory_limit) + "; render a smaller image or raise --memory-limit");
  const uint64_t mesh_limit = options.memory_limit > 0 ? options.memory_limit - image : 0;
  const BvhConfig chosen = bvh_for_memory_limit(declared, mesh_limit, wanted);
  if (bvh) *bvh = chosen;
  stats.estimated_bytes = estimate_render_memory(declared, chosen) + image;
  if (options.memory_limit > 0 && stats.estimated_bytes > options.memory_limit) {
    // The least any layout needs (bvh_for_memory_limit's last resort), not
    // the default layout it returns when nothing fits.
    return Status::error("the scene has " + std::to_string(declared) + " triangles, which need about " +
                         format_bytes(estimate_render_memory(declared, smallest_bvh_layout(wanted))) +
                         " for the mesh and its BVH (compact layout), and the image " + format_bytes(image) +
                         ", more than the memory limit of " + format_bytes(options.memory_limit) + "; about " +
                         std::to_string(triangles_that_fit(mesh_limit, options.bvh)) + " triangles would fit." +
                         (options.over_limit_hint.empty() ? std::string() : " " + options.over_limit_hint));
  }
  if (options.log && chosen.compact_from != options.bvh.compact_from && declared < options.bvh.compact_from)
    options.log("the compact BVH layout is used to fit the memory limit of " + format_bytes(options.memory_limit));

  if (options.log && options.memory_limit == 0 && stats.estimated_bytes > physical_memory_bytes())
    options.log("warning: the scene needs about " + format_bytes(stats.estimated_bytes) + " for " +
                std::to_string(declared) + " triangles, more than this machine's " +
                format_bytes(physical_memory_bytes()) + " of memory; consider `raylod run`");
  std::vector<TriangleMesh> meshes;
  std::optional<Progress> progress;
  if (options.progress) progress.emplace("load", declared, "triangles");
  for (size_t i = 0; i < paths.size(); ++i) {
    if (omitted(i)) {
      TriangleMesh none;
      none.material = scene.objects[i].material;
      none.name = "objects[" + std::to_string(i) + "] (left out)";
      meshes.push_back(std::move(none));
      continue;
    }
    auto mesh = load_triangle_mesh(paths[i], scene.objects[i].transform, scene.objects[i].material, scene.crease_angle_deg,
                                   [&](uint64_t n) { if (progress) progress->advance(n); });
    // Which of the scene's objects, where the scene has several.
    if (!mesh)
      return Status::error(object_context(scene, i) + mesh.status().message());
    if (options.log && options.warn_about_meshes && !has_area(*mesh))
      options.log("warning: " + paths[i].string() + ": all " + std::to_string(mesh->triangle_count()) +
                  " triangles are degenerate (zero area or repeated corners); nothing of it is rendered");
    if (options.log && options.warn_about_meshes) {
      Bbox world;
      for (const Vec3& p : mesh->positions) world.expand(p);
      if (const std::string problem = size_problem(world); !problem.empty())
        options.log("warning: " + paths[i].string() + " " + problem);
    }
    meshes.push_back(std::move(mesh.value()));
  }
  if (progress) progress->finish();
  if (scene.ground) meshes.push_back(make_ground_mesh(*scene.ground, scene.camera));
  stats.load_seconds = seconds_since(start);
  return meshes;
}

namespace {

// A frame's tiles (RenderOptions::tile_size, row-major) and the runs they are
// cut into (RenderOptions::tile_runs, at least one and at most one a tile).
struct TileGrid {
  int tile = 1, tiles_x = 0;
  uint64_t tiles = 0, runs = 1;
};
TileGrid tile_grid(int width, int height, const RenderOptions& options) {
  TileGrid g;
  g.tile = std::max(1, options.tile_size);
  g.tiles_x = (width + g.tile - 1) / g.tile;
  g.tiles = uint64_t(g.tiles_x) * uint64_t((height + g.tile - 1) / g.tile);
  g.runs = std::clamp<uint64_t>(uint64_t(std::max(1, options.tile_runs)), 1, std::max<uint64_t>(g.tiles, 1));
  return g;
}

}  // namespace

RenderResult render_embree_scene(const EmbreeScene& geometry, const Scene& world_scene, const RenderOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const Scene scene = in_render_frame(world_scene);
  const int width = scene.camera.width, height = scene.camera.height;
  const PinholeCamera camera = make_pinhole_camera(scene.camera);
  std::vector<int> used;
  for (const auto& m : geometry.meshes())
    if (m.triangle_count() > 0) used.push_back(m.material);
  const Effects effects = effects_for(scene, used);
  IntegratorConfig config = options.integrator;
  config.max_depth = scene.max_depth;
  // Offsets scale with objects smaller than a unit (IntegratorConfig::offset_floor);
  // the ground plane, as large as the scene file says, does not count.
  if (const Bbox& objects = geometry.info().object_bounds; !objects.empty()) {
    const Vec3d e = objects.extent();
    const double size = std::max({e.x, e.y, e.z});
    if (size > 0 && size < config.offset_floor) config.offset_floor = size;
  }
  config.wireframe = options.wireframe;
  const Integrator integrator(geometry, scene, camera, effects, config);
  const int spp = options.spp > 0 ? options.spp : scene.spp;
  int sx, sy;
  strata(spp, sx, sy);

  RenderResult result;
  if (options.srgb_color) result.srgb = SrgbImage(width, height, 3);
  else result.color = Image(width, height, 3);
  if (options.aov_depth) result.depth = Image(width, height, 1);
  if (options.aov_normal) result.normal = Image(width, height, 3);
  if (options.aov_triangle_id) result.triangle_id.assign(size_t(width) * height, kNoTriangle);

  const auto [tile, tiles_x, tiles, runs] = tile_grid(width, height, options);
  std::optional<Progress> progress;
  if (options.progress) progress.emplace("render", options.next_tile_run ? 0 : tiles, "tiles");
  std::mutex counters_mutex;
  RayCounters counters;
  // Work items: a tile, or "take the next run" (tile == kFetch). Taking a
  // run queues the next fetch, then the run's tiles: the thread that took it
  // renders them in order (the last queued first), and an idle thread steals
  // the oldest item, the fetch, so the next run is asked for only when a
  // thread has nothing left to do.
  constexpr uint64_t kFetch = UINT64_MAX;
  std::mutex fetch_mutex;
  uint64_t whole_frame_next = 0;
  auto fetch = [&](tbb::feeder<uint64_t>& feeder) {
    std::optional<uint64_t> k;
    {
      std::lock_guard<std::mutex> lock(fetch_mutex);
      if (options.next_tile_run) k = options.next_tile_run();
      else if (whole_frame_next < runs) k = whole_frame_next++;
      if (!k || *k >= runs) return;
      result.tile_runs.push_back(*k);
    }
    feeder.add(kFetch);
    const auto [first, last] = tile_run_bounds(tiles, runs, *k);
    for (uint64_t t = last; t-- > first;) feeder.add(t);
  };
  const uint64_t start_items[] = {kFetch};
  tbb::parallel_for_each(std::begin(start_items), std::end(start_items), [&](uint64_t item, tbb::feeder<uint64_t>& feeder) {
    if (item == kFetch) {
      fetch(feeder);
      return;
    }
    RayCounters local;
    {
      const int t = int(item);
      const int x0 = (t % tiles_x) * tile, y0 = (t / tiles_x) * tile;
      const int x1 = std::min(width, x0 + tile), y1 = std::min(height, y0 + tile);
      // 4x4 pixel blocks (clipped to the tile): sample s of every pixel of a
      // block is one camera packet. Each pixel keeps its own random stream,
      // so the image does not depend on the blocking (nor on threads).
      // Packets are pipelined: packet j + 1 is traced (and its triangles'
      // indices prefetched) before packet j is shaded, and its vertices are
      // prefetched before packet j + 2 is traced.
      constexpr int kBlock = 4, kLanes = EmbreeScene::kPacketSize;
      static_assert(kBlock * kBlock == kLanes);
      struct Block {
        int x0 = 0, y0 = 0, w = 0, n = 0;
        uint64_t state[kLanes];
        Vec3 sum[kLanes];
        CameraSample first[kLanes];
      };
      struct Job {
        int block = -1, s = 0;
        glm::dvec2 pos[kLanes];
        Integrator::CameraPacket packet;
      };
      Block blocks[2];  // block b in blocks[b % 2]: the one being traced and the one still being shaded
      Job jobs[2];
      int pending = -1;  // index into jobs of the traced, unshaded job
      CameraSample cs[kLanes];
      auto shade = [&](Job& job) {
        Block& blk = blocks[job.block % 2];
        if (options.camera_packets) {
          integrator.shade_camera_packet(job.packet, cs, local);
        } else {
          for (int i = 0; i < blk.n; ++i) cs[i] = integrator.sample(job.pos[i].x, job.pos[i].y, local);
        }
        for (int i = 0; i < blk.n; ++i) {
          blk.sum[i] += cs[i].color;
          if (job.s == 0) blk.first[i] = cs[i];
        }
        if (job.s != spp - 1) return;
        for (int i = 0; i < blk.n; ++i) {
          const int x = blk.x0 + i % blk.w, y = blk.y0 + i / blk.w;
          const Vec3 mean = blk.sum[i] / float(spp);
          if (options.srgb_color) {
            uint8_t* c = result.srgb.at(x, y);
            c[0] = srgb_byte(mean.x); c[1] = srgb_byte(mean.y); c[2] = srgb_byte(mean.z);
          } else {
            float* c = result.color.at(x, y);
            c[0] = mean.x; c[1] = mean.y; c[2] = mean.z;
          }
          // AOVs come from the pixel's first sample (no blending across edges).
          const CameraSample& f = blk.first[i];
          if (options.aov_depth) *result.depth.at(x, y) = f.hit ? float(f.depth) : 0.0f;
          if (options.aov_normal) {
            float* nrm = result.normal.at(x, y);
            nrm[0] = f.normal.x; nrm[1] = f.normal.y; nrm[2] = f.normal.z;
          }
          if (options.aov_triangle_id && f.hit)
            result.triangle_id[size_t(y) * width + x] = uint32_t(std::min<uint64_t>(f.triangle, kNoTriangle - 1));
        }
      };
      int b = 0;
      for (int by = y0; by < y1; by += kBlock) {
        for (int bx = x0; bx < x1; bx += kBlock, ++b) {
          Block& blk = blocks[b % 2];
          blk.x0 = bx;
          blk.y0 = by;
          blk.w = std::min(x1, bx + kBlock) - bx;
          blk.n = blk.w * (std::min(y1, by + kBlock) - by);
          for (int i = 0; i < blk.n; ++i) {
            blk.state[i] = pixel_state(scene.seed, bx + i % blk.w, by + i / blk.w);
            blk.sum[i] = Vec3(0.0f);
          }
          // Stratified jittered samples: one in each of the sx * sy cells.
          for (int s = 0; s < spp; ++s) {
            Job& job = jobs[pending == 0 ? 1 : 0];
            job.block = b;
            job.s = s;
            for (int i = 0; i < blk.n; ++i) {
              const double jx = uniform01(blk.state[i]), jy = uniform01(blk.state[i]);
              job.pos[i] = glm::dvec2(bx + i % blk.w + ((s % sx) + jx) / sx, by + i / blk.w + ((s / sx) + jy) / sy);
            }
            if (options.camera_packets) integrator.trace_camera_packet({job.pos, size_t(blk.n)}, job.packet, local);
            if (pending >= 0) shade(jobs[pending]);
            // This packet's indices arrived while the previous one was
            // shaded; its vertices arrive while the next one is traced.
            if (options.camera_packets) integrator.prefetch_camera_vertices(job.packet);
            pending = int(&job - jobs);
          }
        }
      }
      if (pending >= 0) shade(jobs[pending]);
      if (progress) progress->advance(1);
    }
    std::lock_guard<std::mutex> lock(counters_mutex);
    counters += local;
  });
  if (progress) progress->finish();
  std::sort(result.tile_runs.begin(), result.tile_runs.end());

  RenderStats& st = result.stats;
  st.rays = counters;
  st.effects = effects;
  st.width = width;
  st.height = height;
  st.spp = spp;
  st.threads = ambient_parallelism();
  const BvhInfo& info = geometry.info();
  st.triangles = info.triangles;
  st.vertices = info.vertices;
  st.mesh_bytes = info.mesh_bytes;
  st.bvh_bytes = info.bvh_bytes;
  st.bvh_peak_bytes = info.bvh_peak_bytes;
  st.bvh_quality = info.quality;
  st.bvh_seconds = info.build_seconds;
  st.render_seconds = seconds_since(start);
  st.peak_rss = peak_rss_bytes();
  return result;
}

namespace {

// Under mpirun: every rank's tiles and ray counters, gathered into rank 0's
// result. Rank 0 learns which runs of tiles each rank rendered; then each
// image goes straight from a rank's buffer into the same rows of rank 0's
// (cluster::gather_blocks, no packing): on a 3840 x 2160 frame over 2 ranks,
// packing each rank's rows into one string, gathering the strings and
// unpacking them took about 0.2 s after the last rank's trace; this takes
// 0.03 s.
void gather_tiles(RenderResult& result, const RenderOptions& options) {
  const int width = result.stats.width, height = result.stats.height;
  const auto [tile, tiles_x, tiles, runs] = tile_grid(width, height, options);
  std::string mine(result.tile_runs.size() * sizeof(uint64_t), '\0');
  if (!mine.empty()) std::memcpy(mine.data(), result.tile_runs.data(), mine.size());
  const std::vector<std::string> runs_of = cluster::gather(mine);
  // Rank r's tiles' rows in order, as runs of pixels.
  auto rows_of = [&](int r) {
    const std::string& list = cluster::is_root() ? runs_of[size_t(r)] : mine;
    std::vector<cluster::Block> rows;
    for (size_t i = 0; i + sizeof(uint64_t) <= list.size(); i += sizeof(uint64_t)) {
      const auto [first, last] = tile_run_bounds(tiles, runs, cluster::from_bytes<uint64_t>(list, i));
      for (uint64_t t = first; t < last; ++t) {
        const int x0 = int(t % uint64_t(tiles_x)) * tile, y0 = int(t / uint64_t(tiles_x)) * tile;
        const int n = std::min(width, x0 + tile) - x0;
        for (int y = y0; y < std::min(height, y0 + tile); ++y) rows.push_back({uint64_t(y) * width + x0, uint64_t(n)});
      }
    }
    std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    return rows;
  };
  for (Image* im : {&result.color, &result.depth, &result.normal})
    if (!im->empty()) cluster::gather_blocks(im->pixels.data(), sizeof(float) * size_t(im->channels), rows_of);
  if (!result.srgb.empty()) cluster::gather_blocks(result.srgb.pixels.data(), size_t(result.srgb.channels), rows_of);
  if (!result.triangle_id.empty()) cluster::gather_blocks(result.triangle_id.data(), sizeof(uint32_t), rows_of);
  const std::vector<std::string> parts = cluster::gather(cluster::to_bytes(result.stats.rays));
  if (!cluster::is_root()) return;
  RayCounters total;
  for (const std::string& part : parts) total += cluster::from_bytes<RayCounters>(part);
  result.stats.rays = total;
  result.tile_runs.resize(runs);
  for (uint64_t k = 0; k < runs; ++k) result.tile_runs[k] = k;
}

}  // namespace

std::pair<uint64_t, uint64_t> tile_run_bounds(uint64_t tiles, uint64_t runs, uint64_t k) {
  const uint64_t base = tiles / runs, extra = tiles % runs;
  const uint64_t first = k * base + std::min(k, extra);
  return {first, first + base + (k < extra ? 1 : 0)};
}

StatusOr<RenderResult> render(const Scene& scene, const RenderOptions& options) {
  auto log = [&](const std::string& m) { if (options.log) options.log(m); };
  // Under mpirun every rank loads the scene and builds its BVH; the ranks
  // agree after each step, so one rank's failure ends all of them cleanly.
  const bool split = options.split_across_ranks && cluster::active();
  auto agreed = [&](const Status& s) { return split ? cluster::agree(s) : s; };

  RenderStats load_stats;
  BvhConfig bvh;
  auto loaded = load_scene_meshes(scene, options, load_stats, &bvh);
  RAYLOD_RETURN_IF_ERROR(agreed(loaded.status()));
  auto meshes = std::move(loaded.value());
  uint64_t tris = 0;
  for (const auto& m : meshes) tris += m.triangle_count();
  log("loaded " + std::to_string(tris) + " triangles in " + std::to_string(load_stats.load_seconds) + " s");
  auto built = EmbreeScene::build(std::move(meshes), bvh);
  RAYLOD_RETURN_IF_ERROR(agreed(built.status()));
  auto geometry = std::move(built.value());
  const BvhInfo& info = geometry->info();
  log("BVH (" + info.quality + " quality): " + format_bytes(info.bvh_bytes) + ", built in " +
      std::to_string(info.build_seconds) + " s; mesh arrays " + format_bytes(info.mesh_bytes));
  {
    std::vector<int> used;
    for (const auto& m : geometry->meshes()) used.push_back(m.material);
    log("effects on: " + effects_for(scene, used).describe());
  }
  if (options.before_trace) RAYLOD_RETURN_IF_ERROR(agreed(options.before_trace()));
  RenderOptions tiles = options;
  std::optional<cluster::WorkQueue> queue;
  std::optional<Progress> progress;
  if (split) {
    // About kRunsPerRank runs a rank: the last run handed out, which a rank
    // may still be rendering when the others are done, is a small part of
    // the frame. A rank asks for its next run while it renders one
    // (ask_ahead): on the 4K frame below, 48 and 200 runs a rank took as
    // long, 12 longer (README, "Running on a cluster").
    constexpr int kRunsPerRank = 48;
    tiles.tile_runs = kRunsPerRank * cluster::size();
    tiles.tile_runs = int(tile_grid(scene.camera.width, scene.camera.height, tiles).runs);  // at most one a tile
    queue.emplace(uint64_t(tiles.tile_runs), /*ask_ahead=*/true);
    if (options.progress && cluster::is_root()) progress.emplace("render", uint64_t(tiles.tile_runs), "runs of tiles started");
    tiles.progress = false;
    tiles.next_tile_run = [&] {
      std::optional<uint64_t> k = queue->next();
      if (progress) progress->set(queue->handed_out());
      return k;
    };
  }
  const auto t_trace = std::chrono::steady_clock::now();
  RenderResult result = render_embree_scene(*geometry, scene, tiles);
  if (split) {
    queue.reset();
    if (progress) progress->finish();
    gather_tiles(result, tiles);
    result.stats.render_seconds = seconds_since(t_trace);  // the whole frame's, gathering included
  }
  result.stats.load_seconds = load_stats.load_seconds;
  result.stats.estimated_bytes = load_stats.estimated_bytes;
  result.stats.peak_rss = peak_rss_bytes();
  return result;
}

namespace {

// An 8-bit sRGB image to an 8-bit format.
Status write_srgb_bytes(const std::filesystem::path& path, int width, int height, int channels, const uint8_t* bytes,
                        ImageBatch* batch) {
  EncodeRequest request;
  request.layout = {width, height, channels, PixelType::UInt8};
  request.pixels = bytes;
  request.srgb = true;
  // PNG rows unfiltered (libpng's PNG_FILTER_NONE) rather than libpng's
  // per-row choice among all five filters: on raylod's renders (default,
  // glass, wireframe and difference images) the files came out 3 to 13%
  // smaller and were written 1.7 to 2.7 times faster (a 3840 x 2160 frame:
  // 0.32 -> 0.12 s, 822 -> 741 KB). Other writers ignore the attribute.
  constexpr int kPngFilterNone = 0x08;
  request.png_filter = kPngFilterNone;
  return write_pixels(path, std::move(request), batch);
}

}  // namespace

Status ImageBatch::commit() {
  for (auto& output : staged_) RAYLOD_RETURN_IF_ERROR(output->commit());
  staged_.clear();
  return {};
}

ImageBatch::~ImageBatch() = default;

void ImageBatch::add(std::unique_ptr<AtomicOutput> staged) { staged_.push_back(std::move(staged)); }

Status write_image(const std::filesystem::path& path, const Image& image, ImageBatch* batch) {
  if (image.empty()) return Status::error(path.string() + ": empty image");
  if (is_float_image_format(path)) {
    EncodeRequest request;
    request.layout = {image.width, image.height, image.channels, PixelType::Float};
    request.pixels = image.pixels.data();
    if (image.channels == 1) request.channel_names = {"Z"};
    return write_pixels(path, std::move(request), batch);
  }
  std::vector<uint8_t> bytes(image.pixels.size());
  srgb_bytes(image.pixels, bytes);
  return write_srgb_bytes(path, image.width, image.height, image.channels, bytes.data(), batch);
}

Status write_image(const std::filesystem::path& path, const SrgbImage& image, ImageBatch* batch) {
  if (image.empty()) return Status::error(path.string() + ": empty image");
  if (is_float_image_format(path))
    return Status::error(path.string() + ": a float format needs the linear image, and this one is 8-bit sRGB");
  return write_srgb_bytes(path, image.width, image.height, image.channels, image.pixels.data(), batch);
}

Status write_color(const std::filesystem::path& path, const RenderResult& render, ImageBatch* batch) {
  return render.srgb.empty() ? write_image(path, render.color, batch) : write_image(path, render.srgb, batch);
}

Status check_output_image_path(const std::filesystem::path& path) {
  RAYLOD_RETURN_IF_ERROR(check_output_path(path, "the image"));
  if (!path.has_extension() && !is_extensionless_device(path))
    return Status::error(path.string() + ": no file extension to choose the image format from");
  return {};
}

namespace {

// Whether the writer for path's extension writes a small image of the kind
// raylod writes there (3 channels; floats for a float format, else 8-bit
// sRGB) that reads back whole: some of OpenImageIO's writers exist but
// cannot (.zfile takes 1 channel, OpenJPEG's .jp2 writes nothing), and
// those failed only after the whole run. Written into a folder of this
// process's own in the system's temporary folder (mkdtemp: no name another
// user can foresee or link), then removed; if no such folder can be made,
// the trial is left out (the write itself still checks what it wrote).
Status check_writer_writes(const std::filesystem::path& path, const ImageCodec& codec) {
  constexpr int kWidth = 64, kHeight = 48, kChannels = 3;
  const bool floats = is_float_image_format(path);
  std::vector<float> f(size_t(kWidth) * kHeight * kChannels);
  std::vector<uint8_t> b(f.size());
  for (size_t i = 0; i < f.size(); ++i) {  // a ramp, as a render has detail
    b[i] = uint8_t(i * 7);
    f[i] = float(b[i]) / 255.0f;
  }
  EncodeRequest request;
  request.writer = image_writer_for(path);
  request.layout = {kWidth, kHeight, kChannels, floats ? PixelType::Float : PixelType::UInt8};
  request.pixels = floats ? static_cast<const void*>(f.data()) : static_cast<const void*>(b.data());
  request.srgb = !floats;
  if (!floats) request.png_filter = 0x08;
  std::string folder = (temporary_folder() / "raylod-writer-check-XXXXXX").string();
  if (!::mkdtemp(folder.data())) return {};
  const std::filesystem::path trial = std::filesystem::path(folder) / ("trial" + path.extension().string());
  request.file = trial.string();
  const Encoded encoded = codec.encode(request);
  std::string error = encoded.error;
  if (error.empty() && encoded.in_memory) {
    std::ofstream out(trial, std::ios::binary);
    out.write(reinterpret_cast<const char*>(encoded.bytes.data()), std::streamsize(encoded.bytes.size()));
    if (!out.flush()) error = "cannot write a trial image to " + trial.string();
  }
  if (error.empty()) {
    const Decoded back = codec.decode(trial.string());
    if (!back.error.empty()) error = "the image it wrote does not read back: " + back.error;
    else if (back.layout.width != kWidth || back.layout.height != kHeight || back.layout.channels != kChannels)
      error = "the image it wrote reads back as " + std::to_string(back.layout.width) + " x " +
              std::to_string(back.layout.height) + " with " + std::to_string(back.layout.channels) + " channels";
  }
  std::error_code ec;
  std::filesystem::remove_all(folder, ec);
  if (!error.empty())
    return Status::error(path.string() + ": OpenImageIO's writer for '" + path.extension().string() +
                         "' files cannot write a " + std::to_string(kChannels) + "-channel " +
                         (floats ? "float" : "8-bit") + " image (" + error +
                         "); use PNG, JPEG, EXR, HDR, TIFF, PFM, BMP, TGA or PNM");
  return {};
}

}  // namespace

Status check_output_image(const std::filesystem::path& path) {
  RAYLOD_RETURN_IF_ERROR(check_output_image_path(path));
  const std::string ext = lower_case_extension(path);
  // OpenImageIO's "term" writer draws on the terminal (stdout) and its
  // "null" writer discards the pixels: neither writes a file.
  if (ext == ".term" || ext == ".null")
    return Status::error(path.string() + ": '" + ext + "' is OpenImageIO's " +
                         (ext == ".term" ? "terminal display" : "writer that discards the image") +
                         ", not an image file; use PNG, JPEG, EXR, HDR, TIFF, PFM, BMP, TGA or PNM");
  RAYLOD_ASSIGN_OR_RETURN(const ImageCodec* codec, image_codec());
  if (!codec->has_writer(image_writer_for(path)))
    return Status::error(path.string() + ": no image writer for '" + path.extension().string() + "' files");
  if (!is_extensionless_device(path)) {
    RAYLOD_RETURN_IF_ERROR(check_writer_writes(path, *codec));
  }
  return {};
}

Status check_output_image_early(const std::filesystem::path& path) {
  RAYLOD_RETURN_IF_ERROR(check_output_image_path(path));
  const std::string ext = lower_case_extension(path);
  for (const char* common : {".png", ".jpg", ".jpeg", ".exr", ".hdr", ".tif", ".tiff", ".pfm", ".bmp", ".tga", ".ppm",
                             ".pgm", ".pnm"})
    if (ext == common) return {};
  if (is_extensionless_device(path)) return {};
  return check_output_image(path);
}

StatusOr<Image> read_image(const std::filesystem::path& path) {
  RAYLOD_ASSIGN_OR_RETURN(const ImageCodec* codec, image_codec());
  Decoded decoded = codec->decode(path.string());
  if (!decoded.error.empty()) return Status::error(path.string() + ": cannot read image: " + decoded.error);
  Image image(decoded.layout.width, decoded.layout.height, decoded.layout.channels);
  image.pixels = std::move(decoded.pixels);
  if (decoded.integer) {  // back to linear, the inverse of write_image
    for (float& v : image.pixels) v = srgb_to_linear(v);
  }
  return image;
}

Status write_triangle_id_image(const std::filesystem::path& path, int width, int height,
                               const std::vector<uint32_t>& ids, ImageBatch* batch) {
  if (ids.size() != size_t(width) * height) return Status::error(path.string() + ": triangle id buffer has the wrong size");
  EncodeRequest request;
  request.layout = {width, height, 1, PixelType::UInt32};
  request.pixels = ids.data();
  request.channel_names = {"id"};
  return write_pixels(path, std::move(request), batch);
}

std::filesystem::path aov_path(const std::filesystem::path& output, const std::string& aov) {
  std::filesystem::path p = output;
  p.replace_extension();
  p += "." + aov + ".exr";
  return p;
}

StatusOr<std::vector<std::filesystem::path>> write_aovs(const std::filesystem::path& output, const RenderResult& r,
                                                        ImageBatch* batch) {
  // All or none: without the caller's batch, one of its own, committed here.
  ImageBatch own;
  ImageBatch& staged = batch ? *batch : own;
  std::vector<std::filesystem::path> written;
  if (!r.depth.empty()) {
    written.push_back(aov_path(output, "depth"));
    RAYLOD_RETURN_IF_ERROR(write_image(written.back(), r.depth, &staged));
  }
  if (!r.normal.empty()) {
    written.push_back(aov_path(output, "normal"));
    RAYLOD_RETURN_IF_ERROR(write_image(written.back(), r.normal, &staged));
  }
  if (!r.triangle_id.empty()) {
    written.push_back(aov_path(output, "triangle-id"));
    // The frame's size from the statistics: an 8-bit output has no linear frame (srgb_color).
    RAYLOD_RETURN_IF_ERROR(
        write_triangle_id_image(written.back(), r.stats.width, r.stats.height, r.triangle_id, &staged));
  }
  if (!batch) RAYLOD_RETURN_IF_ERROR(own.commit());
  return written;
}

}  // namespace raylod
