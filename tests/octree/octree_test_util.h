// Shared helpers for the octree store tests: in-memory meshes streamed
// through a MeshReader, scratch directories, and a brute-force reference.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "streaming/octree_store.h"
#include "streaming/page_codec.h"
#include "test_tmp.h"

namespace raylod::testing {

struct SoupMesh {
  std::vector<Vec3> positions;  // 3 per triangle
  std::vector<Vec3> normals;    // empty or 3 per triangle
  size_t size() const { return positions.size() / 3; }
};

// Positions and normals as a store with this header holds them: each
// position on the store's grid, each normal through its octahedral code
// (page_codec.h). Exactly what read_page returns for them.
inline void to_store_precision(std::vector<Vec3>& positions, std::vector<Vec3>& normals, const StoreHeader& h) {
  const PageGrid grid = page_grid(h.root_lo, h.root_size, h.grid_bits);
  for (Vec3& p : positions) {
    uint32_t q[3];
    quantise_position(p, grid, q);
    p = grid_position(q, grid);
  }
  for (Vec3& n : normals) n = decode_octahedral(encode_octahedral(n));
}

// Streams a SoupMesh in fixed-size batches; can fail after `fail_after` batches.
class VectorReader : public MeshReader {
 public:
  VectorReader(std::shared_ptr<const SoupMesh> mesh, size_t batch, long fail_after = -1)
      : mesh_(std::move(mesh)), batch_(batch), fail_after_(fail_after) {
    header_.format = MeshFormat::Ply;
    header_.has_normals = !mesh_->normals.empty();
    header_.face_count = mesh_->size();
    path_ = "memory.ply";
  }
  StatusOr<bool> next(TriangleBatch& b) override {
    b.clear();
    if (fail_after_ >= 0 && batches_ >= fail_after_) return Status::error("memory.ply: simulated read error");
    if (next_ >= mesh_->size()) return false;
    size_t n = std::min(batch_, mesh_->size() - next_);
    b.positions.assign(mesh_->positions.begin() + long(3 * next_), mesh_->positions.begin() + long(3 * (next_ + n)));
    if (header_.has_normals)
      b.normals.assign(mesh_->normals.begin() + long(3 * next_), mesh_->normals.begin() + long(3 * (next_ + n)));
    next_ += n;
    ++batches_;
    return true;
  }

 private:
  std::shared_ptr<const SoupMesh> mesh_;
  size_t batch_;
  long fail_after_;
  size_t next_ = 0;
  long batches_ = 0;
};

// Each call opens a new pass. With fail_after >= 0, the reader of pass
// `fail_pass` (0-based; -1 = every pass) fails after that many batches.
inline MeshStreamOpener opener(std::shared_ptr<const SoupMesh> mesh, size_t batch = 1000, long fail_after = -1,
                               int fail_pass = -1) {
  auto passes = std::make_shared<int>(0);
  return [=]() -> StatusOr<std::unique_ptr<MeshReader>> {
    const int pass = (*passes)++;
    const bool fail = fail_pass < 0 || pass == fail_pass;
    return std::unique_ptr<MeshReader>(new VectorReader(mesh, batch, fail ? fail_after : -1));
  };
}

inline std::filesystem::path scratch_dir(const std::string& name) {
  std::filesystem::path dir = test::scratch_dir("octree-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline SourceFingerprint fake_source(const std::string& name = "memory.ply") {
  SourceFingerprint s;
  s.path = "/nonexistent/" + name;
  s.bytes = 1234;
  s.mtime_ns = 42;
  s.hash = 0xabcdef;
  return s;
}

// UV sphere of radius r around c with exact unit vertex normals.
inline SoupMesh sphere(int stacks, int slices, double r = 1.0, Vec3d c = Vec3d(0)) {
  SoupMesh m;
  auto vert = [&](int i, int j, Vec3& p, Vec3& n) {
    double th = M_PI * i / stacks, ph = 2 * M_PI * j / slices;
    Vec3d d(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
    p = Vec3(c + r * d);
    n = Vec3(glm::normalize(d));
  };
  for (int i = 0; i < stacks; ++i)
    for (int j = 0; j < slices; ++j) {
      Vec3 p[4], n[4];
      vert(i, j, p[0], n[0]);
      vert(i + 1, j, p[1], n[1]);
      vert(i + 1, j + 1, p[2], n[2]);
      vert(i, j + 1, p[3], n[3]);
      const int tris[2][3] = {{0, 1, 2}, {0, 2, 3}};
      for (auto& t : tris)
        for (int k : t) {
          m.positions.push_back(p[k]);
          m.normals.push_back(n[k]);
        }
    }
  return m;
}

// Random triangles (seeded), optionally with random unit normals.
inline SoupMesh soup(size_t n, uint32_t seed, bool normals, float extent = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-extent, extent), small(-0.05f * extent, 0.05f * extent);
  SoupMesh m;
  for (size_t i = 0; i < n; ++i) {
    Vec3 a(u(rng), u(rng), u(rng));
    for (int k = 0; k < 3; ++k) {
      m.positions.push_back(k == 0 ? a : a + Vec3(small(rng), small(rng), small(rng)));
      if (normals) {
        Vec3 d(small(rng), small(rng), small(rng));
        if (glm::length(d) < 1e-6f) d = Vec3(0, 0, 1);
        m.normals.push_back(glm::normalize(d));
      }
    }
  }
  return m;
}

}  // namespace raylod::testing
