// OBJ reader: index forms, relative indices, polygons, normals policy, ignored
// statements, line continuation, batch boundaries and bad input with line numbers.
#include <gtest/gtest.h>

#include "reader_test_util.h"

namespace raylod {
namespace {

using test::read_all;
using test::write_file;

const std::string kSquare = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

TEST(ObjReader, QuadBecomesTwoTriangles) {
  auto r = read_all(write_file("quad.obj", kSquare + "f 1 2 3 4\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  const std::vector<Vec3> want = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  EXPECT_EQ(r.positions, want);
  EXPECT_EQ(r.header.format, MeshFormat::Obj);
  EXPECT_EQ(r.header.vertex_count, 4u);
  EXPECT_EQ(r.header.face_count, 1u);
  EXPECT_FALSE(r.header.has_normals);
}

TEST(ObjReader, AllIndexFormsAndRelativeIndicesAgree) {
  const std::string vt = "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
  const std::string forms[] = {"f 1 2 3 4\n", "f 1/1 2/2 3/3 4/4\n", "f -4 -3 -2 -1\n", "f -4/-4 -3/-3 -2/-2 -1/-1\n"};
  auto ref = read_all(write_file("ref.obj", kSquare + "f 1 2 3 4\n"));
  for (const auto& f : forms) {
    auto r = read_all(write_file("form.obj", kSquare + vt + f));
    ASSERT_TRUE(r.status.is_ok()) << f << r.status.message();
    EXPECT_EQ(r.positions, ref.positions) << f;
  }
}

TEST(ObjReader, NormalsThroughDoubleSlashAndTripleForms) {
  const std::string vn = "vn 0 0 2\nvn 0 1 0\n";  // the first is normalised
  for (const std::string f : {"f 1//1 2//1 3//2\n", "f 1/1/1 2/1/1 3/1/2\n", "f -4//-2 -3//-2 -2//-1\n"}) {
    auto r = read_all(write_file("n.obj", kSquare + "vt 0 0\n" + vn + f));
    ASSERT_TRUE(r.status.is_ok()) << f << r.status.message();
    EXPECT_TRUE(r.header.has_normals);
    const std::vector<Vec3> want = {{0, 0, 1}, {0, 0, 1}, {0, 1, 0}};
    EXPECT_EQ(r.normals, want) << f;
  }
}

TEST(ObjReader, RelativeIndicesCountOnlyVerticesDefinedSoFar) {
  // Two triangles, each defined just before its face with -3 -2 -1.
  auto r = read_all(write_file("rel.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 0 0\nv 6 0 0\nv 5 1 0\nf -3 -2 -1\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.triangles(), 2u);
  EXPECT_EQ(r.positions[3], Vec3(5, 0, 0));
}

TEST(ObjReader, MixedNormalsAreDroppedForTheWholeMesh) {
  auto r = read_all(write_file("mixed.obj", kSquare + "vn 0 0 1\nf 1//1 2//1 3//1\nf 1 3 4\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_FALSE(r.header.has_normals);
  EXPECT_TRUE(r.normals.empty());
  EXPECT_EQ(r.triangles(), 2u);
}

TEST(ObjReader, IgnoredStatementsCommentsAndContinuations) {
  const std::string s =
      "# a comment\nmtllib x.mtl\no thing\ng group\ns 1\nusemtl red\n"
      "v 0 0 0 1.0\nv 1 0 0 # trailing comment\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\nvt 0 0\nvp 0.5\n"
      "l 1 2\np 3\nf 1 2 \\\n  3 \\\n 4\n\n";
  auto r = read_all(write_file("misc.obj", s));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  auto ref = read_all(write_file("ref.obj", kSquare + "f 1 2 3 4\n"));
  EXPECT_EQ(r.positions, ref.positions);
}

TEST(ObjReader, CrlfAndForwardReferences) {
  // A positive index may name a vertex defined later in the file.
  auto r = read_all(write_file("fwd.obj", "f 1 2 3\r\nv 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions[2], Vec3(0, 1, 0));
}

TEST(ObjReader, ByteOrderMarkIsSkipped) {
  // A UTF-8 byte order mark before the first 'v' used to hide that vertex
  // (the line's keyword read as "\xEF\xBB\xBFv"), shifting every index.
  const std::string bom = "\xEF\xBB\xBF";
  auto plain = read_all(write_file("plain.obj", "v 5 5 5\n" + kSquare + "f 1 2 3\n"));
  auto marked = read_all(write_file("bom.obj", bom + "v 5 5 5\n" + kSquare + "f 1 2 3\n"));
  ASSERT_TRUE(plain.status.is_ok() && marked.status.is_ok()) << marked.status.message();
  EXPECT_EQ(marked.positions, plain.positions);
  EXPECT_EQ(marked.positions[0], Vec3(5, 5, 5));
  EXPECT_EQ(marked.header.vertex_count, 5u);
}

TEST(ObjReader, ClassicMacLineEndings) {
  // Lines ended by "\r" alone (classic Mac OS) read as lines, not as one
  // line with no faces; the line numbers in messages count them.
  auto cr = [](std::string text) {
    for (char& c : text)
      if (c == '\n') c = '\r';
    return text;
  };
  const std::string obj = "v 5 5 5\n" + kSquare + "f 1 2 3\nf 2 3 4\n";
  auto unix_style = read_all(write_file("lf.obj", obj));
  auto mac_style = read_all(write_file("cr.obj", cr(obj)));
  ASSERT_TRUE(unix_style.status.is_ok() && mac_style.status.is_ok()) << mac_style.status.message();
  EXPECT_EQ(mac_style.positions, unix_style.positions);
  EXPECT_EQ(mac_style.triangles(), 2u);
  EXPECT_READ_ERROR(write_file("cr_bad.obj", cr("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")), "line 4");
}

TEST(ObjReader, BatchBoundaries) {
  std::string s;
  const int n = 12;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) s += "v " + std::to_string(i) + " " + std::to_string(j) + " 0\n";
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1;
      s += "f " + std::to_string(a) + " " + std::to_string(a + 1) + " " + std::to_string(a + n + 2) + " " +
           std::to_string(a + n + 1) + "\n";
    }
  auto path = write_file("grid.obj", s);
  auto whole = read_all(path, 1 << 20);
  ASSERT_TRUE(whole.status.is_ok()) << whole.status.message();
  ASSERT_EQ(whole.triangles(), 2u * n * n);
  for (size_t batch : {1, 5, 100, 288}) {
    auto r = read_all(path, batch);
    ASSERT_TRUE(r.status.is_ok());
    EXPECT_EQ(r.positions, whole.positions);
    for (size_t s2 : r.batch_sizes) EXPECT_LE(s2, batch + batch % 2);
  }
}

// ---- bad input, with line numbers ----

TEST(ObjReaderErrors, EmptyFileAndEmptyMeshes) {
  EXPECT_READ_ERROR(write_file("empty.obj", ""), "empty file");
  EXPECT_READ_ERROR(write_file("nofaces.obj", kSquare), "empty mesh: no faces");
  EXPECT_READ_ERROR(write_file("comments.obj", "# nothing\n\n"), "empty mesh");
}

TEST(ObjReaderErrors, IndexOutOfRange) {
  EXPECT_READ_ERROR(write_file("oob.obj", kSquare + "f 1 2 5\n"), "line 5: vertex index 5 is out of range (the file has 4 vertices)");
  EXPECT_READ_ERROR(write_file("rel.obj", kSquare + "f -1 -2 -5\n"), "line 5: relative vertex index -5 refers before the first vertex");
  EXPECT_READ_ERROR(write_file("zero.obj", kSquare + "f 0 1 2\n"), "line 5: bad face corner '0'");
  EXPECT_READ_ERROR(write_file("nrm.obj", kSquare + "vn 0 0 1\nf 1//1 2//2 3//1\n"), "line 6: normal index 2 is out of range (the file has 1 normals)");
  EXPECT_READ_ERROR(write_file("nrel.obj", kSquare + "vn 0 0 1\nf 1//-2 2//1 3//1\n"), "line 6: relative normal index -2 refers before the first normal");
  // Texture coordinates are not read, but their indices are checked like the others'.
  EXPECT_READ_ERROR(write_file("tex.obj", kSquare + "vt 0 0\nf 1/1 2/2 3/1\n"),
                    "line 6: texture coordinate index 2 is out of range (the file has 1 texture coordinates)");
  EXPECT_READ_ERROR(write_file("trel.obj", kSquare + "vt 0 0\nf 1/-2 2/1 3/1\n"),
                    "line 6: relative texture coordinate index -2 refers before the first texture coordinate");
  const auto textured = read_all(write_file("texok.obj", kSquare + "vt 0 0\nvt 1 0\nf 1/1 2/2 3/-1\n"));
  EXPECT_TRUE(textured.status.ok()) << textured.status.message();
  EXPECT_EQ(textured.triangles(), 1u);
}

TEST(ObjReaderErrors, MalformedStatements) {
  EXPECT_READ_ERROR(write_file("corner.obj", kSquare + "f 1/a 2 3\n"), "line 5: bad face corner '1/a'");
  EXPECT_READ_ERROR(write_file("slash.obj", kSquare + "f 1/ 2 3\n"), "line 5: bad face corner '1/'");
  EXPECT_READ_ERROR(write_file("two.obj", kSquare + "f 1 2\n"), "line 5: a face has 2 corners");
  EXPECT_READ_ERROR(write_file("v2.obj", "v 0 0\n"), "line 1: 'v' needs 3 coordinates");
  EXPECT_READ_ERROR(write_file("vx.obj", "v 0 zero 0\n"), "line 1: 'zero' is not a number");
  EXPECT_READ_ERROR(write_file("bin.obj", std::string("v 0 0 0\0\1\2", 10)), "contains binary data");
}

TEST(ObjReaderErrors, NonFiniteCoordinatesAndNormals) {
  EXPECT_READ_ERROR(write_file("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"), "line 2: vertex 2 has a non-finite coordinate");
  EXPECT_READ_ERROR(write_file("inf.obj", "v 0 0 0\nv 1 0 0\nv 0 1 -inf\nf 1 2 3\n"), "line 3: vertex 3 has a non-finite coordinate");
  EXPECT_READ_ERROR(write_file("nann.obj", kSquare + "vn nan 0 1\nf 1//1 2//1 3//1\n"), "line 5: normal 1 is not finite");
}

// A zero-length normal is replaced by the face normal (see zero_normal_test.cpp).
TEST(ObjReader, ZeroLengthNormalGetsTheFaceNormal) {
  auto r = read_all(write_file("zeron.obj", kSquare + "vn 0 0 1\nvn 0 0 0\nf 1//1 2//2 3//1\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.normals, std::vector<Vec3>(3, Vec3(0, 0, 1)));
}

TEST(ObjReaderErrors, WrongExtensionForContent) {
  // A PLY file named .obj is read as OBJ and rejected, not silently accepted.
  EXPECT_READ_ERROR(write_file("really_ply.obj", "ply\nformat ascii 1.0\nend_header\n"), "empty mesh");
}

}  // namespace
}  // namespace raylod
