// A corrupt page found by a reader is recorded beside the store (STORE.corrupt),
// and the next build rebuilds the store because of it; --verify finds one
// that no reader has touched yet.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "file_damage.h"

#include "core/progress.h"
#include "octree/octree_test_util.h"
#include "streaming/octree_store.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// This test's scratch directory, removed when the test ends, pass or fail.
struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name) : dir(testing::scratch_dir(name)) {}
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

// An ASCII PLY triangle soup of the mesh (positions only).
void write_ascii_ply(const fs::path& path, const testing::SoupMesh& m) {
  std::ofstream out(path);
  out << "ply\nformat ascii 1.0\nelement vertex " << m.positions.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << m.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3& p : m.positions) out << p.x << ' ' << p.y << ' ' << p.z << '\n';
  for (size_t t = 0; t < m.size(); ++t) out << "3 " << 3 * t << ' ' << 3 * t + 1 << ' ' << 3 * t + 2 << '\n';
}

using test::flip_byte;

struct Fixture {
  Scratch scratch;
  fs::path mesh, store;
  StoreOptions options;
  explicit Fixture(const std::string& name) : scratch(name) {
    Progress::set_enabled(false);
    mesh = scratch.dir / "sphere.ply";
    store = default_store_path(mesh);
    write_ascii_ply(mesh, testing::sphere(20, 20));
    options.page_triangles = 50;
    options.memory_limit = uint64_t(64) << 20;
  }
  // Damages page i's first triangle on disk.
  void damage_page(size_t i) {
    auto opened = OctreeStore::open(store);
    ASSERT_TRUE(opened.is_ok()) << opened.status().message();
    ASSERT_GT((*opened)->pages().size(), i);
    const uint64_t offset = (*opened)->pages()[i].offset + 5;
    opened.value().reset();
    flip_byte(store, offset);
  }
};

TEST(CorruptionRecord, AReaderRecordsTheCorruptPageAndTheNextBuildRebuilds) {
  Fixture f("record");
  auto first = build_store(f.mesh, f.store, f.options);
  ASSERT_TRUE(first.is_ok()) << first.status().message();
  f.damage_page(2);
  {  // Nothing has read the page yet: the store looks current (the bug's "up to date").
    auto again = build_store(f.mesh, f.store, f.options);
    ASSERT_TRUE(again.is_ok());
    EXPECT_TRUE(again->reused);
  }
  {
    auto opened = OctreeStore::open(f.store);
    ASSERT_TRUE(opened.is_ok());
    TriangleBatch batch;
    const Status read = (*opened)->read_page(2, batch);
    ASSERT_FALSE(read.is_ok());
    EXPECT_NE(read.message().find("page 2"), std::string::npos) << read.message();
    EXPECT_NE(read.message().find(corruption_record_path(f.store).string()), std::string::npos) << read.message();
    EXPECT_TRUE((*opened)->found_corruption());
  }
  const auto recorded = store_corruption(f.store);
  ASSERT_TRUE(recorded.has_value());
  EXPECT_NE(recorded->find("page 2"), std::string::npos) << *recorded;
  std::string reason;
  EXPECT_FALSE(store_is_current(f.mesh, f.store, f.options, &reason));
  EXPECT_NE(reason.find("corrupt"), std::string::npos) << reason;

  auto rebuilt = build_store(f.mesh, f.store, f.options);
  ASSERT_TRUE(rebuilt.is_ok()) << rebuilt.status().message();
  EXPECT_FALSE(rebuilt->reused);
  EXPECT_NE(rebuilt->reason.find("page 2"), std::string::npos) << rebuilt->reason;
  EXPECT_FALSE(fs::exists(corruption_record_path(f.store)));
  auto verified = verify_store_pages(f.store);
  ASSERT_TRUE(verified.is_ok()) << verified.status().message();
  EXPECT_EQ(*verified, first->pages);
}

TEST(CorruptionRecord, VerifyChecksEveryPageAndRebuildsOnAMismatch) {
  Fixture f("verify");
  ASSERT_TRUE(build_store(f.mesh, f.store, f.options).is_ok());
  auto clean = build_store(f.mesh, f.store, f.options, false, true);
  ASSERT_TRUE(clean.is_ok()) << clean.status().message();
  EXPECT_TRUE(clean->reused);
  EXPECT_NE(clean->reason.find("--verify"), std::string::npos) << clean->reason;

  f.damage_page(1);
  auto verified = build_store(f.mesh, f.store, f.options, false, true);
  ASSERT_TRUE(verified.is_ok()) << verified.status().message();
  EXPECT_FALSE(verified->reused);
  EXPECT_NE(verified->reason.find("--verify"), std::string::npos) << verified->reason;
  EXPECT_NE(verified->reason.find("page 1"), std::string::npos) << verified->reason;
  EXPECT_TRUE(verify_store_pages(f.store).is_ok());
  EXPECT_FALSE(fs::exists(corruption_record_path(f.store)));
}

TEST(CorruptionRecord, ARecordAboutAReplacedStoreFileDoesNotApply) {
  Fixture f("replaced");
  ASSERT_TRUE(build_store(f.mesh, f.store, f.options).is_ok());
  ASSERT_TRUE(record_store_corruption(f.store, "page 7 (cell 3) checksum mismatch").is_ok());
  ASSERT_TRUE(store_corruption(f.store).has_value());
  // Another store file renamed into place (as a rebuild does): a new inode.
  const fs::path copy = f.scratch.dir / "copy.raylod";
  fs::copy_file(f.store, copy);
  fs::rename(copy, f.store);
  EXPECT_FALSE(store_corruption(f.store).has_value());
  EXPECT_TRUE(store_is_current(f.mesh, f.store, f.options));
}

}  // namespace
}  // namespace raylod
