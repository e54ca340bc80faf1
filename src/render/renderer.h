// `raylod render` as a library: load the scene's meshes, check memory, build
// one Embree BVH, trace the image in parallel tiles, write it with
// OpenImageIO. Also used by `raylod run` and tools/bench_render.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/status.h"
#include "render/embree_scene.h"
#include "render/integrator.h"
#include "scene/scene.h"

namespace raylod {

// An image, channels interleaved, row 0 at the top: linear floats (Image),
// or the 8-bit sRGB bytes PNG and JPEG files store (SrgbImage: srgb_byte,
// render/srgb.h, of each linear value).
template <class T>
struct ImageOf {
  int width = 0, height = 0, channels = 0;
  std::vector<T> pixels;
  ImageOf() = default;
  ImageOf(int w, int h, int c) : width(w), height(h), channels(c), pixels(size_t(w) * h * c, T(0)) {}
  bool empty() const { return pixels.empty(); }
  T* at(int x, int y) { return &pixels[(size_t(y) * width + x) * channels]; }
  const T* at(int x, int y) const { return &pixels[(size_t(y) * width + x) * channels]; }
};
using Image = ImageOf<float>;
using SrgbImage = ImageOf<uint8_t>;

struct RenderOptions {
  int spp = 0;                  // samples per pixel; 0 = the scene's spp
  uint64_t memory_limit = 0;    // bytes for meshes + BVH and the image (estimate_image_memory); 0 = no limit
  // mesh_override[i] replaces the mesh of scene.objects[i] (empty path = keep).
  std::vector<std::filesystem::path> mesh_override;
  // omit_object[i] != 0 leaves scene.objects[i] out (its simplified mesh is
  // empty); its mesh file is not read.
  std::vector<char> omit_object;
  // Appended to the error when the scene does not fit memory_limit.
  std::string over_limit_hint = "Use `raylod run`, which simplifies the mesh first.";
  // The color only as 8-bit sRGB (the result's srgb; its color stays
  // empty), each pixel encoded as its tile is finished, on the rank that
  // rendered it: for an 8-bit output, the same bytes as write_image makes
  // from the linear image, for a quarter of the frame's memory, and under
  // mpirun a quarter of the bytes to gather and no serial encoding on rank 0.
  bool srgb_color = false;
  bool wireframe = false;       // darken pixels near triangle edges (triangle density)
  bool aov_depth = false;       // camera-ray hit distance, 1 channel (0 where nothing is hit)
  bool aov_normal = false;      // shading normal facing the camera, 3 channels
  bool aov_triangle_id = false; // global triangle id of the first hit (kNoTriangle where none)
  int tile_size = 32;
  // Trace camera rays as 4x4 pixel packets (rtcIntersect16) and their
  // shadow rays as occlusion packets; false: one ray at a time. Both give the
  // same image (tests/render/packet_test.cpp); packets are faster.
  bool camera_packets = true;
  // Rendering part of a frame: its tiles in row-major order are cut into
  // tile_runs runs of consecutive tiles (tile_run_bounds), and
  // next_tile_run hands out the runs to render, one index a call (never
  // from two threads at once), nullopt when none are left. A thread asks for
  // the next run when it has nothing left to render, while the others may
  // still be on the last run's tiles.
  // The result's tile_runs lists the runs rendered; other pixels stay 0.
  // Empty next_tile_run: the whole frame.
  int tile_runs = 1;
  std::function<std::optional<uint64_t>()> next_tile_run;
  // Under mpirun (core/cluster.h): render() deals the frame's runs of tiles
  // to the ranks as they ask for them (cluster::WorkQueue: each rank starts
  // on its own share of the rows and takes from the others' when done), and
  // gathers the pixels on rank 0; the other ranks' result holds only their
  // own tiles and must not be written. The pixels do not depend on which
  // rank rendered them. Every rank calls render() with the same scene.
  bool split_across_ranks = false;
  bool progress = true;         // progress bars on stderr
  // Called once the scene is loaded and its BVH built, before any ray is
  // traced (and agreed across the ranks when split_across_ranks): a check
  // that could not be made sooner without waiting, such as whether the
  // output has an image writer while the image codec loaded meanwhile
  // (start_loading_image_codec). Its error ends the render. Null: none.
  std::function<Status()> before_trace;
  // Informational messages (effects on, BVH quality, ...); null = silent.
  std::function<void(const std::string&)> log;
  // Warn through `log` about meshes that render nothing or are too small or
  // large for single-precision rays. Off where the caller warns about its
  // own inputs (raylod run: it renders a simplified mesh under a temporary
  // name, and warns from the stores).
  bool warn_about_meshes = true;
  BvhConfig bvh;
  IntegratorConfig integrator;  // max_depth and wireframe are taken from the scene / above
};

struct RenderStats {
  RayCounters rays;
  Effects effects;
  int width = 0, height = 0, spp = 0;
  int threads = 0;               // the parallelism it ran with (ambient_parallelism(), core/parallelism.h)
  uint64_t triangles = 0, vertices = 0;
  uint64_t estimated_bytes = 0;  // estimate_render_memory() + estimate_image_memory() before loading
  uint64_t mesh_bytes = 0, bvh_bytes = 0, bvh_peak_bytes = 0;
  uint64_t peak_rss = 0;         // of the process, after rendering
  std::string bvh_quality;
  double load_seconds = 0, bvh_seconds = 0, render_seconds = 0;
  // Rays per second of render time, all kinds.
  double rays_per_second() const { return render_seconds > 0 ? double(rays.total()) / render_seconds : 0; }
};
// The stats as a JSON object (for --stats-json and benchmarks).
std::string render_stats_json(const RenderStats& stats);

inline constexpr uint32_t kNoTriangle = 0xffffffffu;

struct RenderResult {
  Image color;                       // linear RGB (empty with RenderOptions::srgb_color)
  SrgbImage srgb;                    // the color as 8-bit sRGB, with RenderOptions::srgb_color only
  Image depth, normal;               // empty unless asked for
  std::vector<uint32_t> triangle_id; // empty unless asked for; width * height
  RenderStats stats;
  std::vector<uint64_t> tile_runs;   // the runs of tiles rendered (RenderOptions::next_tile_run), increasing
};

// The tiles [first, last) of run k, when a frame's `tiles` tiles in
// row-major order are cut into `runs` runs (1 <= runs <= tiles) whose
// lengths differ by at most one.
std::pair<uint64_t, uint64_t> tile_run_bounds(uint64_t tiles, uint64_t runs, uint64_t k);

// Resident bytes the renderer needs for a scene of this many triangles:
// welded mesh arrays plus the Embree BVH (with the layout BvhConfig picks),
// measured on the teapot meshes (tools/bench_render) and rounded up.
uint64_t estimate_render_memory(uint64_t triangles, const BvhConfig& config = {});
// Resident bytes the frame takes: the float image (12 bytes a pixel), the
// 8-bit copy and encoded bytes written from it (3 + 3), or with srgb_color
// the 8-bit frame and its encoded bytes (3 + 3), and each AOV asked
// for with its own copy to write (depth 8, normal 15, triangle id 8). A
// 6000 x 6000 frame is 618 MiB; under --memory-limit 300M it ran to 566 to
// 677 MiB before the frame was counted.
uint64_t estimate_image_memory(int width, int height, const RenderOptions& options);
// The BVH configuration for a scene of this many triangles under a memory
// limit (0 = none): `config`, switched to the compact layout (medium builder,
// index-only leaves) when only that fits, whatever the scene's size.
BvhConfig bvh_for_memory_limit(uint64_t triangles, uint64_t limit, BvhConfig config = {});
// The largest triangle count that fits in bytes with the layout
// bvh_for_memory_limit would pick.
// The layout that needs the least memory: compact, built by the medium
// builder (bvh_for_memory_limit's last resort).
BvhConfig smallest_bvh_layout(BvhConfig config = {});
uint64_t triangles_that_fit(uint64_t bytes, const BvhConfig& config = {});

// The triangles the scene's mesh files (or their overrides) declare, the
// ground's two included, read from the files' headers: what
// load_scene_meshes checks against the memory limit.
StatusOr<uint64_t> declared_scene_triangles(const Scene& scene, const RenderOptions& options);

// Loads every object's mesh (or its override) into world space, plus the
// ground plane; checks the memory estimate against options.memory_limit
// before reading any triangle. Fills the load part of stats, and `bvh` (if
// given) with the configuration to build with (bvh_for_memory_limit), its
// camera_rays, unless options.bvh gives them, those of one frame of the
// scene (width x height x spp): a caller that traces more frames with the
// same BVH multiplies them.
// Warns through options.log about a mesh whose every triangle is degenerate.
// The scene as the renderer sees it: every world position minus
// scene.render_origin (parse_scene's; in a scene built in code, which has
// none, local_origin_for its camera's look-at point, so meshes built in the
// world frame near zero stay where they are), computed in double (camera,
// point lights, ground height, object transforms), and render_origin zero. Images do not change
// (distances and directions are the same); floats near a far scene's camera
// keep their detail. load_scene_meshes and render_embree_scene apply it
// themselves; whoever builds an EmbreeScene by other means applies it to
// the transforms and ground it uses.
Scene in_render_frame(const Scene& scene);

StatusOr<std::vector<TriangleMesh>> load_scene_meshes(const Scene& scene, const RenderOptions& options,
                                                      RenderStats& stats, BvhConfig* bvh = nullptr);

// Renders a prebuilt scene (for reuse across renders, tests and benchmarks).
// Geometry material indices refer to scene.materials; the camera, lights,
// background, spp, max_depth and seed come from scene.
RenderResult render_embree_scene(const EmbreeScene& geometry, const Scene& scene, const RenderOptions& options);

// The whole render: load, memory check, BVH build, trace.
StatusOr<RenderResult> render(const Scene& scene, const RenderOptions& options);

class AtomicOutput;  // core/system.h

// Images written together, all or none (an image and its AOVs): each write
// given the batch encodes into a temporary beside its destination and is
// checked, and commit() renames them all into place. Destroyed without
// commit(), the batch removes its temporaries and every destination stays as
// it was. A rename failing within commit() leaves the ones before it
// renamed; renames within a folder fail only on a destination made a
// directory meanwhile.
class ImageBatch {
 public:
  ImageBatch() = default;
  ~ImageBatch();
  ImageBatch(const ImageBatch&) = delete;
  ImageBatch& operator=(const ImageBatch&) = delete;
  Status commit();
  // For the writers: an output written and checked, to rename on commit().
  void add(std::unique_ptr<AtomicOutput> staged);

 private:
  std::vector<std::unique_ptr<AtomicOutput>> staged_;
};

// Writes an image, format chosen by the extension (anything OpenImageIO
// writes). Float formats (EXR, HDR, TIFF, PFM) get linear floats; 8/16-bit
// formats (PNG, JPEG, ...) get sRGB-encoded values clamped to [0, 1].
// Atomic: written under a temporary name, then renamed (with a batch, when
// the batch commits).
Status write_image(const std::filesystem::path& path, const Image& image, ImageBatch* batch = nullptr);
// Writes an 8-bit sRGB image (RenderOptions::srgb_color) to an 8-bit format:
// the same file as write_image of the linear image it was encoded from. A
// float format is an error (the linear values are gone).
Status write_image(const std::filesystem::path& path, const SrgbImage& image, ImageBatch* batch = nullptr);
// Writes a render's color as the render made it: its 8-bit frame
// (RenderOptions::srgb_color), else its linear one.
Status write_color(const std::filesystem::path& path, const RenderResult& render, ImageBatch* batch = nullptr);
// Whether write_image stores path's format as linear floats (EXR, HDR,
// TIFF, PFM) rather than 8-bit sRGB.
bool is_float_image_format(const std::filesystem::path& path);
// Checks, before any work, that an image can be written to path: a writer
// exists for its extension and its directory exists.
Status check_output_image(const std::filesystem::path& path);
// The same without asking the image codec for a writer (it is not loaded):
// for the ranks of a job that never write the image.
Status check_output_image_path(const std::filesystem::path& path);
// check_output_image_path, and where the extension is not one every
// OpenImageIO build writes (PNG, JPEG, EXR, HDR, TIFF, PFM, BMP, TGA, PNM),
// check_output_image: an unknown extension fails before any work, waiting
// for the codec to load, while the common ones keep its loading overlapped
// with the work (check_output_image before the first ray or write).
Status check_output_image_early(const std::filesystem::path& path);
// Reads an image as linear float (the inverse of write_image), for tests and tools.
StatusOr<Image> read_image(const std::filesystem::path& path);
// A triangle-id buffer as a one-channel 32-bit unsigned EXR.
Status write_triangle_id_image(const std::filesystem::path& path, int width, int height,
                               const std::vector<uint32_t>& ids, ImageBatch* batch = nullptr);
// "out.png" + "depth" -> "out.depth.exr" (AOVs are always EXR).
std::filesystem::path aov_path(const std::filesystem::path& output, const std::string& aov);
// Writes the AOVs present in result next to output, all or none; returns the
// paths written. With a batch they are renamed into place when it commits.
StatusOr<std::vector<std::filesystem::path>> write_aovs(const std::filesystem::path& output, const RenderResult& result,
                                                        ImageBatch* batch = nullptr);

}  // namespace raylod
