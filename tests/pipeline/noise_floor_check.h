// The noise-floor check of the pipeline tests on real meshes: a simplified
// render is as close to the full render as another seed of the full render
// is (pipeline/noise_floor.h), or closer.
#pragma once

#include <gtest/gtest.h>

#include <cmath>

#include "pipeline/image_compare.h"
#include "pipeline/noise_floor.h"

namespace raylod::test {

inline void expect_within_noise_floor(const Image& simplified, const FullRender& full) {
  const NoiseFloor& floor = full.noise_floor;
  ASSERT_TRUE(std::isfinite(floor.psnr()));
  auto e = compare_images(simplified, full.reference.color);
  ASSERT_TRUE(e.is_ok()) << e.status().message();
  EXPECT_TRUE(within_noise_floor(*e, floor))
      << "simplified render PSNR " << e->psnr << " dB, SSIM " << e->ssim << "; noise floor " << floor.psnr()
      << " dB, SSIM " << floor.error.ssim;
}

}  // namespace raylod::test
