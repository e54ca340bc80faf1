// The report's plot: flat and single-point series must not explode the
// number of ticks (a range of zero once made the tick step vanish).
#include <gtest/gtest.h>

#include <filesystem>

#include "pipeline/plot.h"
#include "render/renderer.h"
#include "test_tmp.h"

namespace raylod {
namespace {

TEST(Plot, SinglePointAndFlatSeriesAreDrawn) {
  const auto dir = test::scratch_dir("plot");
  PlotConfig cfg;
  cfg.width = 320;
  cfg.height = 200;
  cfg.title = "one point";
  ASSERT_TRUE(write_plot(dir / "one.png", {{"a", {1, 0, 0}, {{3.7, 42.0}}}}, cfg).is_ok());
  ASSERT_TRUE(write_plot(dir / "far.png", {{"b", {0, 0, 1}, {{100.0, 40.0}, {100.5, 40.0}}}}, cfg).is_ok());
  auto img = read_image(dir / "one.png");
  ASSERT_TRUE(img.is_ok()) << img.status().message();
  EXPECT_EQ(img->width, 320);
  // The point's red marker is somewhere in the picture.
  int red = 0;
  for (int y = 0; y < img->height; ++y)
    for (int x = 0; x < img->width; ++x) {
      const float* p = img->at(x, y);
      red += p[0] > 0.8f && p[1] < 0.2f && p[2] < 0.2f;
    }
  EXPECT_GT(red, 20);
}

TEST(Plot, NothingToPlotIsAnError) {
  const auto dir = test::scratch_dir("plot");
  EXPECT_FALSE(write_plot(dir / "none.png", {}, PlotConfig{}).is_ok());
  EXPECT_FALSE(std::filesystem::exists(dir / "none.png"));
}

}  // namespace
}  // namespace raylod
