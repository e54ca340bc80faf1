// The Draco position error bound of the pipeline: quantising a cut's kept
// input triangles must not tilt their face normals visibly, even when the
// probe's footprint is much larger than the triangles (small K).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <vector>

#include "pipeline/pipeline.h"
#include "streaming/draco_io.h"
#include "streaming/mesh_writer.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// The tilted plane z = 0.3 x + 0.2 y over [0, 1]^2, n x n squares split into
// two right triangles each (legs 1/n in x and y), with exact vertex normals.
// Every face normal of the exact mesh is the plane's normal, so any tilt of a
// face in the output comes from quantisation.
Vec3d plane_normal() { return glm::normalize(Vec3d(-0.3, -0.2, 1.0)); }

fs::path write_plane(const fs::path& dir, int n) {
  const fs::path path = dir / "plane.ply";
  auto writer = create_mesh_writer(path);
  EXPECT_TRUE(writer.is_ok());
  TriangleBatch batch;
  const Vec3 normal(plane_normal());
  auto vertex = [&](int i, int j) {
    const double x = double(i) / n, y = double(j) / n;
    batch.positions.push_back(Vec3(Vec3d(x, y, 0.3 * x + 0.2 * y)));
    batch.normals.push_back(normal);
  };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1);
      vertex(i, j), vertex(i + 1, j + 1), vertex(i, j + 1);
    }
    EXPECT_TRUE((*writer)->write(batch).is_ok());
    batch.positions.clear();
    batch.normals.clear();
  }
  EXPECT_TRUE((*writer)->finish().is_ok());
  return path;
}

TEST(DracoErrorBound, MeanInputEdgeIsTheEquilateralEdgeOfTheMeanArea) {
  const fs::path dir = test::scratch_dir("draco-bound-edge");
  const int n = 64;
  const fs::path mesh = write_plane(dir, n);
  ASSERT_TRUE(build_store(mesh, dir / "plane.raylod", StoreOptions{}).is_ok());
  auto store = OctreeStore::open(dir / "plane.raylod");
  ASSERT_TRUE(store.is_ok());
  // Each triangle's area is half a square of the tilted plane.
  const double area = 0.5 / (double(n) * n) / plane_normal().z;
  const double expected = std::sqrt(4.0 * area / std::sqrt(3.0));
  EXPECT_NEAR(mean_input_edge(**store), expected, 1e-6 * expected);
  EXPECT_NEAR(geometric_normal_position_bound(**store), kGeometricNormalTolerance * std::sqrt(3.0) / 4.0 * expected,
              1e-6 * expected);
  fs::remove_all(dir);
}

// A cut whose footprint is eight times the triangles' size (what K = 1 gives
// on a dense mesh): an eighth of the footprint is a whole triangle leg, which
// used to tilt faces by tens of degrees. Now no face may tilt by more than
// about the tolerance (the bound is for equilateral faces of the mean area;
// these right triangles are a little more sensitive), and almost all by less.
TEST(DracoErrorBound, QuantisedKeptTrianglesKeepTheirFaceNormals) {
  const fs::path dir = test::scratch_dir("draco-bound-tilt");
  const int n = 160;
  const fs::path mesh = write_plane(dir, n);
  ASSERT_TRUE(build_store(mesh, dir / "plane.raylod", StoreOptions{}).is_ok());
  auto store = OctreeStore::open(dir / "plane.raylod");
  ASSERT_TRUE(store.is_ok());

  Cut cut;  // collapses nothing: every input triangle is kept
  cut.min_footprint = float(8.0 / n);
  EXPECT_LE(draco_error_bound(cut, **store), geometric_normal_position_bound(**store));
  auto written = simplify_cut_to_draco(**store, cut, dir / "plane.drc", 0, 1e-3, false);
  ASSERT_TRUE(written.is_ok()) << written.status().message();
  EXPECT_LE(written->max_position_error, draco_error_bound(cut, **store));
  auto out = read_draco(dir / "plane.drc");
  ASSERT_TRUE(out.is_ok());
  ASSERT_EQ(out->triangle_count(), size_t(2) * n * n);

  std::vector<double> tilt;
  const Vec3d normal = plane_normal();
  for (size_t t = 0; t < out->triangle_count(); ++t) {
    const Vec3d a(out->positions[out->indices[3 * t]]), b(out->positions[out->indices[3 * t + 1]]),
        c(out->positions[out->indices[3 * t + 2]]);
    const Vec3d cross = glm::cross(b - a, c - a);
    const double len = glm::length(cross);
    tilt.push_back(len > 0 ? std::acos(std::clamp(glm::dot(cross / len, normal), -1.0, 1.0)) : M_PI);
  }
  std::sort(tilt.begin(), tilt.end());
  const double p99 = tilt[tilt.size() * 99 / 100];
  EXPECT_LT(p99, kGeometricNormalTolerance) << "99th percentile face tilt " << p99 << " rad";
  EXPECT_LT(tilt.back(), 2 * kGeometricNormalTolerance) << "largest face tilt " << tilt.back() << " rad";
  fs::remove_all(dir);
}

// A closed box 1 x t x 1 of 12 triangles, t thin, without normals.
fs::path write_pane(const fs::path& dir, double t) {
  const fs::path path = dir / "pane.ply";
  auto writer = create_mesh_writer(path);
  EXPECT_TRUE(writer.is_ok());
  TriangleBatch batch;
  const Vec3 c[8] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1},
                     {0, float(t), 0}, {1, float(t), 0}, {1, float(t), 1}, {0, float(t), 1}};
  const int quads[6][4] = {{0, 1, 2, 3}, {4, 7, 6, 5}, {0, 4, 5, 1}, {1, 5, 6, 2}, {2, 6, 7, 3}, {3, 7, 4, 0}};
  for (const auto& q : quads)
    for (const std::array<int, 3>& tri : {std::array<int, 3>{q[0], q[1], q[2]}, std::array<int, 3>{q[0], q[2], q[3]}})
      for (int k : tri) batch.positions.push_back(c[k]);
  EXPECT_TRUE((*writer)->write(batch).is_ok());
  EXPECT_TRUE((*writer)->finish().is_ok());
  return path;
}

TEST(DracoErrorBound, ThinWallsOnGlassKeepTheirSheetsApart) {
  IndexedMesh sliver;
  sliver.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1e-4f, 0}};
  sliver.indices = {0, 1, 2};
  EXPECT_DOUBLE_EQ(thin_wall_position_bound(1e-3, sliver, 1.0, false), 1e-3);
  EXPECT_NEAR(thin_wall_position_bound(1e-3, sliver, 1.0, true), 0.25 * double(1e-4f), 1e-12);
  EXPECT_DOUBLE_EQ(thin_wall_position_bound(1e-6, sliver, 1.0, true), 1e-6);
  sliver.positions[2].y = 1e-9f;  // no less than 2^-22 of the root cell
  EXPECT_DOUBLE_EQ(thin_wall_position_bound(1e-3, sliver, 1.0, true), 0x1p-22);

  // End to end: a glass pane 1e-4 thick, nothing collapsed. With the mirror
  // and glass settings (fold passes, exact normals) both sheets come back
  // apart, each within a quarter of the thickness; the footprint's bound
  // alone (an opaque object's) may merge them.
  const fs::path dir = test::scratch_dir("draco-bound-pane");
  const double t = 1e-4;
  const fs::path mesh = write_pane(dir, t);
  ASSERT_TRUE(build_store(mesh, dir / "pane.raylod", StoreOptions{}).is_ok());
  auto store = OctreeStore::open(dir / "pane.raylod");
  ASSERT_TRUE(store.is_ok());
  Cut cut;
  cut.min_footprint = 3e-3f;  // a pixel of a 320-pixel view of the pane
  ASSERT_GT(draco_error_bound(cut, **store), t);
  auto written = simplify_cut_to_draco(**store, cut, dir / "pane.drc", 0, 1e-3, false, nullptr, kDefaultCreaseAngleDeg, 1);
  ASSERT_TRUE(written.is_ok()) << written.status().message();
  EXPECT_LE(written->max_position_error, t / 4);
  auto out = read_draco(dir / "pane.drc");
  ASSERT_TRUE(out.is_ok());
  ASSERT_EQ(out->triangle_count(), 12u);
  for (const Vec3& p : out->positions) {
    const double y = p.y;
    EXPECT_TRUE(std::abs(y) <= t / 4 || std::abs(y - t) <= t / 4) << y;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace raylod
