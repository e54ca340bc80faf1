#include "pipeline/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "render/image_codec.h"
#include "render/renderer.h"

namespace raylod {
namespace {

const char* kFont = "DejaVuSans";

// "Nice" tick step for a range: 1, 2 or 5 times a power of ten.
double tick_step(double range, int target_ticks) {
  double raw = range / std::max(target_ticks, 1);
  double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

std::string label(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", std::abs(v) < 1e-12 ? 0.0 : v);
  return buf;
}

}  // namespace

Status write_plot(const std::filesystem::path& path, const std::vector<PlotSeries>& series, const PlotConfig& cfg) {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& s : series)
    for (auto [x, y] : s.points) {
      if (!std::isfinite(x) || !std::isfinite(y)) continue;
      x0 = std::min(x0, x); x1 = std::max(x1, x);
      y0 = std::min(y0, y); y1 = std::max(y1, y);
    }
  if (x0 > x1) return Status::error(path.string() + ": nothing to plot");
  // Time axes start at zero; a single point or a flat series still gets a
  // range proportional to its magnitude, so the tick count stays small.
  x0 = std::min(x0, 0.0);
  double xs = tick_step(std::max(x1 - x0, 1e-3 * std::max(std::abs(x1), 1.0)) * 1.1, 8);
  double ys = tick_step(std::max(y1 - y0, 1e-3 * std::max(std::abs(y1), 1.0)) * 1.1, 6);
  x0 = std::floor(x0 / xs) * xs; x1 = std::ceil(x1 / xs + 0.25) * xs;
  y0 = std::floor(y0 / ys - 0.25) * ys; y1 = std::ceil(y1 / ys + 0.25) * ys;

  const int W = cfg.width, H = cfg.height, left = 90, right = 30, top = 50, bottom = 70;
  const Vec3 black{0, 0, 0}, grey{0.85f, 0.85f, 0.85f};
  std::vector<DrawOp> ops;
  auto op = [&](DrawOp::Kind kind, int ax, int ay, int bx, int by, Vec3 c) {
    DrawOp d;
    d.kind = kind;
    d.x0 = ax; d.y0 = ay; d.x1 = bx; d.y1 = by;
    d.color[0] = c.x; d.color[1] = c.y; d.color[2] = c.z;
    ops.push_back(std::move(d));
  };
  auto text = [&](int x, int y, const std::string& t, int size, Vec3 c) {
    op(DrawOp::Kind::Text, x, y, x, y, c);
    ops.back().size = size;
    ops.back().text = t;
  };
  auto px = [&](double x) { return int(left + (x - x0) / (x1 - x0) * (W - left - right)); };
  auto py = [&](double y) { return int(H - bottom - (y - y0) / (y1 - y0) * (H - top - bottom)); };
  for (double x = x0; x <= x1 + 1e-9; x += xs) {
    op(DrawOp::Kind::Line, px(x), top, px(x), H - bottom, grey);
    text(px(x) - 10, H - bottom + 22, label(x), 15, black);
  }
  for (double y = y0; y <= y1 + 1e-9; y += ys) {
    op(DrawOp::Kind::Line, left, py(y), W - right, py(y), grey);
    text(left - 60, py(y) + 5, label(y), 15, black);
  }
  op(DrawOp::Kind::Box, left, top, W - right, H - bottom, black);
  text(left, 26, cfg.title, 20, black);
  text(W / 2 - 80, H - 20, cfg.x_label, 17, black);
  text(8, top - 4, cfg.y_label, 15, black);

  int legend_y = top + 24;
  for (const auto& s : series) {
    std::vector<std::pair<double, double>> pts;
    for (auto p : s.points)
      if (std::isfinite(p.first) && std::isfinite(p.second)) pts.push_back(p);
    for (size_t i = 0; i < pts.size(); ++i) {
      int x = px(pts[i].first), y = py(pts[i].second);
      op(DrawOp::Kind::FilledBox, x - 4, y - 4, x + 4, y + 4, s.color);
      if (s.lines && i > 0) {
        int xp = px(pts[i - 1].first), yp = py(pts[i - 1].second);
        for (int d = -1; d <= 1; ++d) op(DrawOp::Kind::Line, xp, yp + d, x, y + d, s.color);
      }
    }
    op(DrawOp::Kind::FilledBox, W - right - 330, legend_y - 10, W - right - 318, legend_y + 2, s.color);
    text(W - right - 310, legend_y + 2, s.name, 15, black);
    legend_y += 22;
  }
  RAYLOD_ASSIGN_OR_RETURN(const ImageCodec* codec, image_codec());
  std::vector<float> rgb(size_t(W) * size_t(H) * 3, 1.0f);  // white
  codec->draw(rgb.data(), W, H, ops, kFont);  // without a font, without the text
  // The plot's colours are display values: stored as they are, not encoded.
  SrgbImage image(W, H, 3);
  for (size_t i = 0; i < rgb.size(); ++i) image.pixels[i] = uint8_t(std::lround(std::clamp(rgb[i], 0.0f, 1.0f) * 255.0f));
  return write_image(path, image);
}

}  // namespace raylod
