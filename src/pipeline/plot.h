// A small line plot rendered to an image with OpenImageIO (the report's
// accuracy-versus-time figure), so the report needs no plotting package.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/math.h"
#include "core/status.h"

namespace raylod {

struct PlotSeries {
  std::string name;
  Vec3 color{0, 0, 0};
  std::vector<std::pair<double, double>> points;  // (x, y), drawn in the given order
  bool lines = true;                               // join the points
};

struct PlotConfig {
  int width = 960, height = 640;
  std::string title, x_label, y_label;
};

// Writes the plot (format by extension). Labels need a TrueType font
// (DejaVu Sans, Debian package fonts-dejavu-core); without one the plot is
// drawn without text and the caller's table carries the numbers.
Status write_plot(const std::filesystem::path& path, const std::vector<PlotSeries>& series, const PlotConfig& config);

}  // namespace raylod
