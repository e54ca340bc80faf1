#include "pipeline/image_compare.h"

#include <cmath>
#include <limits>

#include "render/image_codec.h"
#include "render/srgb.h"

namespace raylod {
namespace {

std::vector<double> luminance(const Image& im) {
  std::vector<double> y(size_t(im.width) * im.height);
  for (size_t i = 0; i < y.size(); ++i) {
    const float* p = &im.pixels[i * im.channels];
    y[i] = im.channels >= 3 ? 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2] : p[0];
  }
  return y;
}

// Separable Gaussian blur (11 taps, sigma 1.5) with clamped borders.
std::vector<double> blur(const std::vector<double>& in, int w, int h) {
  double k[11], sum = 0;
  for (int i = 0; i < 11; ++i) sum += k[i] = std::exp(-0.5 * (i - 5) * (i - 5) / (1.5 * 1.5));
  for (double& v : k) v /= sum;
  std::vector<double> tmp(in.size()), out(in.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double s = 0;
      for (int i = 0; i < 11; ++i) s += k[i] * in[size_t(y) * w + std::clamp(x + i - 5, 0, w - 1)];
      tmp[size_t(y) * w + x] = s;
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double s = 0;
      for (int i = 0; i < 11; ++i) s += k[i] * tmp[size_t(std::clamp(y + i - 5, 0, h - 1)) * w + x];
      out[size_t(y) * w + x] = s;
    }
  return out;
}

double ssim(const Image& a, const Image& b) {
  const int w = a.width, h = a.height;
  auto x = luminance(a), y = luminance(b);
  std::vector<double> xx(x.size()), yy(x.size()), xy(x.size());
  for (size_t i = 0; i < x.size(); ++i) { xx[i] = x[i] * x[i]; yy[i] = y[i] * y[i]; xy[i] = x[i] * y[i]; }
  auto mx = blur(x, w, h), my = blur(y, w, h), sxx = blur(xx, w, h), syy = blur(yy, w, h), sxy = blur(xy, w, h);
  const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;  // dynamic range 1
  double total = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    double vx = sxx[i] - mx[i] * mx[i], vy = syy[i] - my[i] * my[i], cxy = sxy[i] - mx[i] * my[i];
    total += ((2 * mx[i] * my[i] + c1) * (2 * cxy + c2)) / ((mx[i] * mx[i] + my[i] * my[i] + c1) * (vx + vy + c2));
  }
  return total / double(x.size());
}

}  // namespace

Image to_display(const Image& linear) {
  Image out = linear;
  for (auto& v : out.pixels) v = linear_to_srgb(v);
  return out;
}

StatusOr<ImageError> compare_images(const Image& image, const Image& reference) {
  if (image.width != reference.width || image.height != reference.height || image.channels != reference.channels)
    return Status::error("images differ in size: " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                         " vs " + std::to_string(reference.width) + "x" + std::to_string(reference.height));
  RAYLOD_ASSIGN_OR_RETURN(const ImageCodec* codec, image_codec());
  Image a = to_display(image), b = to_display(reference);
  ImageError e;
  const Comparison cr = codec->compare(a.pixels.data(), b.pixels.data(), {a.width, a.height, a.channels, PixelType::Float});
  e.psnr = cr.psnr;
  e.max_diff = cr.max_error;
  e.mean_diff = cr.mean_error;
  e.pixels_over_1_percent = cr.over_threshold;
  e.ssim = ssim(a, b);
  return e;
}

Image difference_image(const Image& image, const Image& reference, float gain) {
  Image out(image.width, image.height, 3);
  Image a = to_display(image), b = to_display(reference);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < 3; ++c) {
        int cc = std::min(c, image.channels - 1);
        float d = std::abs(a.at(x, y)[cc] - b.at(x, y)[cc]) * gain;
        // write_image sRGB-encodes 8-bit formats; undo that so the PNG shows d.
        out.at(x, y)[c] = std::pow(std::clamp(d, 0.0f, 1.0f), 2.2f);
      }
  return out;
}

}  // namespace raylod
