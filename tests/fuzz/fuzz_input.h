// Shared by the libFuzzer targets in tests/fuzz: the readers take paths, so
// each input is handed to them as an anonymous in-memory file (memfd), named
// through /proc/self/fd. Nothing touches the disk and nothing outlives the
// iteration, even when a target crashes.
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "core/math.h"
#include "streaming/mesh_reader.h"

namespace raylod::fuzz {

// A violated property is a finding: print it and abort, so libFuzzer keeps the input.
[[noreturn]] inline void fail(const char* what) {
  std::fprintf(stderr, "raylod fuzz: %s\n", what);
  std::abort();
}
#define RAYLOD_FUZZ_CHECK(cond) \
  do {                          \
    if (!(cond)) ::raylod::fuzz::fail("check failed: " #cond); \
  } while (0)

class MemFile {
 public:
  MemFile(const uint8_t* data, size_t size) {
    fd_ = ::memfd_create("raylod-fuzz", MFD_CLOEXEC);
    if (fd_ < 0) fail("memfd_create failed");
    for (size_t done = 0; done < size;) {
      const ssize_t w = ::write(fd_, data + done, size - done);
      if (w <= 0) fail("write to memfd failed");
      done += size_t(w);
    }
    path_ = "/proc/self/fd/" + std::to_string(fd_);
  }
  ~MemFile() { ::close(fd_); }
  MemFile(const MemFile&) = delete;
  MemFile& operator=(const MemFile&) = delete;
  const std::filesystem::path& path() const { return path_; }
  int fd() const { return fd_; }

 private:
  int fd_ = -1;
  std::filesystem::path path_;
};

// Reads every batch of an opened reader and checks what the reader promises
// (streaming/mesh_reader.h): an error has a message; triangles come in whole
// batches with finite positions and, if present, unit normals, one per corner.
inline void drain(StatusOr<std::unique_ptr<MeshReader>> opened) {
  if (!opened) {
    RAYLOD_FUZZ_CHECK(!opened.status().message().empty());
    return;
  }
  MeshReader& reader = **opened;
  TriangleBatch batch;
  uint64_t triangles = 0;
  for (;;) {
    auto more = reader.next(batch);
    if (!more) {
      RAYLOD_FUZZ_CHECK(!more.status().message().empty());
      return;
    }
    if (!*more) break;
    RAYLOD_FUZZ_CHECK(batch.positions.size() % 3 == 0 && batch.size() > 0);
    RAYLOD_FUZZ_CHECK(batch.normals.empty() || batch.normals.size() == batch.positions.size());
    RAYLOD_FUZZ_CHECK(batch.normals.empty() == !reader.header().has_normals);
    for (const Vec3& p : batch.positions) RAYLOD_FUZZ_CHECK(is_finite(p));
    for (const Vec3& n : batch.normals) RAYLOD_FUZZ_CHECK(std::fabs(glm::length(n) - 1.0f) < 1e-4f);
    triangles += batch.size();
  }
  RAYLOD_FUZZ_CHECK(triangles > 0);  // an empty mesh must be an error, not an empty success
}

// Small batches, so that polygons meet batch boundaries often.
inline ReaderOptions small_batches() {
  ReaderOptions o;
  o.batch_triangles = 5;
  return o;
}

}  // namespace raylod::fuzz
