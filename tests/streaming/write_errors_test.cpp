// Every writer of a finished file (cut, Draco, glTF binary, atomic text)
// reports a failed write the same way: a write_failed status naming the
// destination and the system's reason, and nothing left at the destination.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "core/system.h"
#include "streaming/cut_file.h"
#include "streaming/draco_io.h"
#include "streaming/gltf_io.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

IndexedMesh one_triangle() {
  IndexedMesh mesh;
  mesh.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  mesh.normals = {Vec3(0, 0, 1), Vec3(0, 0, 1), Vec3(0, 0, 1)};
  mesh.indices = {0, 1, 2};
  return mesh;
}

// A destination whose folder is a regular file: creating the temporary
// fails with ENOTDIR for root as for anyone (a read-only folder would not
// stop root).
class WriteErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::scratch_dir("write-errors");
    std::ofstream(dir_ / "plain-file") << "not a folder";
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path under_a_file(const std::string& name) const { return dir_ / "plain-file" / name; }
  static void expect_reported(const Status& s, const fs::path& dest) {
    ASSERT_FALSE(s.is_ok());
    EXPECT_TRUE(s.is_write_failure()) << s.message();
    EXPECT_EQ(s.path(), dest.string());
    EXPECT_NE(s.message().find(dest.string() + ": cannot open for writing: Not a directory"), std::string::npos)
        << s.message();
    std::error_code ec;
    EXPECT_FALSE(fs::exists(dest, ec));
  }
  fs::path dir_;
};

TEST_F(WriteErrors, CutFile) {
  Cut cut;
  cut.cells.push_back({});
  const fs::path dest = under_a_file("view.cut");
  expect_reported(write_cut(dest, cut), dest);
}

TEST_F(WriteErrors, DracoFile) {
  const fs::path dest = under_a_file("mesh.drc");
  expect_reported(write_draco(dest, one_triangle(), DracoOptions{}).status(), dest);
}

TEST_F(WriteErrors, GlbFile) {
  auto encoded = encode_draco("mesh.drc", one_triangle(), DracoOptions{});
  ASSERT_TRUE(encoded.is_ok()) << encoded.status().message();
  GlbMesh mesh;
  mesh.draco = encoded->bytes;
  const fs::path dest = under_a_file("scene.glb");
  expect_reported(write_glb(dest, {mesh}, {GlbNode{}}).status(), dest);
}

TEST_F(WriteErrors, AtomicTextFile) {
  const fs::path dest = under_a_file("stats.json");
  expect_reported(write_file_atomic(dest, "{}"), dest);
}

TEST_F(WriteErrors, PiecesArriveInOrderWithTheHookBetweenThem) {
  const fs::path dest = dir_ / "pieces.bin";
  AtomicOutput out(dest);
  static std::string seen;
  seen.clear();
  ASSERT_TRUE(write_temporary(out, {"ab", "", "cde"}, [](size_t i) { seen += std::to_string(i); }).is_ok());
  ASSERT_TRUE(out.commit().is_ok());
  std::ifstream in(dest, std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "abcde");
  EXPECT_EQ(seen, "01");  // after each piece but the last
}

// A symlink is followed: the file it names is replaced, the link stays.
TEST_F(WriteErrors, SymlinkStaysAndItsFileIsReplaced) {
  std::ofstream(dir_ / "real.json") << "old";
  fs::create_directory(dir_ / "sub");
  fs::create_symlink("../real.json", dir_ / "sub" / "link.json");
  ASSERT_TRUE(write_file_atomic(dir_ / "sub" / "link.json", "new").is_ok());
  EXPECT_TRUE(fs::is_symlink(dir_ / "sub" / "link.json"));
  std::ifstream in(dir_ / "real.json");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "new");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "sub"), fs::directory_iterator{}), 1);  // no temporary left
}

// A file replaced keeps its permissions: a read-only image stays read-only,
// a group-readable one group-readable; a new file takes the umask's.
TEST_F(WriteErrors, AReplacedFileKeepsItsPermissions) {
  for (const fs::perms mode : {fs::perms(0444), fs::perms(0640), fs::perms(0600)}) {
    const fs::path p = dir_ / "image.json";
    fs::remove(p);
    std::ofstream(p) << "old";
    fs::permissions(p, mode, fs::perm_options::replace);
    ASSERT_TRUE(write_file_atomic(p, "new").is_ok());
    EXPECT_EQ(fs::status(p).permissions() & fs::perms::all, mode);
    std::ifstream in(p);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "new");
  }
}

// A device is written into, never replaced (as root a rename would swap
// /dev/null for a regular file): through a link to /dev/null, and
// /dev/full's "disk full" is reported.
TEST_F(WriteErrors, DevicesAreWrittenIntoNotReplaced) {
  fs::create_symlink("/dev/null", dir_ / "null.json");
  ASSERT_TRUE(write_file_atomic(dir_ / "null.json", "{}").is_ok());
  EXPECT_TRUE(fs::is_symlink(dir_ / "null.json"));
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  if (fs::exists("/dev/full")) {
    const Status s = write_file_atomic("/dev/full", "{}");
    EXPECT_TRUE(s.is_write_failure()) << s.message();
    EXPECT_TRUE(fs::is_character_file("/dev/full"));
  }
}

}  // namespace
}  // namespace raylod
