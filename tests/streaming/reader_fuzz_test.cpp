// Seeded mutation fuzzing of every reader: random byte edits, truncations
// and insertions of valid files must give either a clean error naming the
// file or a mesh whose positions are finite and whose normals are unit
// length -- never a crash, a hang or garbage.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>

#include "reader_test_util.h"

namespace raylod {
namespace {

using test::Bytes;
using test::write_file;

std::vector<std::pair<std::string, std::string>> seeds() {
  std::vector<std::pair<std::string, std::string>> s;
  const std::string ply_head =
      "element vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n"
      "property float nz\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n";
  const float v[4][6] = {{0, 0, 0, 0, 0, 1}, {1, 0, 0, 0, 0, 1}, {1, 1, 0, 0, 0, 1}, {0, 1, 1, 0, 1, 0}};
  std::string ascii = "ply\nformat ascii 1.0\n" + ply_head;
  for (const auto& r : v) {
    for (float c : r) ascii += std::to_string(c) + " ";
    ascii += "\n";
  }
  s.push_back({"a.ply", ascii + "4 0 1 2 3\n3 3 2 1\n"});
  for (bool big : {false, true}) {
    Bytes b;
    b.big = big;
    b.text(std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") + " 1.0\n" + ply_head);
    for (const auto& r : v)
      for (float c : r) b.put<float>(c);
    b.put<uint8_t>(4).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2).put<int32_t>(3);
    b.put<uint8_t>(3).put<int32_t>(3).put<int32_t>(2).put<int32_t>(1);
    s.push_back({big ? "be.ply" : "le.ply", b.data});
  }
  Bytes stl;
  std::string h(80, ' ');
  stl.text(h).put<uint32_t>(2);
  for (int t = 0; t < 2; ++t) {
    for (int k = 0; k < 3; ++k) stl.put<float>(0);
    for (int k = 0; k < 3; ++k) stl.put<float>(v[t + k][0]).put<float>(v[t + k][1]).put<float>(v[t + k][2]);
    stl.put<uint16_t>(0);
  }
  s.push_back({"b.stl", stl.data});
  s.push_back({"a.stl",
               "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n"
               "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n"});
  s.push_back({"a.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\nvn 0 0 1\nvn 0 1 0\nvt 0 0\n"
                        "f 1//1 2//1 3//1 4//2\nf -1/1/-2 -2/1/-1 -3/1/-1\n"});
  return s;
}

TEST(ReaderFuzz, MutatedFilesFailCleanlyOrReadSanely) {
  std::mt19937 rng(20240611);
  const std::string interesting = "0123456789 \n-+.eE/#\\naninfx\0\xff";
  // RAYLOD_FUZZ_ITERATIONS raises the count for a long run (e.g. under ASan).
  const char* env = std::getenv("RAYLOD_FUZZ_ITERATIONS");
  const int iterations = env && *env ? std::max(1, std::atoi(env)) : 400;
  int ok = 0, failed = 0;
  for (const auto& [name, original] : seeds()) {
    for (int iter = 0; iter < iterations; ++iter) {
      std::string m = original;
      const int edits = 1 + int(rng() % 4);
      for (int e = 0; e < edits && !m.empty(); ++e) {
        const size_t at = rng() % m.size();
        switch (rng() % 5) {
          case 0: m[at] = char(rng()); break;
          case 1: m[at] = interesting[rng() % interesting.size()]; break;
          case 2: m.resize(at); break;
          case 3: m.insert(at, 1, interesting[rng() % interesting.size()]); break;
          case 4: m.erase(at, 1 + rng() % 8); break;
        }
      }
      // A fresh name each time: rewriting a truncated file makes ext4 flush it on close (slow).
      const auto path = write_file(std::to_string(iter) + "_" + name, m);
      const size_t batch = 1 + rng() % 4;
      auto r = test::read_all(path, batch);
      std::filesystem::remove(path);
      if (!r.status.is_ok()) {
        ++failed;
        EXPECT_NE(r.status.message().find(name), std::string::npos) << r.status.message();
        continue;
      }
      ++ok;
      EXPECT_GT(r.triangles(), 0u);
      for (const Vec3& p : r.positions) ASSERT_TRUE(is_finite(p)) << name << " iteration " << iter;
      if (!r.normals.empty()) {
        ASSERT_EQ(r.normals.size(), r.positions.size());
        for (const Vec3& n : r.normals) ASSERT_NEAR(glm::length(n), 1.0f, 1e-5f) << name << " iteration " << iter;
      }
    }
  }
  // Both outcomes occur, so the test exercises acceptance and rejection.
  EXPECT_GT(ok, 0);
  EXPECT_GT(failed, 0);
}

}  // namespace
}  // namespace raylod
