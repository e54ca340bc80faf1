// Zero-length vertex normals (OpenCASCADE writes (0, 0, 0) on degenerate
// triangles) are replaced per triangle corner by the triangle's face normal,
// counted, and reported in one warning per file; NaN/Inf normals stay errors.
#include <gtest/gtest.h>

#include <cmath>

#include "reader_test_util.h"
#include "streaming/vertex_table.h"

namespace raylod {
namespace {

using test::Bytes;
using test::read_all;
using test::write_file;

TEST(ZeroNormal, RepairGivesTheFaceNormalToZeroCornersOnly) {
  const Vec3 p[3] = {{0, 0, 0}, {2, 0, 0}, {0, 0, -3}};  // face normal +Y by the right-hand rule
  Vec3 n[3] = {{0, 0, 0}, {0.6f, 0.8f, 0}, {-0.0f, 0, 0}};
  EXPECT_EQ(repair_zero_normals(p, n), 2);
  EXPECT_EQ(n[0], Vec3(0, 1, 0));
  EXPECT_EQ(n[1], Vec3(0.6f, 0.8f, 0));
  EXPECT_EQ(n[2], Vec3(0, 1, 0));
  Vec3 unit[3] = {{0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
  EXPECT_EQ(repair_zero_normals(p, unit), 0);
}

TEST(ZeroNormal, FaceNormalIsTurnedToAgreeWithTheOtherNormals) {
  const Vec3 p[3] = {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}};  // wound clockwise seen from +Z: face normal -Z
  Vec3 n[3] = {{0, 0, 1}, {0, 0, 0}, {0, 0, 1}};
  EXPECT_EQ(repair_zero_normals(p, n), 1);
  EXPECT_EQ(n[1], Vec3(0, 0, 1));
  Vec3 alone[3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};  // no other normal: the winding decides
  EXPECT_EQ(repair_zero_normals(p, alone), 3);
  EXPECT_EQ(alone[0], Vec3(0, 0, -1));
}

TEST(ZeroNormal, DegenerateTriangleTakesTheSumOfItsOtherNormalsElsePlusZ) {
  const Vec3 line[3] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};  // collinear: no face normal
  Vec3 n[3] = {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}};
  EXPECT_EQ(repair_zero_normals(line, n), 1);
  EXPECT_NEAR(n[0].y, std::sqrt(0.5f), 1e-6f);
  EXPECT_NEAR(n[0].z, std::sqrt(0.5f), 1e-6f);
  EXPECT_EQ(n[0].x, 0.0f);
  const Vec3 point[3] = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  Vec3 none[3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  EXPECT_EQ(repair_zero_normals(point, none), 3);
  for (const Vec3& v : none) EXPECT_EQ(v, Vec3(0, 0, 1));
}

// An OpenCASCADE-like PLY: a good triangle, and a degenerate one whose
// collapsed corner carries a zero normal.
std::string occ_ply(const std::string& format) {
  const std::string header =
      "ply\nformat " + format + " 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
      "property float nx\nproperty float ny\nproperty float nz\nelement face 2\n"
      "property list uchar int vertex_indices\nend_header\n";
  const float v[5][6] = {{0, 0, 0, 0, 0, 1}, {1, 0, 0, 0, 0, 1}, {0, 1, 0, 0, 0, 1}, {2, 0, 0, 0, 0, 0}, {3, 0, 0, 0, 1, 0}};
  const int f[2][3] = {{0, 1, 2}, {1, 3, 4}};
  if (format == "ascii") {
    std::string s = header;
    for (const auto& r : v) {
      for (int k = 0; k < 6; ++k) s += std::to_string(r[k]) + (k < 5 ? " " : "\n");
    }
    for (const auto& t : f) s += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
    return s;
  }
  Bytes b;
  b.big = format == "binary_big_endian";
  b.text(header);
  for (const auto& r : v)
    for (float c : r) b.put<float>(c);
  for (const auto& t : f) b.put<uint8_t>(3).put<int32_t>(t[0]).put<int32_t>(t[1]).put<int32_t>(t[2]);
  return b.data;
}

TEST(ZeroNormal, PlyDegenerateTriangleIsReadInEveryEncoding) {
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    SCOPED_TRACE(format);
    auto opened = open_mesh(write_file("occ.ply", occ_ply(format)));
    ASSERT_TRUE(opened.is_ok()) << opened.status().message();
    MeshReader& reader = *opened.value();
    TriangleBatch batch;
    auto more = reader.next(batch);
    ASSERT_TRUE(more.is_ok()) << more.status().message();
    ASSERT_EQ(batch.normals.size(), 6u);
    EXPECT_EQ(batch.normals[0], Vec3(0, 0, 1));
    EXPECT_EQ(batch.normals[3], Vec3(0, 0, 1));
    EXPECT_NEAR(batch.normals[4].y, std::sqrt(0.5f), 1e-6f);  // (0,0,1) + (0,1,0), normalised
    EXPECT_NEAR(batch.normals[4].z, std::sqrt(0.5f), 1e-6f);
    EXPECT_EQ(batch.normals[5], Vec3(0, 1, 0));
    EXPECT_EQ(reader.repaired_normals(), 1u);
  }
}

TEST(ZeroNormal, ObjPolygonCornerIsRepairedInEachFanTriangle) {
  // Corner 0 of the quad has the zero normal; it is in both fan triangles,
  // which lie in different planes (a folded quad), so each gets its own.
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\nvn 0 0 0\nvn 0 0 1\nf 1//1 2//2 3//2 4//2\n";
  auto opened = open_mesh(write_file("fold.obj", obj));
  ASSERT_TRUE(opened.is_ok()) << opened.status().message();
  TriangleBatch batch;
  ASSERT_TRUE(opened.value()->next(batch).is_ok());
  ASSERT_EQ(batch.normals.size(), 6u);
  EXPECT_EQ(batch.normals[0], Vec3(0, 0, 1));
  const Vec3 second = Vec3(face_normal(Vec3d(0, 0, 0), Vec3d(1, 1, 0), Vec3d(0, 1, 1)));
  EXPECT_NEAR(glm::length(batch.normals[3] - second), 0.0f, 1e-6f);
  EXPECT_EQ(opened.value()->repaired_normals(), 2u);
}

TEST(ZeroNormal, ManyBatchesOnTheBinaryFastPathAreAllCounted) {
  const int faces = 1000;
  Bytes b;
  b.text("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
         "property float nx\nproperty float ny\nproperty float nz\nelement face " + std::to_string(faces) +
         "\nproperty list uchar int vertex_indices\nend_header\n");
  for (float c : {0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f}) b.put<float>(c);
  for (int f = 0; f < faces; ++f) b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  auto opened = open_mesh(write_file("many.ply", b.data), ReaderOptions{64});
  ASSERT_TRUE(opened.is_ok()) << opened.status().message();
  MeshReader& reader = *opened.value();
  TriangleBatch batch;
  size_t triangles = 0;
  ::testing::internal::CaptureStderr();
  while (true) {
    auto more = reader.next(batch);
    ASSERT_TRUE(more.is_ok()) << more.status().message();
    if (!more.value()) break;
    for (size_t i = 0; i < batch.size(); ++i) EXPECT_EQ(batch.normals[3 * i], Vec3(0, 0, 1));
    triangles += batch.size();
  }
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(triangles, size_t(faces));
  EXPECT_EQ(reader.repaired_normals(), uint64_t(faces));
  EXPECT_NE(err.find("many.ply: 1000 triangle corners had a zero-length normal"), std::string::npos) << err;
}

TEST(ZeroNormal, WarningIsPrintedOncePerFile) {
  const auto path = write_file("once.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nf 1//1 2//1 3//1\n");
  ::testing::internal::CaptureStderr();
  auto first = read_all(path);
  auto second = read_all(path);  // a build reads its mesh twice
  const std::string err = ::testing::internal::GetCapturedStderr();
  ASSERT_TRUE(first.status.is_ok()) << first.status.message();
  ASSERT_TRUE(second.status.is_ok()) << second.status.message();
  EXPECT_EQ(second.normals, std::vector<Vec3>(3, Vec3(0, 0, 1)));
  const std::string warning = "raylod: warning: " + path.string() + ": 3 triangle corners had a zero-length normal";
  const size_t at = err.find(warning);
  ASSERT_NE(at, std::string::npos) << err;
  EXPECT_EQ(err.find("warning", at + warning.size()), std::string::npos) << err;
}

TEST(ZeroNormal, NonFiniteNormalsStayErrors) {
  EXPECT_READ_ERROR(write_file("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nvn nan 0 1\nf 1//1 2//2 3//1\n"),
                    "line 5: normal 2 is not finite");
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "property float nx\nproperty float ny\nproperty float nz\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n0 0 0 0 0 0\n1 0 0 0 inf 0\n0 1 0 0 0 1\n3 0 1 2\n";
  EXPECT_READ_ERROR(write_file("inf.ply", ply), "line 16: vertex 1 has a non-finite normal (0, inf, 0)");
}

}  // namespace
}  // namespace raylod
