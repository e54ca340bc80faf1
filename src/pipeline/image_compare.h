// Image error against a reference, as the accuracy report measures it.
// Both images are compared as displayed: linear RGB clamped to [0, 1] and
// sRGB-encoded, the values a PNG holds.
#pragma once

#include "core/status.h"
#include "render/renderer.h"

namespace raylod {

struct ImageError {
  double psnr = 0;        // dB over RGB (OpenImageIO's compare); infinity if identical
  double ssim = 0;        // mean SSIM of luminance (Wang et al. 2004; 11x11 Gaussian, sigma 1.5)
  double max_diff = 0;    // largest absolute channel difference, in [0, 1]
  double mean_diff = 0;
  uint64_t pixels_over_1_percent = 0;  // pixels with some channel off by more than 0.01
};

StatusOr<ImageError> compare_images(const Image& image, const Image& reference);
// |image - reference| per channel, scaled by `gain` for visibility (the
// paper's Figure 4(d)), as a 3-channel linear image ready for write_image.
Image difference_image(const Image& image, const Image& reference, float gain = 4.0f);
// sRGB-encoded copy of a linear image, clamped to [0, 1].
Image to_display(const Image& linear);

}  // namespace raylod
