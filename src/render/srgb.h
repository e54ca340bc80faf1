// The sRGB transfer function (IEC 61966-2-1) images are displayed with, and
// the 8-bit encoding PNG and JPEG files store.
#pragma once

#include <cstdint>
#include <span>

namespace raylod {

// Linear light in [0, 1] (clamped; NaN stays NaN) to its display value.
float linear_to_srgb(float linear);
// The inverse: a display value in [0, 1] to linear light.
float srgb_to_linear(float display);

// The byte an 8-bit image stores for a linear value:
// lround(linear_to_srgb(v) * 255) for every float v (0 for NaN and below
// 0, 255 from 1 up). It is read from the 255 values where the byte steps
// up, found once by bisecting the floats with that formula, and a table of
// where each run of 2^16 floats starts: one or two compares instead of a
// pow, which for a 3840 x 2160 frame was the largest serial cost after the
// PNG's compression.
uint8_t srgb_byte(float linear);
// srgb_byte of every value (out.size() == linear.size()), in parallel.
void srgb_bytes(std::span<const float> linear, std::span<uint8_t> out);

}  // namespace raylod
