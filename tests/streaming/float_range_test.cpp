// Coordinates and normals no float holds (past about +-3.4e38: "1e39" in
// text, or a double PLY property) are rejected when the file is read, with
// the file, the line or face, and the value named, instead of turning into
// inf (or "not a number") and failing far downstream. Values just inside the
// range, and tiny ones that round to zero, are read.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <limits>

#include "reader_test_util.h"
#include "streaming/text_scan.h"

namespace raylod {
namespace {

using test::Bytes;
using test::read_all;
using test::write_file;
using text::FloatParse;

FloatParse parse(const std::string& tok, float& out) { return text::parse_float(tok, out); }

TEST(FloatRange, ParseFloatSaysOutOfRangeForNumbersNoFloatHolds) {
  float f = 0;
  EXPECT_EQ(parse("1e39", f), FloatParse::OutOfRange);
  EXPECT_EQ(parse("-1e39", f), FloatParse::OutOfRange);
  EXPECT_EQ(parse("+1e39", f), FloatParse::OutOfRange);
  EXPECT_EQ(parse("3.4028236e38", f), FloatParse::OutOfRange);  // past FLT_MAX + half an ulp
  EXPECT_EQ(parse("1e400", f), FloatParse::OutOfRange);          // past double too
  EXPECT_EQ(parse("-1e99999999999999999999", f), FloatParse::OutOfRange);
  EXPECT_EQ(parse("1" + std::string(400, '0'), f), FloatParse::OutOfRange);
}

TEST(FloatRange, ParseFloatReadsTheEdgesAndRoundsTinyValuesToZero) {
  float f = 1;
  ASSERT_EQ(parse("3.4028234e38", f), FloatParse::Ok);
  EXPECT_EQ(f, FLT_MAX);
  ASSERT_EQ(parse("-3.4028235e38", f), FloatParse::Ok);
  EXPECT_EQ(f, -FLT_MAX);
  ASSERT_EQ(parse("1e-50", f), FloatParse::Ok);
  EXPECT_EQ(f, 0.0f);
  ASSERT_EQ(parse("-1e-400", f), FloatParse::Ok);
  EXPECT_TRUE(f == 0.0f && std::signbit(f));
  ASSERT_EQ(parse("0." + std::string(400, '0') + "1", f), FloatParse::Ok);
  EXPECT_EQ(f, 0.0f);
  ASSERT_EQ(parse("1e-45", f), FloatParse::Ok);  // the smallest subnormal
  EXPECT_GT(f, 0.0f);
  ASSERT_EQ(parse("+2.5", f), FloatParse::Ok);
  EXPECT_EQ(f, 2.5f);
  ASSERT_EQ(parse("nan", f), FloatParse::Ok);  // the callers reject non-finite values
  EXPECT_TRUE(std::isnan(f));
}

TEST(FloatRange, ParseFloatRejectsWhatIsNotANumber) {
  float f = 0;
  for (const char* tok : {"", "+", "abc", "1e39x", "1..0", "0x10", "1,5"})
    EXPECT_EQ(parse(tok, f), FloatParse::NotANumber) << tok;
}

std::string ply_header(const std::string& format, const std::string& type, bool normals) {
  std::string h = "ply\nformat " + format + " 1.0\nelement vertex 3\n";
  for (const char* c : {"x", "y", "z"}) h += "property " + type + " " + c + "\n";
  if (normals)
    for (const char* c : {"nx", "ny", "nz"}) h += "property " + type + " " + c + "\n";
  return h + "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
}

TEST(FloatRange, AsciiPlyCoordinatesAndNormals) {
  EXPECT_READ_ERROR(write_file("x.ply", ply_header("ascii", "float", false) + "0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n"),
                    "line 11: vertex 1 coordinate x = 1e39 is beyond the float range");
  EXPECT_READ_ERROR(write_file("y.ply", ply_header("ascii", "double", false) + "0 0 0\n1 0 0\n0 -1e400 0\n3 0 1 2\n"),
                    "line 12: vertex 2 coordinate y = -1e400 is beyond the float range");
  EXPECT_READ_ERROR(write_file("nz.ply", ply_header("ascii", "float", true) + "0 0 0 0 0 1\n1 0 0 0 0 1e39\n0 1 0 0 0 1\n3 0 1 2\n"),
                    "line 14: vertex 1 normal component nz = 1e39 is beyond the float range");
}

// Binary PLY with double properties: little endian takes the face fast path,
// big endian the generic decoder; both check the vertex where a face uses it.
std::string double_ply(bool big, const std::vector<double>& vertices, bool normals) {
  Bytes b;
  b.big = big;
  b.text(ply_header(big ? "binary_big_endian" : "binary_little_endian", "double", normals));
  for (double v : vertices) b.put<double>(v);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  return b.data;
}

TEST(FloatRange, BinaryPlyDoubleProperties) {
  for (bool big : {false, true}) {
    SCOPED_TRACE(big ? "big endian" : "little endian");
    EXPECT_READ_ERROR(write_file("x.ply", double_ply(big, {0, 0, 0, 1e39, 0, 0, 0, 1, 0}, false)),
                      "face 0: vertex 1 has a coordinate beyond the float range (about +-3.4e38) (1e+39, 0, 0)");
    EXPECT_READ_ERROR(write_file("z.ply", double_ply(big, {0, 0, 0, 1, 0, 0, 0, 1, -3.5e38}, false)),
                      "face 0: vertex 2 has a coordinate beyond the float range");
    EXPECT_READ_ERROR(write_file("n.ply", double_ply(big, {0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 1, 0, 2e300, 0, 1}, true)),
                      "face 0: vertex 2 has a normal component beyond the float range (about +-3.4e38) (2e+300, 0, 1)");
    // Inside the range: read, rounded to float.
    auto r = read_all(write_file("ok.ply", double_ply(big, {0, 0, 0, 3.4e38, 0, 0, 0, -3.4e38, 1e-60}, false)));
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    ASSERT_EQ(r.positions.size(), 3u);
    EXPECT_EQ(r.positions[1], Vec3(3.4e38f, 0, 0));
    EXPECT_EQ(r.positions[2], Vec3(0, -3.4e38f, 0));
  }
}

TEST(FloatRange, ObjVerticesAndNormals) {
  EXPECT_READ_ERROR(write_file("v.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n"),
                    "line 2: vertex 2 coordinate 1e39 is beyond the float range");
  EXPECT_READ_ERROR(write_file("vn.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 -1e39 1\nf 1//1 2//1 3//1\n"),
                    "line 4: normal 1 component -1e39 is beyond the float range");
  auto r = read_all(write_file("tiny.obj", "v 0 0 0\nv 1 1e-50 0\nv 0 1 0\nf 1 2 3\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions[1], Vec3(1, 0, 0));
}

// Every coordinate a float, but not their span: positions are kept relative
// to the first vertex, and 3e38 lies 6e38 from -3e38. Said as such, not as
// a non-finite coordinate the file does not hold.
TEST(FloatRange, TextMeshSpanningMoreThanTheFloatRange) {
  EXPECT_READ_ERROR(write_file("span.obj", "v -3e38 0 0\nv 3e38 0 0\nv 0 1 0\nf 1 2 3\n"),
                    "line 2: vertex 2 coordinate 3e38 lies more than the float range from the mesh's first vertex "
                    "(-3e+38, 0, 0): the mesh spans more than the float range");
  EXPECT_READ_ERROR(write_file("span.ply", ply_header("ascii", "float", false) + "-3e38 0 0\n3e38 0 0\n0 1 0\n3 0 1 2\n"),
                    "line 11: vertex 1 coordinate x = 3e38 lies more than the float range from the mesh's first vertex");
  // Within the range of each other, far from zero: read.
  auto r = read_all(write_file("far.obj", "v 3e38 0 0\nv 3.1e38 0 0\nv 3e38 1 0\nf 1 2 3\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.triangles(), 1u);
}

TEST(FloatRange, AsciiStlVerticesAndFacetNormals) {
  const std::string head = "solid s\nfacet normal 0 0 1\nouter loop\n";
  const std::string tail = "endloop\nendfacet\nendsolid s\n";
  EXPECT_READ_ERROR(write_file("v.stl", head + "vertex 0 0 0\nvertex 1e39 0 0\nvertex 0 1 0\n" + tail),
                    "line 5: vertex x = 1e39 is beyond the float range");
  EXPECT_READ_ERROR(write_file("n.stl", "solid s\nfacet normal 0 0 1e39\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n" + tail),
                    "line 2: facet normal z = 1e39 is beyond the float range");
}

}  // namespace
}  // namespace raylod
