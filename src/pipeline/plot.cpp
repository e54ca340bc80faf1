#include "pipeline/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "core/system.h"

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
  OIIO::ImageBuf img(OIIO::ImageSpec(W, H, 3, OIIO::TypeDesc::FLOAT));
  const float white[3] = {1, 1, 1}, black[3] = {0, 0, 0}, grey[3] = {0.85f, 0.85f, 0.85f};
  OIIO::ImageBufAlgo::fill(img, white);
  auto px = [&](double x) { return int(left + (x - x0) / (x1 - x0) * (W - left - right)); };
  auto py = [&](double y) { return int(H - bottom - (y - y0) / (y1 - y0) * (H - top - bottom)); };
  bool text_ok = true;
  auto text = [&](int x, int y, const std::string& t, int size, const float* color) {
    if (text_ok) text_ok = OIIO::ImageBufAlgo::render_text(img, x, y, t, size, kFont, {color, 3});
  };
  for (double x = x0; x <= x1 + 1e-9; x += xs) {
    OIIO::ImageBufAlgo::render_line(img, px(x), top, px(x), H - bottom, grey);
    text(px(x) - 10, H - bottom + 22, label(x), 15, black);
  }
  for (double y = y0; y <= y1 + 1e-9; y += ys) {
    OIIO::ImageBufAlgo::render_line(img, left, py(y), W - right, py(y), grey);
    text(left - 60, py(y) + 5, label(y), 15, black);
  }
  OIIO::ImageBufAlgo::render_box(img, left, top, W - right, H - bottom, black);
  text(left, 26, cfg.title, 20, black);
  text(W / 2 - 80, H - 20, cfg.x_label, 17, black);
  text(8, top - 4, cfg.y_label, 15, black);

  int legend_y = top + 24;
  for (const auto& s : series) {
    const float c[3] = {s.color.x, s.color.y, s.color.z};
    std::vector<std::pair<double, double>> pts;
    for (auto p : s.points)
      if (std::isfinite(p.first) && std::isfinite(p.second)) pts.push_back(p);
    for (size_t i = 0; i < pts.size(); ++i) {
      int x = px(pts[i].first), y = py(pts[i].second);
      OIIO::ImageBufAlgo::render_box(img, x - 4, y - 4, x + 4, y + 4, {c, 3}, true);
      if (s.lines && i > 0) {
        int xp = px(pts[i - 1].first), yp = py(pts[i - 1].second);
        for (int d = -1; d <= 1; ++d) OIIO::ImageBufAlgo::render_line(img, xp, yp + d, x, y + d, {c, 3});
      }
    }
    OIIO::ImageBufAlgo::render_box(img, W - right - 330, legend_y - 10, W - right - 318, legend_y + 2, {c, 3}, true);
    text(W - right - 310, legend_y + 2, s.name, 15, black);
    legend_y += 22;
  }
  // OpenImageIO chooses the format from the file name, so the temporary keeps the extension.
  AtomicOutput out(path);
  std::filesystem::path tmp = out.temp_path();
  tmp += path.extension();
  if (!img.write(tmp.string())) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    return Status::error(path.string() + ": cannot write plot: " + img.geterror());
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out.temp_path(), ec);
  if (ec) return Status::error(path.string() + ": " + ec.message());
  return out.commit();
}

}  // namespace raylod
