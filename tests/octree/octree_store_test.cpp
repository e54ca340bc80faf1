// The store file: round trip of every triangle, refusal of corrupt,
// truncated, foreign-version and stale stores, no-op rebuilds, and atomic
// writes that leave nothing behind on failure.
#include <fcntl.h>
#include <gtest/gtest.h>

#include <chrono>

#include "file_damage.h"
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <fstream>
#include <map>
#include <thread>

#include "core/progress.h"
#include "octree/octree_test_util.h"
#include "streaming/octree_format.h"
#include "streaming/page_codec.h"
#include "streaming/source_record.h"

namespace raylod {
namespace {

using testing::SoupMesh;

Status build_memory(const SoupMesh& mesh, const std::filesystem::path& path, StoreOptions options = {},
                    long fail_after = -1, int fail_pass = -1) {
  Progress::set_enabled(false);
  auto shared = std::make_shared<const SoupMesh>(mesh);
  return build_store_from_stream(testing::opener(shared, 1000, fail_after, fail_pass), testing::fake_source(), path,
                                 options)
      .status();
}

void flip_byte(const std::filesystem::path& p, uint64_t offset) { test::flip_byte(p, offset, 0x20); }

void expect_error_contains(const Status& s, const std::vector<std::string>& parts) {
  ASSERT_FALSE(s.is_ok()) << "expected an error";
  for (const auto& p : parts) EXPECT_NE(s.message().find(p), std::string::npos) << s.message() << " lacks '" << p << "'";
}

// Every triangle comes back from the page of its centroid's cell, in input
// order within the page, exactly as quantised (to_store_precision), and
// that quantisation moves each position by at most half a grid step per axis
// (a step being at most 1/4096 of the finest cell) and each normal by less
// than 1e-4 rad (page_codec.h).
TEST(OctreeStore, RoundTripsEveryTriangle) {
  auto m = testing::sphere(70, 90);  // 12600 triangles with normals
  auto dir = testing::scratch_dir("roundtrip");
  StoreOptions opt;
  opt.page_triangles = 200;
  ASSERT_TRUE(build_memory(m, dir / "s.raylod", opt).is_ok());
  auto opened = OctreeStore::open(dir / "s.raylod");
  ASSERT_TRUE(opened.is_ok()) << opened.status().message();
  const OctreeStore& store = **opened;
  const StoreHeader& h = store.header();
  ASSERT_GT(store.pages().size(), 20u);
  const PageGrid grid = page_grid(h.root_lo, h.root_size, h.grid_bits);
  ASSERT_LE(grid.step, store.cell_size(h.quadric_depth) / 4096);

  testing::SoupMesh q = m;
  testing::to_store_precision(q.positions, q.normals, h);
  double worst_position = 0, worst_normal = 0;
  for (size_t c = 0; c < m.positions.size(); ++c) {
    const Vec3d want(m.positions[c]), got(q.positions[c]);
    for (int a = 0; a < 3; ++a) {
      // Half a step, and the rounding of the decoded value to float.
      const double allowed = 0.5 * grid.step + std::abs(want[a]) * 0x1p-24;
      worst_position = std::max(worst_position, std::abs(got[a] - want[a]) / allowed);
    }
    const Vec3d n0(m.normals[c]), n1(q.normals[c]);
    worst_normal = std::max(worst_normal, std::atan2(glm::length(glm::cross(n0, n1)), glm::dot(n0, n1)));
  }
  EXPECT_LE(worst_position, 1.0) << "a position moved by more than the stated bound (ratio to it)";
  EXPECT_GT(worst_position, 0.0) << "nothing was quantised: the test would not notice a wrong bound";
  EXPECT_LT(worst_normal, 1e-4) << "radians";

  // The quantised triangles by page, in input order.
  std::map<uint64_t, std::vector<size_t>> by_page;
  for (size_t t = 0; t < q.size(); ++t) {
    const Vec3d c = (Vec3d(q.positions[3 * t]) + Vec3d(q.positions[3 * t + 1]) + Vec3d(q.positions[3 * t + 2])) / 3.0;
    by_page[store.cell_of(c, h.page_level).code].push_back(t);
  }
  ASSERT_EQ(by_page.size(), store.pages().size());
  TriangleBatch b;
  size_t i = 0;
  for (const auto& [code, tris] : by_page) {
    const PageInfo& page = store.pages()[i];
    ASSERT_EQ(page.code, code);
    ASSERT_TRUE(store.read_page(i++, b).is_ok());
    ASSERT_EQ(b.size(), page.triangle_count);
    ASSERT_EQ(b.size(), tris.size());
    ASSERT_EQ(b.normals.size(), b.positions.size());
    Bbox tight;
    for (const Vec3& p : b.positions) tight.expand(p);
    EXPECT_EQ(tight.lo, page.bounds.lo);
    EXPECT_EQ(tight.hi, page.bounds.hi);
    for (size_t k = 0; k < tris.size(); ++k)
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(b.positions[3 * k + c], q.positions[3 * tris[k] + c]) << "page " << i - 1 << " triangle " << k;
        ASSERT_EQ(b.normals[3 * k + c], q.normals[3 * tris[k] + c]) << "page " << i - 1 << " triangle " << k;
      }
  }
  EXPECT_EQ(h.triangle_count, m.size());
  EXPECT_EQ(h.source_path, "/nonexistent/memory.ply");
  EXPECT_TRUE(is_store_file(dir / "s.raylod"));
  EXPECT_FALSE(store.read_page(store.pages().size(), b).is_ok());
}

TEST(OctreeStore, RefusesCorruptTruncatedAndForeignFiles) {
  auto m = testing::soup(5000, 2, true);
  auto dir = testing::scratch_dir("corrupt");
  const auto good = dir / "good.raylod";
  StoreOptions opt;
  opt.page_triangles = 100;
  ASSERT_TRUE(build_memory(m, good, opt).is_ok());
  auto opened = OctreeStore::open(good);
  ASSERT_TRUE(opened.is_ok());
  const PageInfo page = (*opened)->pages()[3];
  opened.value().reset();

  auto copy = [&](const std::string& name) {
    auto p = dir / name;
    std::filesystem::copy_file(good, p, std::filesystem::copy_options::overwrite_existing);
    return p;
  };
  {  // A flipped byte inside a page: the store opens, that page does not read.
    auto p = copy("page.raylod");
    flip_byte(p, page.offset + 17);
    auto s = OctreeStore::open(p);
    ASSERT_TRUE(s.is_ok()) << s.status().message();
    TriangleBatch b;
    expect_error_contains((*s)->read_page(3, b), {p.string(), "page 3", "checksum"});
    EXPECT_TRUE((*s)->read_page(2, b).is_ok());
  }
  {  // A flipped byte in the header.
    auto p = copy("header.raylod");
    flip_byte(p, 40);
    expect_error_contains(OctreeStore::open(p).status(), {p.string(), "header checksum"});
  }
  {  // A flipped byte in the node table (just after the header).
    auto p = copy("nodes.raylod");
    flip_byte(p, 1024 + 8);
    auto s = OctreeStore::open(p).status();
    expect_error_contains(s, {p.string(), "checksum"});
  }
  {  // Truncated by one byte, and cut in the header.
    auto p = copy("trunc.raylod");
    std::filesystem::resize_file(p, std::filesystem::file_size(p) - 1);
    expect_error_contains(OctreeStore::open(p).status(), {p.string(), "truncated"});
    std::filesystem::resize_file(p, 30);
    expect_error_contains(OctreeStore::open(p).status(), {p.string(), "truncated"});
  }
  {  // Cut anywhere after the header (a copy that stopped): said so, with both
     // sizes, before the node table's counts are checked against the size.
    const auto full = std::filesystem::file_size(good);
    uint32_t blob = 0;
    {
      std::ifstream in(good, std::ios::binary);
      in.seekg(12);
      in.read(reinterpret_cast<char*>(&blob), 4);
    }
    const uint64_t header = 16 + uint64_t(blob) + 4;
    ASSERT_LT(header + 1, full);
    for (const uint64_t keep : {header, header + 1, full / 2, full - 4096}) {
      if (keep >= full || keep < header) continue;
      auto p = copy("cut.raylod");
      std::filesystem::resize_file(p, keep);
      expect_error_contains(OctreeStore::open(p).status(),
                            {p.string(), "truncated store (" + std::to_string(keep) + " bytes, header says " +
                                             std::to_string(full) + ")"});
    }
  }
  {  // Another format version.
    auto p = copy("version.raylod");
    flip_byte(p, 9);
    expect_error_contains(OctreeStore::open(p).status(), {p.string(), "version"});
  }
  {  // Not a store at all.
    auto p = dir / "text.raylod";
    std::ofstream(p) << "ply\nformat ascii 1.0\nend_header\n";
    expect_error_contains(OctreeStore::open(p).status(), {p.string(), "not a raylod store"});
    EXPECT_FALSE(is_store_file(p));
  }
  expect_error_contains(OctreeStore::open(dir / "missing.raylod").status(), {"missing.raylod"});
}

// Found by tests/fuzz/fuzz_store: a header whose CRC matches but whose node
// count makes count x 144 bytes wrap to 0 passed the "tables outside the file"
// check, and open() then threw std::length_error sizing the node table.
TEST(OctreeStore, RefusesAHeaderWhoseCountsWrapAroundWithAValidChecksum) {
  auto m = testing::soup(500, 2, true);
  auto dir = testing::scratch_dir("wrap");
  const auto p = dir / "wrap.raylod";
  ASSERT_TRUE(build_memory(m, p).is_ok());
  const int fd = ::open(p.c_str(), O_RDWR | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  StoreHeader h;
  store_format::Layout l;
  ASSERT_TRUE(store_format::read_header(fd, p, h, l).is_ok());
  const std::string before = store_format::encode_header(h, l);
  for (auto [level_count, page_count] : {std::pair<uint64_t, uint64_t>{uint64_t(1) << 60, l.page_count},
                                         std::pair<uint64_t, uint64_t>{l.level_counts[0], (uint64_t(1) << 61) / 9}}) {
    store_format::Layout bad = l;
    bad.level_counts[0] = level_count;  // 2^60 x sizeof(NodeRecord) = 9 x 2^64
    bad.page_count = page_count;        // offset + 2^61 / 9 x sizeof(PageInfo) wraps past 2^64
    const std::string header = store_format::encode_header(h, bad);
    ASSERT_EQ(header.size(), before.size());
    ASSERT_TRUE(store_format::pwrite_all(fd, header.data(), header.size(), 0, p).is_ok());
    StatusOr<std::unique_ptr<OctreeStore>> opened = Status::error("not opened");
    ASSERT_NO_THROW(opened = OctreeStore::open(p));
    expect_error_contains(opened.status(), {p.string(), "malformed store header"});
  }
  {  // A negative quadric depth with no levels: refused, not read as level -1.
    StoreHeader negative = h;
    negative.quadric_depth = -1;
    store_format::Layout none = l;
    none.level_counts.clear();
    const std::string header = store_format::encode_header(negative, none);
    ASSERT_TRUE(store_format::pwrite_all(fd, header.data(), header.size(), 0, p).is_ok());
    expect_error_contains(OctreeStore::open(p).status(), {p.string(), "malformed store header"});
  }
  ::close(fd);
}


// The node table is used in place, as mapped: damage that a valid checksum
// hides (a crafted file) must still be refused, not followed. Each case
// rewrites some bytes, then repairs the table checksums the header records.
TEST(OctreeStore, RefusesANodeTableOrBoundaryListWhoseStructureIsWrong) {
  auto m = testing::soup(3000, 2, true);  // a soup: every edge open, so boundary leaves abound
  auto dir = testing::scratch_dir("structure");
  const auto good = dir / "good.raylod";
  ASSERT_TRUE(build_memory(m, good).is_ok());
  StoreHeader h;
  store_format::Layout l;
  {
    const int fd = ::open(good.c_str(), O_RDONLY | O_CLOEXEC);
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(store_format::read_header(fd, good, h, l).is_ok());
    ::close(fd);
  }
  ASSERT_GE(l.level_counts.size(), 3u);
  ASSERT_GT(l.boundary_count, 1u);
  auto damaged = [&](const std::string& name, uint64_t offset, uint64_t value) {
    const auto p = dir / name;
    std::filesystem::copy_file(good, p, std::filesystem::copy_options::overwrite_existing);
    const int fd = ::open(p.c_str(), O_RDWR | O_CLOEXEC);
    EXPECT_TRUE(store_format::pwrite_all(fd, &value, 8, offset, p).is_ok());
    std::string table(l.node_table_bytes, '\0'), list(l.boundary_count * 8, '\0');
    EXPECT_TRUE(store_format::pread_all(fd, table.data(), table.size(), l.node_table_offset, p).is_ok());
    EXPECT_TRUE(store_format::pread_all(fd, list.data(), list.size(), l.boundary_offset, p).is_ok());
    store_format::Layout repaired = l;
    repaired.node_table_crc = crc32c(table.data(), table.size());
    repaired.boundary_crc = crc32c(list.data(), list.size());
    const std::string header = store_format::encode_header(h, repaired);
    EXPECT_TRUE(store_format::pwrite_all(fd, header.data(), header.size(), 0, p).is_ok());
    ::close(fd);
    return p;
  };
  const uint64_t level2 = l.node_table_offset + (l.level_counts[0] + l.level_counts[1]) * sizeof(NodeRecord);
  {  // The checksum repair alone changes nothing.
    const auto p = damaged("same.raylod", l.boundary_offset, [&] {
      uint64_t first = 0;
      const int fd = ::open(good.c_str(), O_RDONLY | O_CLOEXEC);
      EXPECT_TRUE(store_format::pread_all(fd, &first, 8, l.boundary_offset, good).is_ok());
      ::close(fd);
      return first;
    }());
    auto s = OctreeStore::open(p);
    ASSERT_TRUE(s.is_ok()) << s.status().message();
    EXPECT_EQ((*s)->boundary_leaves(), l.boundary_count);
  }
  {  // A node of the level above the leaves moved to a free code between its
     // neighbours: still sorted and in range, but no longer its children's parent.
    auto opened = OctreeStore::open(good);
    ASSERT_TRUE(opened.is_ok());
    const int above = (*opened)->header().quadric_depth - 1;
    ASSERT_GE(above, 2);
    auto nodes = (*opened)->level(above);
    uint64_t before = 0;
    for (int i = 0; i < above; ++i) before += l.level_counts[size_t(i)];
    size_t gap = 0;
    while (gap + 1 < nodes.size() && nodes[gap].code + 1 == nodes[gap + 1].code) ++gap;
    ASSERT_LT(gap + 1, nodes.size()) << "no free code between two nodes of level " << above;
    const uint64_t code = nodes[gap].code + 1;
    opened.value().reset();
    expect_error_contains(
        OctreeStore::open(damaged("orphan.raylod", l.node_table_offset + (before + gap) * sizeof(NodeRecord), code)).status(),
        {"level " + std::to_string(above), "parents", "corrupt"});
  }
  // Level 2's last node moved out of level 2's range (8^2 cells).
  const uint64_t last2 = level2 + (l.level_counts[2] - 1) * sizeof(NodeRecord);
  expect_error_contains(OctreeStore::open(damaged("range.raylod", last2, 1000)).status(),
                        {"level 2", "out of range", "corrupt"});
  // A boundary code that is no leaf, and one out of order.
  expect_error_contains(OctreeStore::open(damaged("foreign.raylod", l.boundary_offset, ~uint64_t(0))).status(),
                        {"boundary list", "corrupt"});
  expect_error_contains(OctreeStore::open(damaged("order.raylod", l.boundary_offset + 8, 0)).status(),
                        {"boundary list", "corrupt"});
}
TEST(OctreeStore, FailedBuildLeavesTheOldStoreAndNoTemporaries) {
  auto m = testing::soup(5000, 4, false);
  auto dir = testing::scratch_dir("atomic");
  const auto path = dir / "s.raylod";
  ASSERT_TRUE(build_memory(m, path).is_ok());
  const auto size = std::filesystem::file_size(path);
  auto other = testing::soup(6000, 5, false);
  for (int pass : {0, 1}) {  // a read error in pass 1, then in pass 2
    Status s = build_memory(other, path, {}, 3, pass);
    expect_error_contains(s, {"memory.ply", "simulated read error"});
  }
  EXPECT_EQ(std::filesystem::file_size(path), size);
  ASSERT_TRUE(OctreeStore::open(path).is_ok());
  size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir)) {
    (void)e;
    ++files;
  }
  EXPECT_EQ(files, 1u) << "temporary files were left behind";
}

// A binary little-endian PLY with float positions and normals, written here
// so these tests do not depend on the project's writer.
void write_ply(const std::filesystem::path& path, const SoupMesh& m) {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << 3 * m.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
      << "element face " << m.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (size_t i = 0; i < m.positions.size(); ++i) {
    out.write(reinterpret_cast<const char*>(&m.positions[i]), 12);
    out.write(reinterpret_cast<const char*>(&m.normals[i]), 12);
  }
  for (int32_t t = 0; t < int32_t(m.size()); ++t) {
    unsigned char three = 3;
    int32_t idx[3] = {3 * t, 3 * t + 1, 3 * t + 2};
    out.write(reinterpret_cast<const char*>(&three), 1);
    out.write(reinterpret_cast<const char*>(idx), 12);
  }
}

// Writes `moved` over `mesh` (the same size: the same vertex count) and sets
// the old access and modification times back: only the content and the
// ctime change.
void rewrite_keeping_size_and_mtime(const std::filesystem::path& mesh, const SoupMesh& moved) {
  struct stat before {};
  ASSERT_EQ(::stat(mesh.c_str(), &before), 0);
  write_ply(mesh, moved);
  struct timespec times[2] = {before.st_atim, before.st_mtim};
  ASSERT_EQ(::utimensat(AT_FDCWD, mesh.c_str(), times, 0), 0);
  struct stat after {};
  ASSERT_EQ(::stat(mesh.c_str(), &after), 0);
  ASSERT_EQ(after.st_size, before.st_size);
}

// STORE.checked spares re-reading the mesh while its file status is the one
// whose content hash matched, and never vouches for a changed mesh.
TEST(OctreeStore, CheckedRecordSparesTheHashOnlyForAnUnchangedMesh) {
  Progress::set_enabled(false);
  auto dir = testing::scratch_dir("checked");
  const auto mesh = dir / "ball.ply";
  auto m = testing::sphere(12, 16);
  write_ply(mesh, m);
  const auto store = default_store_path(mesh);
  const auto record = source_record_path(store);
  StoreOptions opt;
  std::string why;

  // A mesh changed less than kSettleNs before its hash was read gets no record.
  ASSERT_TRUE(build_store(mesh, store, opt).is_ok());
  EXPECT_FALSE(std::filesystem::exists(record));
  auto st = file_status(mesh);
  ASSERT_TRUE(st.is_ok());
  EXPECT_FALSE(note_source_checked(store, *st, 1, st->ctime_ns + kSettleNs - 1));
  EXPECT_FALSE(std::filesystem::exists(record));
  EXPECT_TRUE(note_source_checked(store, *st, 1, st->ctime_ns + kSettleNs));
  EXPECT_TRUE(source_record_vouches(store, *st, 1));
  EXPECT_FALSE(source_record_vouches(store, *st, 2));  // another content hash
  auto other = *st;
  other.ctime_ns += 1;
  EXPECT_FALSE(source_record_vouches(store, other, 1));
  std::filesystem::remove(record);

  // Once the mesh has settled, the build records it and checks stop hashing.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  auto built = build_store(mesh, store, opt, /*force=*/true);
  ASSERT_TRUE(built.is_ok()) << built.status().message();
  EXPECT_TRUE(std::filesystem::exists(record));
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;
  EXPECT_NE(why.find("last content check"), std::string::npos) << why;
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why, /*rehash=*/true)) << why;
  EXPECT_NE(why.find("content hash and options"), std::string::npos) << why;

  // The record names the store file: one about a replaced store is not believed.
  const auto saved = dir / "saved.checked";
  std::filesystem::copy_file(record, saved);
  ASSERT_TRUE(build_store(mesh, store, opt, /*force=*/true).is_ok());
  std::filesystem::copy_file(saved, record, std::filesystem::copy_options::overwrite_existing);
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;
  EXPECT_NE(why.find("content hash and options"), std::string::npos) << why;
  // ... and that hash rewrote it for the new store.
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;
  EXPECT_NE(why.find("last content check"), std::string::npos) << why;

  // A torn record is ignored.
  {
    std::ofstream torn(record, std::ios::trunc);
    torn << "raylod source check record\nstore 1 2";
  }
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;
  EXPECT_NE(why.find("content hash and options"), std::string::npos) << why;

  // Same size and modification time, other content: the write changed the
  // ctime, so the record no longer vouches and the hash catches it.
  ASSERT_TRUE(std::filesystem::exists(record));
  auto moved = m;
  moved.positions[3].y += 0.25f;
  rewrite_keeping_size_and_mtime(mesh, moved);
  EXPECT_FALSE(store_is_current(mesh, store, opt, &why));
  EXPECT_NE(why.find("content"), std::string::npos) << why;
}

TEST(OctreeStore, RebuildIsANoOpUntilTheMeshChanges) {
  Progress::set_enabled(false);
  auto dir = testing::scratch_dir("stale");
  const auto mesh = dir / "ball.ply";
  auto m = testing::sphere(20, 30);
  write_ply(mesh, m);
  const auto store = default_store_path(mesh);
  EXPECT_EQ(store.filename(), "ball.ply.raylod");
  StoreOptions opt;
  opt.memory_limit = 64 << 20;

  auto first = build_store(mesh, store, opt);
  ASSERT_TRUE(first.is_ok()) << first.status().message();
  EXPECT_FALSE(first->reused);
  EXPECT_EQ(first->triangles, m.size());
  std::string why;
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;

  auto again = build_store(mesh, store, opt);
  ASSERT_TRUE(again.is_ok());
  EXPECT_TRUE(again->reused);
  EXPECT_NE(again->reason.find("up to date"), std::string::npos) << again->reason;
  auto forced = build_store(mesh, store, opt, /*force=*/true);
  ASSERT_TRUE(forced.is_ok());
  EXPECT_FALSE(forced->reused);
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;

  // Other options: stale.
  StoreOptions deeper = opt;
  deeper.max_depth = 9;
  EXPECT_FALSE(store_is_current(mesh, store, deeper, &why));
  EXPECT_NE(why.find("options"), std::string::npos) << why;

  // Touched (another modification time, the same bytes): the hash finds
  // the same content and the store stays; the record then vouches again.
  {
    const auto t = std::filesystem::last_write_time(mesh);
    std::filesystem::last_write_time(mesh, t + std::chrono::hours(1));
  }
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;
  EXPECT_NE(why.find("only its modification time changed"), std::string::npos) << why;
  auto touched = build_store(mesh, store, opt);
  ASSERT_TRUE(touched.is_ok());
  EXPECT_TRUE(touched->reused) << touched->reason;

  // Same size and modification time, different content: caught by the hash.
  auto moved = m;
  moved.positions[5].x += 0.5f;
  rewrite_keeping_size_and_mtime(mesh, moved);
  EXPECT_FALSE(store_is_current(mesh, store, opt, &why));
  EXPECT_NE(why.find("content"), std::string::npos) << why;

  // A changed size.
  auto bigger = testing::sphere(21, 30);
  write_ply(mesh, bigger);
  EXPECT_FALSE(store_is_current(mesh, store, opt, &why));
  EXPECT_NE(why.find("size"), std::string::npos) << why;
  auto rebuilt = build_store(mesh, store, opt);
  ASSERT_TRUE(rebuilt.is_ok()) << rebuilt.status().message();
  EXPECT_FALSE(rebuilt->reused);
  EXPECT_EQ(rebuilt->triangles, bigger.size());
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;

  // A corrupt store is rebuilt, not trusted.
  {
    std::fstream f(store, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(40);
    f.put('\x7f');
  }
  EXPECT_FALSE(store_is_current(mesh, store, opt, &why));
  EXPECT_NE(why.find("unusable"), std::string::npos) << why;
}

// A store of an earlier format (version 2 held float triangle soup) is
// detected, and the next build replaces it, saying why.
TEST(OctreeStore, OldFormatStoreIsRebuiltWithAMessage) {
  Progress::set_enabled(false);
  auto dir = testing::scratch_dir("oldformat");
  const auto mesh = dir / "ball.ply";
  write_ply(mesh, testing::sphere(20, 30));
  const auto store = default_store_path(mesh);
  StoreOptions opt;
  opt.memory_limit = 64 << 20;
  ASSERT_TRUE(build_store(mesh, store, opt).is_ok());
  {
    std::fstream f(store, std::ios::in | std::ios::out | std::ios::binary);
    const uint32_t old_version = 2;
    f.seekp(8);  // after the magic
    f.write(reinterpret_cast<const char*>(&old_version), 4);
  }
  std::string why;
  EXPECT_FALSE(store_is_current(mesh, store, opt, &why));
  auto rebuilt = build_store(mesh, store, opt);
  ASSERT_TRUE(rebuilt.is_ok()) << rebuilt.status().message();
  EXPECT_FALSE(rebuilt->reused);
  for (const char* part : {"format version 2", "reads version 6", store.c_str()})
    EXPECT_NE(rebuilt->reason.find(part), std::string::npos) << rebuilt->reason << " lacks " << part;
  EXPECT_TRUE(store_is_current(mesh, store, opt, &why)) << why;
}

TEST(OctreeStore, BuildsFromStlAndRefusesABrokenMesh) {
  Progress::set_enabled(false);
  auto dir = testing::scratch_dir("formats");
  const auto stl = dir / "two.stl";
  std::ofstream(stl) << "solid two\n"
                        "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
                        "facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\n"
                        "endsolid two\n";
  auto built = build_store(stl, default_store_path(stl), {});
  ASSERT_TRUE(built.is_ok()) << built.status().message();
  auto store = OctreeStore::open(default_store_path(stl));
  ASSERT_TRUE(store.is_ok());
  EXPECT_EQ((*store)->header().triangle_count, 2u);
  EXPECT_FALSE((*store)->header().has_normals);
  EXPECT_DOUBLE_EQ((*store)->level(0)[0].quadric.a22, 1.0);  // total area 1, plane z = 0

  // A binary PLY cut short: a clear error naming the mesh, and no store.
  const auto ply = dir / "cut.ply";
  write_ply(ply, testing::sphere(10, 10));
  std::filesystem::resize_file(ply, std::filesystem::file_size(ply) - 20);
  auto broken = build_store(ply, default_store_path(ply), {});
  ASSERT_FALSE(broken.is_ok());
  EXPECT_NE(broken.status().message().find("cut.ply"), std::string::npos) << broken.status().message();
  EXPECT_FALSE(std::filesystem::exists(default_store_path(ply)));
  size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir)) {
    (void)e;
    ++files;
  }
  EXPECT_EQ(files, 3u) << "only two.stl, its store and cut.ply may remain";
}

TEST(OctreeStore, InfoPrintsLevelsPagesAndOptions) {
  auto dir = testing::scratch_dir("info");
  StoreOptions opt;
  opt.memory_limit = 256 << 20;
  opt.max_depth = 4;
  ASSERT_TRUE(build_memory(testing::sphere(30, 40), dir / "s.raylod", opt).is_ok());
  char* text = nullptr;
  size_t len = 0;
  std::FILE* f = open_memstream(&text, &len);
  ASSERT_TRUE(print_store_info(dir / "s.raylod", f).is_ok());
  std::fclose(f);
  std::string s(text, len);
  std::free(text);
  for (const char* part : {"--memory-limit 256.00 MiB", "--max-depth 4", "levels        0..4", "pages", "quadric mem",
                           "2400 (with vertex normals)"})
    EXPECT_NE(s.find(part), std::string::npos) << "missing '" << part << "' in\n" << s;
}

}  // namespace
}  // namespace raylod
