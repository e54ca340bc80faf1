// Helpers for the streaming reader tests: a per-test scratch directory, file
// writers, a byte builder for binary PLY/STL in either byte order, and
// read-everything helpers.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "streaming/mesh_reader.h"

namespace raylod::test {

// The scratch directory of one test (not created).
inline std::filesystem::path scratch_dir_of(const ::testing::TestInfo* info) {
  const char* env = std::getenv("RAYLOD_TEST_TMP");
  std::filesystem::path root = env && *env ? std::filesystem::path(env) : std::filesystem::path(::testing::TempDir());
  std::string name = "streaming-" + std::to_string(::getpid());
  if (info) name += std::string("-") + info->test_suite_name() + "-" + info->name();
  for (char& c : name) if (c == '/') c = '_';
  return root / name;
}

// The running test's scratch directory, created on first use and removed
// when the test ends (by the listener below), pass or fail.
inline std::filesystem::path scratch_dir() {
  std::filesystem::path dir = scratch_dir_of(::testing::UnitTest::GetInstance()->current_test_info());
  std::filesystem::create_directories(dir);
  return dir;
}

class RemoveScratchDir : public ::testing::EmptyTestEventListener {
  void OnTestEnd(const ::testing::TestInfo& info) override {
    std::error_code ec;
    std::filesystem::remove_all(scratch_dir_of(&info), ec);
  }
};
// Registered once per test program, before main() runs the tests (gtest owns the listener).
inline const bool kRemoveScratchDirRegistered =
    (::testing::UnitTest::GetInstance()->listeners().Append(new RemoveScratchDir), true);

inline std::filesystem::path write_file(const std::string& name, const std::string& bytes) {
  std::filesystem::path p = scratch_dir() / name;
  std::ofstream out(p, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  return p;
}

// Appends scalars in little- or big-endian byte order.
struct Bytes {
  std::string data;
  bool big = false;
  template <class T>
  Bytes& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof(T));
    data.append(b, sizeof(T));
    return *this;
  }
  Bytes& text(const std::string& s) { data += s; return *this; }
};

struct ReadAll {
  Status status;             // ok, or the first error (open or next)
  MeshHeader header;
  std::vector<Vec3> positions, normals;
  std::vector<size_t> batch_sizes;
  size_t triangles() const { return positions.size() / 3; }
};

inline ReadAll read_all(StatusOr<std::unique_ptr<MeshReader>> opened) {
  ReadAll r;
  if (!opened) { r.status = opened.status(); return r; }
  MeshReader& reader = *opened.value();
  r.header = reader.header();
  TriangleBatch batch;
  while (true) {
    auto more = reader.next(batch);
    if (!more) { r.status = more.status(); return r; }
    if (!more.value()) break;
    r.batch_sizes.push_back(batch.size());
    r.positions.insert(r.positions.end(), batch.positions.begin(), batch.positions.end());
    r.normals.insert(r.normals.end(), batch.normals.begin(), batch.normals.end());
  }
  return r;
}

inline ReadAll read_all(const std::filesystem::path& path, size_t batch_triangles = 1 << 16) {
  return read_all(open_mesh(path, ReaderOptions{batch_triangles}));
}

// The error message of reading the file whole ("" if it read fine).
inline std::string read_error(const std::filesystem::path& path) {
  ReadAll r = read_all(path);
  return r.status.is_ok() ? std::string() : r.status.message();
}

using Tri = std::array<float, 9>;
inline std::vector<Tri> triangles_of(const std::vector<Vec3>& p) {
  std::vector<Tri> t(p.size() / 3);
  for (size_t i = 0; i < t.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      t[i][3 * k] = p[3 * i + k].x;
      t[i][3 * k + 1] = p[3 * i + k].y;
      t[i][3 * k + 2] = p[3 * i + k].z;
    }
  return t;
}
inline std::vector<Tri> sorted_triangles(const std::vector<Vec3>& p) {
  auto t = triangles_of(p);
  std::sort(t.begin(), t.end());
  return t;
}

}  // namespace raylod::test

// Expects that reading `path` fails with a message containing the file name and `needle`.
#define EXPECT_READ_ERROR(path, needle)                                              \
  do {                                                                               \
    const std::string _msg = ::raylod::test::read_error(path);                       \
    EXPECT_FALSE(_msg.empty()) << "expected an error for " << (path);                \
    EXPECT_NE(_msg.find((path).filename().string()), std::string::npos) << _msg;     \
    EXPECT_NE(_msg.find(needle), std::string::npos) << "message: " << _msg;          \
  } while (0)
