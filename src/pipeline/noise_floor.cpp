#include "pipeline/noise_floor.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>


#include "core/system.h"

namespace raylod {

namespace {

std::string db(double psnr) {
  if (!std::isfinite(psnr)) return "infinite";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f dB", psnr);
  return buf;
}

}  // namespace

bool within_noise_floor(const ImageError& error, const NoiseFloor& floor) {
  // inf >= inf holds, and a finite PSNR is never at an infinite floor.
  return error.psnr >= floor.psnr();
}

std::string describe_against_noise_floor(const ImageError& error, const NoiseFloor& floor) {
  if (!std::isfinite(floor.psnr())) {
    // Seeds s and s + 1 gave the same image: the render has no sampling noise
    // here, so only an identical image matches the full mesh.
    return within_noise_floor(error, floor) ? "noise floor infinite (seeds give identical images): identical"
                                            : "below the noise floor (seeds give identical images; this one differs)";
  }
  if (within_noise_floor(error, floor)) return "noise floor " + db(floor.psnr()) + ": indistinguishable";
  char buf[96];
  std::snprintf(buf, sizeof buf, "below the noise floor of %s by %.2f dB", db(floor.psnr()).c_str(),
                floor.psnr() - error.psnr);
  return buf;
}

StatusOr<NoiseFloor> measure_noise_floor(const EmbreeScene& geometry, const Scene& scene, const RenderOptions& options,
                                         const Image& reference) {
  Scene next = scene;
  next.seed = noise_floor_seed(scene.seed);
  RenderOptions o = options;
  // Only the colour is compared.
  o.aov_depth = o.aov_normal = o.aov_triangle_id = false;
  const RenderResult second = render_embree_scene(geometry, next, o);
  NoiseFloor floor;
  floor.seed = scene.seed;
  floor.spp = second.stats.spp;
  floor.render_seconds = second.stats.render_seconds;
  RAYLOD_ASSIGN_OR_RETURN(floor.error, compare_images(second.color, reference));
  return floor;
}

StatusOr<FullRender> render_full_with_noise_floor(const Scene& scene, const RenderOptions& options) {
  RenderStats load_stats;
  BvhConfig bvh;
  RAYLOD_ASSIGN_OR_RETURN(auto meshes, load_scene_meshes(scene, options, load_stats, &bvh));
  if (options.bvh.camera_rays == 0) bvh.camera_rays *= 2;  // the reference and the noise floor's frame
  RAYLOD_ASSIGN_OR_RETURN(auto geometry, EmbreeScene::build(std::move(meshes), bvh));
  FullRender out;
  out.reference = render_embree_scene(*geometry, scene, options);
  out.reference.stats.load_seconds = load_stats.load_seconds;
  out.reference.stats.estimated_bytes = load_stats.estimated_bytes;
  RAYLOD_ASSIGN_OR_RETURN(out.noise_floor, measure_noise_floor(*geometry, scene, options, out.reference.color));
  out.reference.stats.peak_rss = peak_rss_bytes();
  return out;
}

}  // namespace raylod
