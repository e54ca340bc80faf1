// Paths that are not regular files (a named pipe, a directory, a character
// device) fail at once with what they are, instead of blocking on the open
// (a FIFO waits for a writer) or reading forever (/dev/zero).
#include <gtest/gtest.h>

#include "fifo_guard.h"
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <future>

#include "reader_test_util.h"
#include "streaming/cut_file.h"
#include "streaming/mapped_file.h"
#include "streaming/octree_store.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

fs::path make_fifo(const std::string& name) {
  const fs::path p = test::scratch_dir() / name;
  EXPECT_EQ(::mkfifo(p.c_str(), 0600), 0) << p;
  return p;
}

using test::without_blocking;

TEST(SpecialFile, OpenMeshOnANamedPipeFailsAtOnce) {
  for (const char* name : {"pipe.ply", "pipe.obj", "pipe.stl", "pipe.drc"}) {
    const fs::path fifo = make_fifo(name);
    const std::string msg = without_blocking(fifo, [&] { return test::read_error(fifo); });
    EXPECT_NE(msg.find(fifo.string() + ": is a named pipe (FIFO), not a regular file"), std::string::npos) << msg;
  }
}

TEST(SpecialFile, FormatOpenersAndMappedFileRejectANamedPipe) {
  // The format openers do not go through open_mesh; MappedFile guards them.
  const fs::path fifo = make_fifo("direct.ply");
  const std::string msg = without_blocking(fifo, [&] {
    auto r = open_ply_reader(fifo);
    return r.is_ok() ? std::string() : r.status().message();
  });
  EXPECT_NE(msg.find("direct.ply: is a named pipe (FIFO), not a regular file"), std::string::npos) << msg;
  const std::string mapped = without_blocking(fifo, [&] {
    auto m = MappedFile::open(fifo);
    return m.is_ok() ? std::string() : m.status().message();
  });
  EXPECT_NE(mapped.find("is a named pipe (FIFO)"), std::string::npos) << mapped;
}

TEST(SpecialFile, StoreAndCutChecksDoNotBlockOnANamedPipe) {
  const fs::path fifo = make_fifo("pipe.raylod");
  EXPECT_FALSE(without_blocking(fifo, [&] { return is_store_file(fifo); }));
  EXPECT_FALSE(without_blocking(fifo, [&] { return is_cut_file(fifo); }));
  const std::string store = without_blocking(fifo, [&] {
    auto s = OctreeStore::open(fifo);
    return s.is_ok() ? std::string() : s.status().message();
  });
  EXPECT_NE(store.find("is a named pipe (FIFO)"), std::string::npos) << store;
  const std::string cut = without_blocking(fifo, [&] {
    auto c = read_cut(fifo);
    return c.is_ok() ? std::string() : c.status().message();
  });
  EXPECT_NE(cut.find("is a named pipe (FIFO)"), std::string::npos) << cut;
}

TEST(SpecialFile, DirectoryAndDevicesAndLinksToThem) {
  const fs::path dir = test::scratch_dir() / "meshes.ply";
  fs::create_directories(dir);
  EXPECT_READ_ERROR(dir, "meshes.ply: is a directory");
  // A character device is named as one, whatever its name says it holds.
  const std::string zero = test::read_error("/dev/zero");
  EXPECT_NE(zero.find("/dev/zero: is a character device, not a regular file"), std::string::npos) << zero;
  const fs::path link = test::scratch_dir() / "null.stl";
  fs::create_symlink("/dev/null", link);
  EXPECT_READ_ERROR(link, "null.stl: is a character device, not a regular file");
}

}  // namespace
}  // namespace raylod
