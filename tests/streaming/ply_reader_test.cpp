// PLY reader: tiny exact cases, encodings against each other, property types,
// element order, batch boundaries, and every kind of bad input.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <limits>

#include "reader_test_util.h"

namespace raylod {
namespace {

using test::Bytes;
using test::read_all;
using test::write_file;

const std::string kQuadAscii =
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";

TEST(PlyReader, QuadBecomesTwoTrianglesFannedFromFirstCorner) {
  auto r = read_all(write_file("quad.ply", kQuadAscii));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.triangles(), 2u);
  const std::vector<Vec3> want = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  EXPECT_EQ(r.positions, want);
  EXPECT_TRUE(r.normals.empty());
  EXPECT_EQ(r.header.format, MeshFormat::Ply);
  EXPECT_EQ(r.header.encoding, "ascii");
  EXPECT_EQ(r.header.vertex_count, 4u);
  EXPECT_EQ(r.header.face_count, 1u);
  EXPECT_FALSE(r.header.has_normals);
}

TEST(PlyReader, PentagonFanAndCrlfLineEndings) {
  std::string s =
      "ply\r\nformat ascii 1.0\r\ncomment made by hand\r\nelement vertex 5\r\nproperty double x\r\nproperty double y\r\n"
      "property double z\r\nelement face 1\r\nproperty list uchar uint vertex_index\r\nend_header\r\n"
      "0 0 0\r\n1 0 0\r\n2 1 0\r\n1 2 0\r\n0 1 0\r\n5 0 1 2 3 4\r\n";
  auto r = read_all(write_file("pentagon.ply", s));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.triangles(), 3u);
  EXPECT_EQ(r.positions[6], Vec3(0, 0, 0));
  EXPECT_EQ(r.positions[7], Vec3(1, 2, 0));
  EXPECT_EQ(r.positions[8], Vec3(0, 1, 0));
}

// The same mesh (3 vertices with normals and an extra uchar property, a quad
// and a triangle, an extra face property and an extra element on either side)
// in ASCII, binary little endian and binary big endian.
struct RichMesh {
  std::vector<Vec3> p = {{0, 0, 0}, {1.5f, 0, 0}, {1.5f, 2.25f, -1}, {0, 2, 0.125f}};
  std::vector<Vec3> n = {{0, 0, 1}, {0, 0, 2}, {0, 3, 0}, {1, 0, 0}};  // non-unit ones get normalised
  std::string header(const std::string& format) const {
    return "ply\nformat " + format + " 1.0\n"
           "element material 2\nproperty uchar r\nproperty list uchar float weights\n"
           "element vertex 4\nproperty float x\nproperty uchar red\nproperty float y\nproperty double z\n"
           "property float nx\nproperty float ny\nproperty float nz\n"
           "element face 2\nproperty ushort flags\nproperty list uchar int vertex_indices\n"
           "property list int float texcoord\n"
           "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n";
  }
  std::string ascii() const {
    std::string s = header("ascii");
    s += "7 2 0.5 0.25\n9 0\n";
    for (int i = 0; i < 4; ++i) {
      char line[256];
      std::snprintf(line, sizeof line, "%.9g 200 %.9g %.17g %.9g %.9g %.9g\n", p[i].x, p[i].y, double(p[i].z), n[i].x,
                    n[i].y, n[i].z);
      s += line;
    }
    s += "1 4 0 1 2 3 2 0.5 0.5\n\n2 3 3 2 0 0\n0 1\n";
    return s;
  }
  std::string binary(bool big) const {
    Bytes b;
    b.big = big;
    b.text(header(big ? "binary_big_endian" : "binary_little_endian"));
    b.put<uint8_t>(7).put<uint8_t>(2).put<float>(0.5f).put<float>(0.25f).put<uint8_t>(9).put<uint8_t>(0);
    for (int i = 0; i < 4; ++i)
      b.put<float>(p[i].x).put<uint8_t>(200).put<float>(p[i].y).put<double>(p[i].z).put<float>(n[i].x).put<float>(n[i].y).put<float>(n[i].z);
    b.put<uint16_t>(1).put<uint8_t>(4).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2).put<int32_t>(3);
    b.put<int32_t>(2).put<float>(0.5f).put<float>(0.5f);
    b.put<uint16_t>(2).put<uint8_t>(3).put<int32_t>(3).put<int32_t>(2).put<int32_t>(0).put<int32_t>(0);
    b.put<int32_t>(0).put<int32_t>(1);
    return b.data;
  }
};

TEST(PlyReader, AsciiLittleAndBigEndianReadTheSame) {
  RichMesh m;
  auto a = read_all(write_file("rich_ascii.ply", m.ascii()));
  auto le = read_all(write_file("rich_le.ply", m.binary(false)));
  auto be = read_all(write_file("rich_be.ply", m.binary(true)));
  ASSERT_TRUE(a.status.is_ok()) << a.status.message();
  ASSERT_TRUE(le.status.is_ok()) << le.status.message();
  ASSERT_TRUE(be.status.is_ok()) << be.status.message();
  ASSERT_EQ(a.triangles(), 3u);
  const std::vector<Vec3> want = {m.p[0], m.p[1], m.p[2], m.p[0], m.p[2], m.p[3], m.p[3], m.p[2], m.p[0]};
  EXPECT_EQ(a.positions, want);
  EXPECT_EQ(le.positions, want);
  EXPECT_EQ(be.positions, want);
  EXPECT_EQ(le.normals, a.normals);
  EXPECT_EQ(be.normals, a.normals);
  ASSERT_EQ(a.normals.size(), 9u);
  EXPECT_EQ(a.normals[1], Vec3(0, 0, 1));  // (0, 0, 2) normalised
  EXPECT_EQ(a.normals[2], Vec3(0, 1, 0));
  EXPECT_TRUE(a.header.has_normals);
  EXPECT_EQ(be.header.encoding, "binary_big_endian");
  EXPECT_EQ(le.header.encoding, "binary_little_endian");
}

// Every PLY scalar type name (and its sized alias) as the coordinate type.
class PlyScalarType : public ::testing::TestWithParam<const char*> {};

TEST_P(PlyScalarType, CoordinatesOfEveryTypeInBothByteOrders) {
  const std::string type = GetParam();
  for (bool big : {false, true}) {
    Bytes b;
    b.big = big;
    b.text("ply\nformat " + std::string(big ? "binary_big_endian" : "binary_little_endian") +
           " 1.0\nelement vertex 3\nproperty " + type + " x\nproperty " + type + " y\nproperty " + type +
           " z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n");
    const int v[3][3] = {{1, 2, 3}, {4, 5, 6}, {7, 8, 100}};
    for (const auto& row : v)
      for (int c : row) {
        if (type == "char" || type == "int8") b.put<int8_t>(int8_t(c));
        else if (type == "uchar" || type == "uint8") b.put<uint8_t>(uint8_t(c));
        else if (type == "short" || type == "int16") b.put<int16_t>(int16_t(c));
        else if (type == "ushort" || type == "uint16") b.put<uint16_t>(uint16_t(c));
        else if (type == "int" || type == "int32") b.put<int32_t>(c);
        else if (type == "uint" || type == "uint32") b.put<uint32_t>(uint32_t(c));
        else if (type == "float" || type == "float32") b.put<float>(float(c));
        else b.put<double>(double(c));
      }
    b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
    auto r = read_all(write_file("types.ply", b.data));
    ASSERT_TRUE(r.status.is_ok()) << type << ": " << r.status.message();
    ASSERT_EQ(r.triangles(), 1u);
    EXPECT_EQ(r.positions[0], Vec3(1, 2, 3)) << type;
    EXPECT_EQ(r.positions[2], Vec3(7, 8, 100)) << type;
  }
}

INSTANTIATE_TEST_SUITE_P(AllTypes, PlyScalarType,
                         ::testing::Values("char", "int8", "uchar", "uint8", "short", "int16", "ushort", "uint16", "int",
                                           "int32", "uint", "uint32", "float", "float32", "double", "float64"));

TEST(PlyReader, IndexAndCountTypesOtherThanUcharInt) {
  // list ushort uint, big endian: goes through the generic decoder.
  Bytes b;
  b.big = true;
  b.text("ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 1\nproperty list ushort ushort vertex_indices\nend_header\n");
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 1.f, 1.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  b.put<uint16_t>(4).put<uint16_t>(0).put<uint16_t>(1).put<uint16_t>(2).put<uint16_t>(3);
  auto r = read_all(write_file("ushort.ply", b.data));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  auto q = read_all(write_file("quad.ply", kQuadAscii));
  EXPECT_EQ(r.positions, q.positions);
}

TEST(PlyReader, FaceElementBeforeVertexElement) {
  const std::string head =
      "element face 1\nproperty list uchar int vertex_indices\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  auto a = read_all(write_file("faces_first.ply", "ply\nformat ascii 1.0\n" + head + "3 2 1 0\n0 0 0\n1 0 0\n0 1 0\n"));
  ASSERT_TRUE(a.status.is_ok()) << a.status.message();
  const std::vector<Vec3> want = {{0, 1, 0}, {1, 0, 0}, {0, 0, 0}};
  EXPECT_EQ(a.positions, want);
  Bytes b;
  b.text("ply\nformat binary_little_endian 1.0\n" + head);
  b.put<uint8_t>(3).put<int32_t>(2).put<int32_t>(1).put<int32_t>(0);
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  auto r = read_all(write_file("faces_first_bin.ply", b.data));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, want);
}

// An n x n grid of quads, as ASCII or binary PLY; 2 n^2 triangles.
std::string grid_ply(int n, bool binary) {
  const int nv = (n + 1) * (n + 1);
  Bytes b;
  b.text("ply\nformat " + std::string(binary ? "binary_little_endian" : "ascii") + " 1.0\nelement vertex " +
         std::to_string(nv) + "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(n * n) + "\nproperty list uchar int vertex_indices\nend_header\n");
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      if (binary) {
        b.put<float>(float(i)).put<float>(float(j)).put<float>(float(i * j % 7));
      } else {
        b.text(std::to_string(i) + " " + std::to_string(j) + " " + std::to_string(i * j % 7) + "\n");
      }
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, c[4] = {a, a + 1, a + n + 2, a + n + 1};
      if (binary) {
        b.put<uint8_t>(4);
        for (int k : c) b.put<int32_t>(k);
      } else {
        b.text("4 " + std::to_string(c[0]) + " " + std::to_string(c[1]) + " " + std::to_string(c[2]) + " " +
               std::to_string(c[3]) + "\n");
      }
    }
  return b.data;
}

TEST(PlyReader, BatchBoundariesNeverSplitAPolygonAndLoseNothing) {
  for (bool binary : {false, true}) {
    auto path = write_file(binary ? "grid_bin.ply" : "grid_ascii.ply", grid_ply(20, binary));
    auto whole = read_all(path, 1 << 20);
    ASSERT_TRUE(whole.status.is_ok()) << whole.status.message();
    ASSERT_EQ(whole.triangles(), 800u);
    ASSERT_EQ(whole.batch_sizes.size(), 1u);
    for (size_t batch : {1, 2, 7, 64, 799, 800}) {
      auto r = read_all(path, batch);
      ASSERT_TRUE(r.status.is_ok()) << r.status.message();
      EXPECT_EQ(r.positions, whole.positions) << "batch " << batch;
      for (size_t i = 0; i < r.batch_sizes.size(); ++i) {
        // A quad is never split, so a batch overshoots an odd limit by one triangle.
        const size_t full = batch + batch % 2;
        if (i + 1 < r.batch_sizes.size()) {
          EXPECT_EQ(r.batch_sizes[i], full) << "batch " << batch;
        } else {
          EXPECT_LE(r.batch_sizes[i], full) << "batch " << batch;
        }
      }
    }
  }
}

TEST(PlyReader, MixedBinaryAndAsciiGridsAgree) {
  auto a = read_all(write_file("g_ascii.ply", grid_ply(5, false)));
  auto b = read_all(write_file("g_bin.ply", grid_ply(5, true)));
  ASSERT_TRUE(a.status.is_ok() && b.status.is_ok());
  EXPECT_EQ(a.positions, b.positions);
}

// ---- bad input: every case names the file and the problem ----

std::string simple_header(const std::string& format = "ascii", int nv = 3, int nf = 1,
                          const std::string& vtype = "float", const std::string& extra_vertex = "") {
  return "ply\nformat " + format + " 1.0\nelement vertex " + std::to_string(nv) + "\nproperty " + vtype +
         " x\nproperty " + vtype + " y\nproperty " + vtype + " z\n" + extra_vertex + "element face " +
         std::to_string(nf) + "\nproperty list uchar int vertex_indices\nend_header\n";
}
const std::string kTri = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

TEST(PlyReader, ClassicMacLineEndings) {
  std::string text = simple_header() + kTri;
  for (char& c : text)
    if (c == '\n') c = '\r';
  auto r = test::read_all(write_file("cr.ply", text));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.triangles(), 1u);
  EXPECT_EQ(r.positions, test::read_all(write_file("lf.ply", simple_header() + kTri)).positions);
}

TEST(PlyReaderErrors, EmptyFile) { EXPECT_READ_ERROR(write_file("empty.ply", ""), "empty file"); }

TEST(PlyReaderErrors, NotAPlyFile) {
  EXPECT_READ_ERROR(write_file("notply.ply", "solid x\nendsolid x\n"), "not a PLY file");
}

TEST(PlyReaderErrors, HeaderWithoutEndHeader) {
  EXPECT_READ_ERROR(write_file("noend.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"), "end_header");
}

TEST(PlyReaderErrors, UnknownEncodingAndVersion) {
  EXPECT_READ_ERROR(write_file("enc.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"), "line 2: unknown PLY encoding");
  EXPECT_READ_ERROR(write_file("ver.ply", "ply\nformat ascii 2.0\nend_header\n"), "line 2: unsupported PLY version");
}

TEST(PlyReaderErrors, MissingFormatLine) {
  EXPECT_READ_ERROR(write_file("nofmt.ply", "ply\nelement vertex 0\nend_header\n"), "no format line");
}

TEST(PlyReaderErrors, UnsupportedPropertyTypes) {
  EXPECT_READ_ERROR(write_file("int64.ply", simple_header("ascii", 3, 1, "int64") + kTri), "line 4: unsupported property type 'int64'");
  EXPECT_READ_ERROR(write_file("half.ply", simple_header("ascii", 3, 1, "half") + kTri), "unsupported property type 'half'");
  EXPECT_READ_ERROR(write_file("str.ply", simple_header("ascii", 3, 1, "float", "property string name\n") + kTri),
                    "unsupported property type 'string'");
  std::string float_count = simple_header();
  float_count.replace(float_count.find("list uchar int"), 14, "list float int");
  EXPECT_READ_ERROR(write_file("fcount.ply", float_count + kTri), "not an integer type");
  std::string float_index = simple_header();
  float_index.replace(float_index.find("list uchar int"), 14, "list uchar float");
  EXPECT_READ_ERROR(write_file("findex.ply", float_index + kTri), "non-integer index type");
}

TEST(PlyReaderErrors, UnknownHeaderKeywordAndMalformedLines) {
  EXPECT_READ_ERROR(write_file("kw.ply", "ply\nformat ascii 1.0\nvertex 3\nend_header\n"), "line 3: unknown header keyword 'vertex'");
  EXPECT_READ_ERROR(write_file("elem.ply", "ply\nformat ascii 1.0\nelement vertex many\nend_header\n"), "line 3: element 'vertex' has an invalid count");
  EXPECT_READ_ERROR(write_file("prop.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n"), "line 3: property declared before any element");
  EXPECT_READ_ERROR(write_file("twice.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                            "property float x\nend_header\n"),
                    "line 6: property 'x' is declared twice in element 'vertex'");
}

TEST(PlyReaderErrors, MissingElementsAndProperties) {
  EXPECT_READ_ERROR(write_file("noface.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n"),
                    "no 'face' element");
  EXPECT_READ_ERROR(write_file("novertex.ply", "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"),
                    "no 'vertex' element");
  EXPECT_READ_ERROR(write_file("noz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                          "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n"),
                    "no 'z' property");
  EXPECT_READ_ERROR(write_file("partialn.ply", simple_header("ascii", 3, 1, "float", "property float nx\n") + kTri),
                    "some but not all of nx, ny, nz");
  EXPECT_READ_ERROR(write_file("noindices.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                                "property float z\nelement face 1\nproperty list uchar int corners\nend_header\n" + kTri),
                    "no 'vertex_indices'");
}

TEST(PlyReaderErrors, EmptyMeshes) {
  EXPECT_READ_ERROR(write_file("nofaces.ply", simple_header("ascii", 3, 0) + "0 0 0\n1 0 0\n0 1 0\n"), "empty mesh");
  EXPECT_READ_ERROR(write_file("novertices.ply", simple_header("ascii", 0, 0)), "empty mesh");
}

TEST(PlyReaderErrors, AsciiWrongCountsInHeader) {
  // Too few vertex lines for the declared count: the file ends early.
  EXPECT_READ_ERROR(write_file("fewv.ply", simple_header("ascii", 4, 1) + "0 0 0\n1 0 0\n0 1 0\n"),
                    "truncated: the file ends after 3 of 4 'vertex' records");
  // More faces than declared.
  EXPECT_READ_ERROR(write_file("morefaces.ply", simple_header() + kTri + "3 2 1 0\n"), "line 14: more data than the header declares");
  // Fewer faces than declared.
  EXPECT_READ_ERROR(write_file("fewf.ply", simple_header("ascii", 3, 2) + kTri), "truncated: the file ends after 1 of 2 faces");
}

TEST(PlyReaderErrors, AsciiMalformedRecords) {
  EXPECT_READ_ERROR(write_file("shortv.ply", simple_header() + "0 0 0\n1 0\n0 1 0\n3 0 1 2\n"), "line 11: vertex 1 has too few values");
  EXPECT_READ_ERROR(write_file("longv.ply", simple_header() + "0 0 0\n1 0 0 5\n0 1 0\n3 0 1 2\n"), "line 11: vertex 1 has more values");
  EXPECT_READ_ERROR(write_file("nan_text.ply", simple_header() + "0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n"), "line 11: 'zero' is not a number");
  EXPECT_READ_ERROR(write_file("shortf.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n"), "line 13: face has fewer indices");
  EXPECT_READ_ERROR(write_file("hugef.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n"),
                    "line 13: list length 4000000000 does not fit the header's count type (largest 255)");
  // A uchar count holds at most 255, in text as in binary.
  EXPECT_READ_ERROR(write_file("ucharf.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n"),
                    "line 13: list length 300 does not fit the header's count type (largest 255)");
  EXPECT_READ_ERROR(write_file("longf.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 2\n"), "line 13: face has more values");
  EXPECT_READ_ERROR(write_file("badidx.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1 x\n"), "line 13: vertex index 'x' is not an integer");
}

TEST(PlyReaderErrors, IndexOutOfRange) {
  EXPECT_READ_ERROR(write_file("oob.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
                    "line 13: vertex index 3 is out of range (the file has 3 vertices)");
  EXPECT_READ_ERROR(write_file("neg.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n"), "vertex index -1 is out of range");
  Bytes b;
  b.text(simple_header("binary_little_endian"));
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(7).put<int32_t>(2);
  EXPECT_READ_ERROR(write_file("oob_bin.ply", b.data), "face 0: vertex index 7 is out of range");
}

TEST(PlyReaderErrors, FaceWithTooFewCorners) {
  EXPECT_READ_ERROR(write_file("two.ply", simple_header() + "0 0 0\n1 0 0\n0 1 0\n2 0 1\n"), "line 13: a face has 2 corners");
  Bytes b;
  b.text(simple_header("binary_little_endian"));
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  b.put<uint8_t>(0);
  EXPECT_READ_ERROR(write_file("zero_bin.ply", b.data), "face 0: a face has 0 corners");
  // Its counts fit the file: no hint at a wrong vertex count (the size alone
  // fitted two vertices and one triangle).
  EXPECT_EQ(test::read_error(write_file("zero_bin2.ply", b.data)).find("vertex count"), std::string::npos);
}

// A binary header that declares the wrong number of vertices shifts every
// face record, so the faces read as nonsense ("a face has 0 corners"); the
// message then says which vertex count the file's size fits.
TEST(PlyReaderErrors, BinaryWrongVertexCountIsNamed) {
  auto square = [](int declared) {
    Bytes b;
    b.text(simple_header("binary_little_endian", declared, 2));
    for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 1.f, 1.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
    b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
    b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(2).put<int32_t>(3);
    return b.data;
  };
  EXPECT_EQ(test::read_all(write_file("square.ply", square(4))).triangles(), 2u);
  for (int declared : {3, 5})
    EXPECT_READ_ERROR(write_file("square" + std::to_string(declared) + ".ply", square(declared)),
                      "(the header declares " + std::to_string(declared) +
                          " vertices, but with 2 triangles the file's size fits 4: is the header's vertex count "
                          "wrong?)");
  // A face that really has too few corners, in a file whose counts fit, gets no such hint.
  Bytes b;
  b.text(simple_header("binary_little_endian"));
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  b.put<uint8_t>(2).put<int32_t>(0).put<int32_t>(1);
  const std::string message = test::read_error(write_file("two_bin.ply", b.data));
  EXPECT_NE(message.find("a face has 2 corners; at least 3 are needed"), std::string::npos) << message;
  EXPECT_EQ(message.find("vertex count"), std::string::npos) << message;
}

TEST(PlyReaderErrors, NonFiniteCoordinates) {
  EXPECT_READ_ERROR(write_file("nan.ply", simple_header() + "0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n"), "line 11: vertex 1 has a non-finite coordinate");
  EXPECT_READ_ERROR(write_file("inf.ply", simple_header() + "0 0 0\n1 0 -inf\n0 1 0\n3 0 1 2\n"), "line 11: vertex 1 has a non-finite coordinate");
  for (float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    Bytes b;
    b.text(simple_header("binary_little_endian"));
    for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, bad, 0.f, 1.f, 0.f}) b.put<float>(c);
    b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
    EXPECT_READ_ERROR(write_file("nonfinite_bin.ply", b.data), "face 0: vertex 1 has a non-finite coordinate");
  }
}

// A zero-length normal is replaced by the triangle's face normal (here +Z);
// see zero_normal_test.cpp for the rule. A NaN normal stays an error.
TEST(PlyReader, ZeroLengthNormalGetsTheFaceNormal) {
  const std::string h = simple_header("ascii", 3, 1, "float", "property float nx\nproperty float ny\nproperty float nz\n");
  auto r = read_all(write_file("zeron.ply", h + "0 0 0 0 0 1\n1 0 0 0 0 0\n0 1 0 0 0 1\n3 0 1 2\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.normals, std::vector<Vec3>(3, Vec3(0, 0, 1)));
  Bytes b;
  b.big = true;
  b.text(simple_header("binary_big_endian", 3, 1, "float", "property float nx\nproperty float ny\nproperty float nz\n"));
  for (float c : {0.f, 0.f, 0.f, 0.f, 0.f, 1.f, 1.f, 0.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 0.f, 0.f, 0.f, 0.f}) b.put<float>(c);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  r = read_all(write_file("zeron_bin.ply", b.data));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.normals, std::vector<Vec3>(3, Vec3(0, 0, 1)));
}

TEST(PlyReaderErrors, NonFiniteNormal) {
  const std::string h = simple_header("ascii", 3, 1, "float", "property float nx\nproperty float ny\nproperty float nz\n");
  EXPECT_READ_ERROR(write_file("nann.ply", h + "0 0 0 0 0 1\n1 0 0 nan 0 0\n0 1 0 0 0 1\n3 0 1 2\n"),
                    "line 16: vertex 1 has a non-finite normal (nan, 0, 0)");
  Bytes b;
  b.big = true;
  b.text(simple_header("binary_big_endian", 3, 1, "float", "property float nx\nproperty float ny\nproperty float nz\n"));
  const float inf = std::numeric_limits<float>::infinity();
  for (float c : {0.f, 0.f, 0.f, 0.f, 0.f, 1.f, 1.f, 0.f, 0.f, 0.f, 0.f, 1.f, 0.f, 1.f, 0.f, 0.f, inf, 0.f}) b.put<float>(c);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  EXPECT_READ_ERROR(write_file("infn_bin.ply", b.data), "face 0: vertex 2 has a non-finite normal (0, inf, 0)");
}

// Little endian, float x y z nx ny nz, uchar/int faces: the in-place fast path.
std::string fast_path_ply(const std::vector<float>& vertex_data, int faces = 1) {
  Bytes b;
  b.text(simple_header("binary_little_endian", 3, faces, "float", "property float nx\nproperty float ny\nproperty float nz\n"));
  for (float c : vertex_data) b.put<float>(c);
  for (int f = 0; f < faces; ++f) b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  return b.data;
}

TEST(PlyReader, FastPathNormalisesNonUnitNormals) {
  auto r = read_all(write_file("fast_n.ply", fast_path_ply({0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 4, 0, 1, 0, 3, 4, 0}, 2)));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.normals.size(), 6u);
  EXPECT_EQ(r.normals[1], Vec3(0, 0, 1));
  EXPECT_NEAR(r.normals[2].x, 0.6f, 1e-7f);
  EXPECT_NEAR(r.normals[2].y, 0.8f, 1e-7f);
  EXPECT_EQ(r.normals[5], r.normals[2]);
}

TEST(PlyReader, FastPathReplacesZeroNormals) {
  auto r = read_all(write_file("fast_zero.ply", fast_path_ply({0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1})));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.normals, std::vector<Vec3>(3, Vec3(0, 0, 1)));
}

TEST(PlyReaderErrors, FastPathBadNormalsAndCoordinates) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  EXPECT_READ_ERROR(write_file("fast_nan_n.ply", fast_path_ply({0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 1, 0, nan, 0, 1})),
                    "face 0: vertex 2 has a non-finite normal");
  EXPECT_READ_ERROR(write_file("fast_inf_p.ply", fast_path_ply({0, inf, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 1})),
                    "face 0: vertex 0 has a non-finite coordinate");
}

TEST(PlyReaderErrors, BinaryTruncated) {
  Bytes b;
  b.text(simple_header("binary_little_endian"));
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  const std::string whole = b.data;
  // Cut inside the vertex data, and inside the face.
  EXPECT_READ_ERROR(write_file("trunc_v.ply", whole.substr(0, whole.size() - 20)), "truncated: element 'vertex' needs 3 records");
  EXPECT_READ_ERROR(write_file("trunc_f.ply", whole.substr(0, whole.size() - 2)), "truncated: the file ends inside face 0 of 1");
  // A header that declares two faces but holds one.
  std::string two = whole;
  two.replace(two.find("element face 1"), 14, "element face 2");
  EXPECT_READ_ERROR(write_file("trunc_count.ply", two), "truncated: the file ends inside face 1 of 2");
  // Generic decoder (big endian) truncated inside a face list.
  Bytes be;
  be.big = true;
  be.text(simple_header("binary_big_endian"));
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) be.put<float>(c);
  be.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1);
  EXPECT_READ_ERROR(write_file("trunc_be.ply", be.data), "truncated: the file ends inside face 0 of 1");
}

TEST(PlyReaderErrors, BinaryTrailingDataMeansWrongCount) {
  Bytes b;
  b.text(simple_header("binary_little_endian"));
  for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  b.put<uint8_t>(3).put<int32_t>(2).put<int32_t>(1).put<int32_t>(0);  // one face more than declared
  EXPECT_READ_ERROR(write_file("trailing.ply", b.data), "13 bytes of unexpected data after the last element");
}

// Found by tests/fuzz/fuzz_ply: skipping the elements after the faces went
// once round a loop per declared record without moving when a record took no
// bytes (an element without properties) or when the file ended before a
// list's count, so a small header declaring 10^15 such records hung the
// reader. Each read runs in a child process that SIGALRM ends if it hangs.
TEST(PlyReaderErrors, ElementsAfterTheFacesCannotHangTheReader) {
  auto file = [](const std::string& name, const std::string& extra_header, const std::string& extra_data) {
    Bytes b;
    b.text("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
           "property float z\nelement face 1\nproperty list uchar int vertex_indices\n" + extra_header + "end_header\n");
    for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) b.put<float>(c);
    b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
    return write_file(name, b.data + extra_data);
  };
  // Exit status 0 if the read ends (within 20 s) with `expected` ("" = success) in its status.
  auto read_ends_with = [](const std::filesystem::path& path, const std::string& expected) {
    ::alarm(20);
    const auto r = test::read_all(path);
    const bool as_expected = expected.empty() ? r.status.is_ok() && r.triangles() == 1
                                              : r.status.message().find(expected) != std::string::npos;
    std::_Exit(as_expected ? 0 : 3);
  };
  const auto empty = file("no-properties.ply", "element nothing 1000000000000000\n", "");
  EXPECT_EXIT(read_ends_with(empty, ""), ::testing::ExitedWithCode(0), "");
  const auto list = file("list-at-eof.ply", "element tail 1000000000000000\nproperty list uchar int values\n", "");
  EXPECT_EXIT(read_ends_with(list, "truncated: the file ends inside tail 0 of"), ::testing::ExitedWithCode(0), "");
  const auto one = file("list-one-record.ply", "element tail 1000000000000000\nproperty list uchar int values\n",
                        std::string(1, '\0'));
  EXPECT_EXIT(read_ends_with(one, "truncated: the file ends inside tail 1 of"), ::testing::ExitedWithCode(0), "");
}

TEST(PlyReaderErrors, BinaryListInVertexElement) {
  Bytes b;
  b.text(simple_header("binary_little_endian", 3, 1, "float", "property list uchar float extra\n"));
  EXPECT_READ_ERROR(write_file("vlist.ply", b.data), "list property in the vertex element is not supported");
}

TEST(PlyReaderErrors, MissingFile) {
  EXPECT_READ_ERROR(test::scratch_dir() / "does_not_exist.ply", "no such file");
}

}  // namespace
}  // namespace raylod
