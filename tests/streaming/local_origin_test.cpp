// Meshes far from zero (MeshHeader::origin): readers of formats that hold
// more than a float keep positions relative to the first vertex rounded to
// integers, so origin + position is the file's coordinate to float precision
// of the small offset; float formats, and meshes near zero, keep (0, 0, 0)
// and read exactly as before.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "reader_test_util.h"
#include "streaming/draco_io.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;
using test::Bytes;
using test::write_file;

// A triangle with 1e-3 detail at a 1e7 offset.
const Vec3d kFar[3] = {{1e7 + 0.25, -2e7 + 0.5, 3e7 + 0.125}, {1e7 + 0.251, -2e7 + 0.5, 3e7 + 0.125},
                       {1e7 + 0.25, -2e7 + 0.501, 3e7 + 0.126}};
const Vec3d kOrigin(1e7, -2e7, 3e7);  // kFar[0] rounded

void expect_far_triangle(const test::ReadAll& r) {
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.header.origin, kOrigin);
  ASSERT_EQ(r.positions.size(), 3u);
  for (int k = 0; k < 3; ++k)
    for (int a = 0; a < 3; ++a)
      // Floats near 0.25 are 3e-8 apart; near 1e7 they would be 1 apart.
      EXPECT_NEAR(r.header.origin[a] + double(r.positions[size_t(k)][a]), kFar[k][a], 1e-7) << "corner " << k << " axis " << a;
}

std::string text_coords(const Vec3d& p) {
  char buf[100];
  std::snprintf(buf, sizeof buf, "%.17g %.17g %.17g", p.x, p.y, p.z);
  return buf;
}

TEST(LocalOrigin, BinaryDoublePly) {
  Bytes b;
  b.text("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
         "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n");
  for (const Vec3d& p : kFar) b.put<double>(p.x).put<double>(p.y).put<double>(p.z);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  expect_far_triangle(test::read_all(write_file("far.ply", b.data)));
}

TEST(LocalOrigin, AsciiPly) {
  std::string s = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
                  "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3d& p : kFar) s += text_coords(p) + "\n";
  s += "3 0 1 2\n";
  expect_far_triangle(test::read_all(write_file("far_ascii.ply", s)));
}

TEST(LocalOrigin, Obj) {
  std::string s;
  for (const Vec3d& p : kFar) s += "v " + text_coords(p) + "\n";
  s += "f 1 2 3\n";
  expect_far_triangle(test::read_all(write_file("far.obj", s)));
}

TEST(LocalOrigin, DracoCarriesItThroughAWriteAndARead) {
  IndexedMesh m;
  m.origin = kOrigin;
  for (const Vec3d& p : kFar) m.positions.push_back(Vec3(p - kOrigin));
  m.indices = {0, 1, 2};
  const fs::path out = test::scratch_dir() / "far.drc";
  DracoOptions o;
  o.max_position_error = 1e-8;
  ASSERT_TRUE(write_draco(out, m, o).is_ok());
  expect_far_triangle(test::read_all(out));
}

TEST(LocalOrigin, NearZeroAndFloatFilesKeepNone) {
  // Near zero: 4095 is below the threshold.
  const std::string near = "v 4095.5 0 0\nv 4096.5 0 0\nv 4095.5 1 0\nf 1 2 3\n";
  auto r = test::read_all(write_file("near.obj", near));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.header.origin, Vec3d(0));
  EXPECT_EQ(r.positions[0], Vec3(4095.5f, 0, 0));
  // Float PLY far from zero: the file holds floats, nothing to keep.
  Bytes b;
  b.text("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n");
  for (const Vec3d& p : kFar) b.put<float>(float(p.x)).put<float>(float(p.y)).put<float>(float(p.z));
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  r = test::read_all(write_file("far_float.ply", b.data));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.header.origin, Vec3d(0));
  EXPECT_EQ(r.positions[0], Vec3(float(kFar[0].x), float(kFar[0].y), float(kFar[0].z)));
}

TEST(LocalOrigin, TheRule) {
  EXPECT_EQ(local_origin_for(Vec3d(4095.9, -4095.9, 0)), Vec3d(0));
  EXPECT_EQ(local_origin_for(Vec3d(4096, 0.4, -0.6)), Vec3d(4096, 0, -1));
  EXPECT_EQ(local_origin_for(Vec3d(0, 0, -1e7 - 0.5)), Vec3d(0, 0, std::round(-1e7 - 0.5)));
  EXPECT_EQ(local_origin_for(Vec3d(std::nan(""), 1e9, 0)), Vec3d(0));
}

}  // namespace
}  // namespace raylod
