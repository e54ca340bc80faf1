// The streaming indexed PLY writer: exact bytes of a tiny mesh, and every
// misuse giving an error with nothing left under the destination name.
#include "gen_test_util.h"
#include "streaming/indexed_ply_writer.h"

namespace raylod {
namespace {

const std::vector<Vec3> kPos = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
const std::vector<Vec3> kNrm = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {1, 0, 0}};
const std::vector<uint32_t> kTris = {0, 1, 2, 0, 2, 3};

TEST(IndexedPlyWriter, TinyMeshExactBytes) {
  const auto dir = test::test_tmp_dir("writer-exact");
  const auto path = dir / "tiny.ply";
  IndexedPlyLayout layout{4, 2, true, {"hello"}};
  auto w = IndexedPlyWriter::create(path, layout);
  ASSERT_TRUE(w.is_ok()) << w.status().message();
  // Chunks of any size.
  ASSERT_TRUE((*w)->append_vertices(std::span(kPos).first(1), std::span(kNrm).first(1)).is_ok());
  ASSERT_TRUE((*w)->append_vertices(std::span(kPos).subspan(1), std::span(kNrm).subspan(1)).is_ok());
  ASSERT_TRUE((*w)->append_triangles(std::span(kTris).first(3)).is_ok());
  EXPECT_FALSE(std::filesystem::exists(path));  // not before finish()
  ASSERT_TRUE((*w)->append_triangles(std::span(kTris).subspan(3)).is_ok());
  ASSERT_TRUE((*w)->finish().is_ok());

  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment hello\nelement vertex 4\n"
      "property float x\nproperty float y\nproperty float z\n"
      "property float nx\nproperty float ny\nproperty float nz\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
  EXPECT_EQ(indexed_ply_header(layout), header);
  const std::string bytes = test::read_bytes(path);
  ASSERT_EQ(bytes.size(), header.size() + 4 * 24 + 2 * 13);
  EXPECT_EQ(indexed_ply_file_bytes(layout), bytes.size());
  EXPECT_EQ((*w)->bytes_written(), bytes.size());
  EXPECT_EQ(bytes.substr(0, header.size()), header);
  // Vertex 3: position (0,0,1), normal (1,0,0), little-endian floats.
  float v3[6];
  std::memcpy(v3, bytes.data() + header.size() + 3 * 24, 24);
  EXPECT_EQ(v3[2], 1.0f);
  EXPECT_EQ(v3[3], 1.0f);
  // Face 1: count 3, then 0 2 3 as little-endian int32.
  const std::string f1 = bytes.substr(header.size() + 4 * 24 + 13, 13);
  EXPECT_EQ(f1, std::string("\x03\x00\x00\x00\x00\x02\x00\x00\x00\x03\x00\x00\x00", 13));

  const auto m = test::read_generated_ply(path);
  EXPECT_EQ(m.positions, kPos);
  EXPECT_EQ(m.normals, kNrm);
  EXPECT_EQ(m.indices, kTris);
}

TEST(IndexedPlyWriter, WithoutNormals) {
  const auto dir = test::test_tmp_dir("writer-nonormals");
  auto w = IndexedPlyWriter::create(dir / "a.ply", {4, 2, false, {}});
  ASSERT_TRUE(w.is_ok());
  ASSERT_TRUE((*w)->append_vertices(kPos, {}).is_ok());
  ASSERT_TRUE((*w)->append_triangles(kTris).is_ok());
  ASSERT_TRUE((*w)->finish().is_ok());
  const auto m = test::read_generated_ply(dir / "a.ply");
  EXPECT_EQ(m.positions, kPos);
  EXPECT_TRUE(m.normals.empty());
}

void expect_error_and_no_file(const Status& st, const std::filesystem::path& path, const std::string& words) {
  EXPECT_FALSE(st.is_ok());
  EXPECT_NE(st.message().find(path.string()), std::string::npos) << st.message();
  EXPECT_NE(st.message().find(words), std::string::npos) << st.message();
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(IndexedPlyWriter, MisuseIsAnErrorAndLeavesNoFile) {
  const auto dir = test::test_tmp_dir("writer-misuse");
  const auto path = dir / "bad.ply";
  {  // too few faces at finish
    auto w = IndexedPlyWriter::create(path, {4, 2, true, {}});
    ASSERT_TRUE((*w)->append_vertices(kPos, kNrm).is_ok());
    ASSERT_TRUE((*w)->append_triangles(std::span(kTris).first(3)).is_ok());
    expect_error_and_no_file((*w)->finish(), path, "header declares");
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));  // the temporary is gone too
  {  // faces before all vertices
    auto w = IndexedPlyWriter::create(path, {4, 2, true, {}});
    ASSERT_TRUE((*w)->append_vertices(std::span(kPos).first(2), std::span(kNrm).first(2)).is_ok());
    expect_error_and_no_file((*w)->append_triangles(kTris), path, "faces appended after 2 of 4 vertices");
  }
  {  // index out of range
    auto w = IndexedPlyWriter::create(path, {4, 2, true, {}});
    ASSERT_TRUE((*w)->append_vertices(kPos, kNrm).is_ok());
    const std::vector<uint32_t> bad = {0, 1, 4};
    expect_error_and_no_file((*w)->append_triangles(bad), path, "vertex index 4");
  }
  {  // too many vertices, mismatched normals
    auto w = IndexedPlyWriter::create(path, {3, 1, true, {}});
    expect_error_and_no_file((*w)->append_vertices(kPos, kNrm), path, "more vertices");
    auto w2 = IndexedPlyWriter::create(path, {4, 1, true, {}});
    expect_error_and_no_file((*w2)->append_vertices(kPos, std::span(kNrm).first(2)), path, "normals");
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  {  // unwritable directory, too many vertices for int indices, multi-line comment
    EXPECT_FALSE(IndexedPlyWriter::create(dir / "no" / "such" / "dir.ply", {4, 2, true, {}}).is_ok());
    EXPECT_FALSE(IndexedPlyWriter::create(path, {uint64_t(1) << 31, 1, true, {}}).is_ok());
    EXPECT_FALSE(IndexedPlyWriter::create(path, {4, 2, true, {"two\nlines"}}).is_ok());
  }
}

}  // namespace
}  // namespace raylod
