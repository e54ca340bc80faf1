// The renderer's noise floor: how far apart two equally valid renders of the
// full-resolution mesh are when only the sampling differs. The full mesh is
// rendered at the scene's seed s (the reference the method is measured
// against) and again at seed s + 1 with the same samples per pixel; the
// second render's error against the first (compare_images) is the floor.
// A simplified render whose PSNR against the reference is at or above the
// floor's differs from it by no more than another seed would: it is
// indistinguishable from the full mesh at this sample count.
#pragma once

#include <cstdint>
#include <string>

#include "core/status.h"
#include "pipeline/image_compare.h"
#include "render/embree_scene.h"
#include "render/renderer.h"
#include "scene/scene.h"

namespace raylod {

struct NoiseFloor {
  uint64_t seed = 0;            // the reference's seed s; the floor's render used s + 1 (wrapping)
  int spp = 0;                  // samples per pixel of both renders
  ImageError error;             // the render at s + 1 against the render at s
  double render_seconds = 0;    // tracing the render at s + 1 (the geometry is shared)
  double psnr() const { return error.psnr; }
};

// The seed of the floor's second render: s + 1, wrapping at 2^64.
inline uint64_t noise_floor_seed(uint64_t seed) { return seed + 1; }

// PSNR at or above the floor's: no further from the reference than a render
// of the full mesh at another seed. Two identical images (infinite PSNR) are
// within any floor; nothing but an identical image is within an infinite one.
bool within_noise_floor(const ImageError& error, const NoiseFloor& floor);

// For people: "noise floor 42.2 dB: indistinguishable" or
// "below the noise floor of 42.2 dB by 3.1 dB".
std::string describe_against_noise_floor(const ImageError& error, const NoiseFloor& floor);

// Renders `geometry` (the full-resolution meshes of `scene`) at the next seed
// with the same options and compares it with `reference`, the render at
// scene.seed. An error if the two images differ in size.
StatusOr<NoiseFloor> measure_noise_floor(const EmbreeScene& geometry, const Scene& scene, const RenderOptions& options,
                                         const Image& reference);

struct FullRender {
  RenderResult reference;       // the full-resolution render at scene.seed
  NoiseFloor noise_floor;       // the same geometry at scene.seed + 1 against it
};

// The full-resolution reference and its noise floor, as render() would make
// the reference (options.mesh_override, memory check), with the
// meshes loaded and the BVH built once for both renders.
StatusOr<FullRender> render_full_with_noise_floor(const Scene& scene, const RenderOptions& options);

}  // namespace raylod
