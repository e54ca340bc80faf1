// STL reader: tiny exact cases (ASCII equals binary), the binary/ASCII
// decision by size, bad input, and the npm stl-models broken/misc set in data/.
#include <gtest/gtest.h>

#include <cctype>

#include <limits>

#include "reader_test_util.h"

namespace raylod {
namespace {

using test::Bytes;
using test::read_all;
using test::write_file;

const std::vector<Vec3> kTwo = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {0, 0, 1.5f}, {1, 0, 0}};

std::string ascii_stl(const std::vector<Vec3>& p, const std::string& normal = "0 0 1") {
  std::string s = "solid two triangles\n";
  for (size_t t = 0; t < p.size() / 3; ++t) {
    s += "  facet normal " + normal + "\n    outer loop\n";
    for (int k = 0; k < 3; ++k) {
      char line[128];
      std::snprintf(line, sizeof line, "      vertex %.9g %.9g %.9g\n", p[3 * t + k].x, p[3 * t + k].y, p[3 * t + k].z);
      s += line;
    }
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid two triangles\n";
}

std::string binary_stl(const std::vector<Vec3>& p, const std::string& header = "binary", float nx = 0) {
  Bytes b;
  std::string h = header;
  h.resize(80, '\0');
  b.text(h).put<uint32_t>(uint32_t(p.size() / 3));
  for (size_t t = 0; t < p.size() / 3; ++t) {
    b.put<float>(nx).put<float>(0).put<float>(1);
    for (int k = 0; k < 3; ++k) b.put<float>(p[3 * t + k].x).put<float>(p[3 * t + k].y).put<float>(p[3 * t + k].z);
    b.put<uint16_t>(0);
  }
  return b.data;
}

TEST(StlReader, AsciiExact) {
  auto r = read_all(write_file("two.stl", ascii_stl(kTwo)));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, kTwo);
  EXPECT_TRUE(r.normals.empty());
  EXPECT_EQ(r.header.encoding, "ascii");
  EXPECT_EQ(r.header.face_count, 2u);
  EXPECT_EQ(r.header.vertex_count, 6u);
  EXPECT_FALSE(r.header.has_normals);
}

TEST(StlReader, AsciiWithAByteOrderMark) {
  // Read as ASCII, not as a binary file with a wrong triangle count.
  auto plain = read_all(write_file("plain.stl", ascii_stl(kTwo)));
  auto marked = read_all(write_file("bom.stl", "\xEF\xBB\xBF" + ascii_stl(kTwo)));
  ASSERT_TRUE(marked.status.is_ok()) << marked.status.message();
  EXPECT_EQ(marked.positions, plain.positions);
  EXPECT_EQ(marked.header.encoding, "ascii");
}

TEST(StlReader, BinaryEqualsAscii) {
  auto b = read_all(write_file("two_bin.stl", binary_stl(kTwo)));
  ASSERT_TRUE(b.status.is_ok()) << b.status.message();
  EXPECT_EQ(b.positions, kTwo);
  EXPECT_EQ(b.header.encoding, "binary");
}

TEST(StlReader, BinaryWhoseHeaderStartsWithSolidIsDecidedBySize) {
  auto b = read_all(write_file("solid_bin.stl", binary_stl(kTwo, "solid but binary")));
  ASSERT_TRUE(b.status.is_ok()) << b.status.message();
  EXPECT_EQ(b.header.encoding, "binary");
  EXPECT_EQ(b.positions, kTwo);
}

TEST(StlReader, AsciiKeywordsAnyCaseSeveralSolidsAndOddWhitespace) {
  std::string s =
      "SOLID a\nFACET NORMAL 0 0 1\nOUTER LOOP\nVERTEX 0 0 0\nVERTEX 1 0 0\nVERTEX 0 1 0\nENDLOOP\nENDFACET\nENDSOLID a\n"
      "solid b\r\n\tfacet normal 0 0 0 outer loop vertex 0 0 0 vertex 0 0 1.5 vertex 1 0 0 endloop endfacet\r\nendsolid\r\n";
  auto r = read_all(write_file("multi.stl", s));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, kTwo);
}

TEST(StlReader, BatchBoundaries) {
  std::vector<Vec3> p;
  for (int i = 0; i < 100; ++i) p.insert(p.end(), {Vec3(float(i), 0, 0), Vec3(float(i), 1, 0), Vec3(float(i), 0, 1)});
  for (bool binary : {false, true}) {
    auto path = write_file(binary ? "b.stl" : "a.stl", binary ? binary_stl(p) : ascii_stl(p));
    for (size_t batch : {1, 3, 99, 100, 1000}) {
      auto r = read_all(path, batch);
      ASSERT_TRUE(r.status.is_ok()) << r.status.message();
      EXPECT_EQ(r.positions, p);
      EXPECT_EQ(r.batch_sizes.size(), (100 + batch - 1) / batch);
      for (size_t s : r.batch_sizes) EXPECT_LE(s, batch);
    }
  }
}

TEST(StlReader, ZeroFacetNormalIsAccepted) {
  auto r = read_all(write_file("zeron.stl", ascii_stl(kTwo, "0 0 0")));
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, kTwo);
}

// ---- bad input ----

TEST(StlReaderErrors, EmptyFile) { EXPECT_READ_ERROR(write_file("empty.stl", ""), "empty file"); }

TEST(StlReaderErrors, TooShortForBinaryAndNotAscii) {
  EXPECT_READ_ERROR(write_file("short.stl", "hello"), "too short for a binary STL header");
}

TEST(StlReaderErrors, WrongTriangleCountInBinaryHeader) {
  std::string b = binary_stl(kTwo);
  b[80] = 3;  // declares 3, holds 2
  EXPECT_READ_ERROR(write_file("count3.stl", b), "it declares 3 triangles");
  b[80] = 1;  // declares 1, holds 2
  EXPECT_READ_ERROR(write_file("count1.stl", b), "it declares 1 triangles");
  // Truncated in the middle of a record.
  EXPECT_READ_ERROR(write_file("cut.stl", binary_stl(kTwo).substr(0, 84 + 50 + 20)), "wrong triangle count");
}

TEST(StlReaderErrors, EmptyMeshes) {
  EXPECT_READ_ERROR(write_file("zero.stl", binary_stl({})), "empty mesh");
  EXPECT_READ_ERROR(write_file("faceless.stl", "solid empty\nendsolid empty\n"), "empty mesh");
}

TEST(StlReaderErrors, AsciiTruncated) {
  const std::string s = ascii_stl(kTwo);
  EXPECT_READ_ERROR(write_file("noend.stl", s.substr(0, s.find("endsolid"))), "without 'endsolid'");
  EXPECT_READ_ERROR(write_file("midfacet.stl", s.substr(0, s.find("endloop"))), "truncated: the file ends inside the facet at line 2");
}

TEST(StlReaderErrors, AsciiWrongVertexCount) {
  std::string four = ascii_stl(kTwo);
  four.insert(four.find("    endloop"), "      vertex 5 5 5\n");
  EXPECT_READ_ERROR(write_file("four.stl", four), "line 2: facet has more than 3 vertices");
  std::string two = ascii_stl(kTwo);
  const size_t v = two.find("      vertex 0 1 0\n");
  two.erase(v, std::string("      vertex 0 1 0\n").size());
  EXPECT_READ_ERROR(write_file("twov.stl", two), "line 2: facet has 2 vertices");
}

TEST(StlReaderErrors, AsciiSyntax) {
  std::string s = ascii_stl(kTwo);
  s.replace(s.find("vertex 1 0 0"), 12, "vertex 1 x 0");
  EXPECT_READ_ERROR(write_file("nan_text.stl", s), "line 5: expected 3 numbers after 'vertex', found 'x'");
  std::string t = ascii_stl(kTwo);
  t.replace(t.find("outer loop"), 10, "inner loop");
  EXPECT_READ_ERROR(write_file("inner.stl", t), "line 3: expected 'outer', found 'inner'");
}

TEST(StlReaderErrors, NonFiniteCoordinatesAndNormals) {
  std::vector<Vec3> bad = kTwo;
  bad[4].y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_READ_ERROR(write_file("nan_bin.stl", binary_stl(bad)), "triangle 1: a vertex has a non-finite coordinate");
  bad[4].y = std::numeric_limits<float>::infinity();
  EXPECT_READ_ERROR(write_file("inf_bin.stl", binary_stl(bad)), "triangle 1: a vertex has a non-finite coordinate");
  std::string s = ascii_stl(kTwo);
  s.replace(s.find("vertex 0 0 1.5"), 14, "vertex 0 0 inf");
  EXPECT_READ_ERROR(write_file("inf.stl", s), "line 12: vertex has a non-finite coordinate");
  EXPECT_READ_ERROR(write_file("nann.stl", ascii_stl(kTwo, "nan 0 1")), "line 2: facet normal is not finite");
  EXPECT_READ_ERROR(write_file("nann_bin.stl", binary_stl(kTwo, "binary", std::numeric_limits<float>::quiet_NaN())),
                    "triangle 0: the facet normal is not finite");
}

TEST(StlReaderErrors, BinaryDataAfterSolidWordIsNotAscii) {
  std::string b = binary_stl(kTwo, "solid header");
  b += "xx";  // wrong size, starts with solid, holds NUL bytes: reported as a binary count error
  EXPECT_READ_ERROR(write_file("solid_wrong.stl", b), "wrong triangle count");
}

// ---- the npm stl-models broken and misc files (data/stl-models, see data/README.md) ----

struct SharedCase {
  const char* file;
  int triangles;        // >= 0: reads fine with this many triangles
  const char* error;    // otherwise: a substring of the error
};

// Short names in test listings (ctest shows the parameter).
void PrintTo(const SharedCase& c, std::ostream* os) { *os << c.file; }

class StlModelsSet : public ::testing::TestWithParam<SharedCase> {};

TEST_P(StlModelsSet, ReadsOrFailsAsDecided) {
  const SharedCase c = GetParam();
  const std::filesystem::path path = std::filesystem::path(RAYLOD_DATA_DIR) / "stl-models" / c.file;
  ASSERT_TRUE(std::filesystem::exists(path)) << path;
  auto r = read_all(path);
  if (c.triangles >= 0) {
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    EXPECT_EQ(r.triangles(), size_t(c.triangles));
  } else {
    EXPECT_FALSE(r.status.is_ok());
    EXPECT_NE(r.status.message().find(path.filename().string()), std::string::npos) << r.status.message();
    EXPECT_NE(r.status.message().find(c.error), std::string::npos) << r.status.message();
    EXPECT_TRUE(r.positions.empty()) << "an error must come before any triangle of a text STL";
  }
}

INSTANTIATE_TEST_SUITE_P(
    Files, StlModelsSet,
    ::testing::Values(
        SharedCase{"broken/empty.stl", -1, "empty file"},
        SharedCase{"broken/fourVertices.ascii.stl", -1, "line 2: facet has more than 3 vertices"},
        SharedCase{"broken/incorrectFaceCounter.bin.stl", -1, "it declares 66 triangles"},
        SharedCase{"broken/missingEndsolid.ascii.stl", -1, "without 'endsolid'"},
        // A valid but open surface: the reader does not judge closedness.
        SharedCase{"broken/missingFace.ascii.stl", 3, ""},
        SharedCase{"broken/missingNormal.ascii.stl", -1, "line 24: expected 3 numbers after 'facet normal', found 'outer'"},
        SharedCase{"broken/notANumberNormal.ascii.stl", -1, "line 9: facet normal is not finite"},
        SharedCase{"broken/quad.ascii.stl", -1, "line 2: facet has more than 3 vertices"},
        SharedCase{"broken/singleFace.ascii.stl", 1, ""},
        // The name after endsolid is not checked.
        SharedCase{"broken/solidNameMismatch.ascii.stl", 4, ""},
        SharedCase{"broken/twoVertices.ascii.stl", -1, "line 2: facet has 2 vertices"},
        // Binary despite its "solid" header: decided by size (84 + 50 x 12).
        SharedCase{"broken/wrongHeader.bin.stl", 12, ""},
        // Facet normals are not used, so wrong or zero ones are harmless.
        SharedCase{"broken/wrongNormal.ascii.stl", 4, ""},
        SharedCase{"broken/wrongNormals.ascii.stl", 4, ""},
        SharedCase{"misc/faceless.ascii.stl", -1, "empty mesh"},
        SharedCase{"misc/multiWordName.ascii.stl", 4, ""},
        // Its bytes were mangled into UTF-8 replacement characters (333 bytes for 4 triangles).
        SharedCase{"misc/multiWordName.bin.stl", -1, "it declares 4 triangles"},
        SharedCase{"misc/namelessSolid.ascii.stl", 4, ""}),
    [](const ::testing::TestParamInfo<SharedCase>& test_case) {
      std::string name = test_case.param.file;
      for (char& c : name)
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      return name;
    });

TEST(StlReader, AbcCadPartFromData) {
  const std::filesystem::path path = std::filesystem::path(RAYLOD_DATA_DIR) / "abc" / "abc5.stl";
  auto r = read_all(path, 1000);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.triangles(), 5080u);
  EXPECT_EQ(r.batch_sizes.size(), 6u);
}

}  // namespace
}  // namespace raylod
