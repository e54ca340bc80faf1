// Test helpers for the generators: an independent little reader for the
// binary PLY files raylod gen writes (the project's readers are tested on
// their own), in-memory meshes of a GridSurface, and brute-force ray casting.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/math.h"
#include "gen/grid_mesh.h"
#include "test_tmp.h"

namespace raylod::test {

struct IndexedMesh {
  std::vector<std::string> header_lines;
  std::vector<Vec3> positions, normals;
  std::vector<uint32_t> indices;  // 3 per triangle
  size_t triangles() const { return indices.size() / 3; }
};

inline std::filesystem::path test_tmp_dir(const std::string& name) {
  std::filesystem::path dir = test::scratch_dir("gen-" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string read_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Parses exactly the layout of IndexedPlyWriter; fails the test on anything else.
inline IndexedMesh read_generated_ply(const std::filesystem::path& path) {
  IndexedMesh m;
  const std::string bytes = read_bytes(path);
  const size_t end = bytes.find("end_header\n");
  EXPECT_NE(end, std::string::npos) << path;
  if (end == std::string::npos) return m;
  std::istringstream h(bytes.substr(0, end));
  uint64_t nv = 0, nf = 0;
  bool normals = false;
  for (std::string line; std::getline(h, line);) {
    m.header_lines.push_back(line);
    std::istringstream ls(line);
    std::string a, b;
    ls >> a >> b;
    if (a == "element" && b == "vertex") ls >> nv;
    if (a == "element" && b == "face") ls >> nf;
    if (a == "property" && line == "property float nx") normals = true;
  }
  EXPECT_EQ(m.header_lines.at(1), "format binary_little_endian 1.0");
  const size_t rec = normals ? 24 : 12;
  const size_t data = end + 11;
  EXPECT_EQ(bytes.size(), data + nv * rec + nf * 13) << path;
  if (bytes.size() != data + nv * rec + nf * 13) return m;
  m.positions.resize(nv);
  if (normals) m.normals.resize(nv);
  for (size_t i = 0; i < nv; ++i) {
    float f[6];
    std::memcpy(f, bytes.data() + data + i * rec, rec);
    m.positions[i] = Vec3(f[0], f[1], f[2]);
    if (normals) m.normals[i] = Vec3(f[3], f[4], f[5]);
  }
  const size_t faces = data + nv * rec;
  m.indices.resize(3 * nf);
  for (size_t t = 0; t < nf; ++t) {
    EXPECT_EQ(uint8_t(bytes[faces + 13 * t]), 3u);
    std::memcpy(&m.indices[3 * t], bytes.data() + faces + 13 * t + 1, 12);
  }
  return m;
}

// The whole tessellation in memory (small surfaces only), with the piece and
// vertex row of every vertex.
struct GridMesh : IndexedMesh {
  std::vector<uint32_t> vertex_piece, vertex_row, vertex_col;
  std::vector<uint32_t> triangle_piece;
};

inline GridMesh grid_to_mesh(const GridSurface& s) {
  GridMesh m;
  uint64_t base = 0;
  const auto& pieces = s.pieces();
  for (size_t p = 0; p < pieces.size(); ++p) {
    const GridPiece& g = pieces[p];
    for (uint32_t r = 0; r < g.rows; ++r) {
      const uint32_t n = grid_row_vertices(g, r);
      std::vector<Vec3> pos(n), nrm(n);
      s.eval_row(p, r, pos, nrm);
      for (uint32_t c = 0; c < n; ++c) {
        m.positions.push_back(pos[c]);
        m.normals.push_back(nrm[c]);
        m.vertex_piece.push_back(uint32_t(p));
        m.vertex_row.push_back(r);
        m.vertex_col.push_back(c);
      }
    }
    const size_t before = m.indices.size();
    grid_band_indices(g, base, 0, g.rows - 1, m.indices);
    m.triangle_piece.insert(m.triangle_piece.end(), (m.indices.size() - before) / 3, uint32_t(p));
    base += grid_vertex_count(g);
  }
  return m;
}

inline Vec3d corner(const IndexedMesh& m, size_t t, int k) { return Vec3d(m.positions[m.indices[3 * t + k]]); }

// Number of triangles the ray crosses (Moller-Trumbore, brute force).
inline int count_crossings(const IndexedMesh& m, const Vec3d& o, const Vec3d& d) {
  int hits = 0;
  for (size_t t = 0; t < m.triangles(); ++t) {
    const Vec3d a = corner(m, t, 0), e1 = corner(m, t, 1) - a, e2 = corner(m, t, 2) - a;
    const Vec3d p = glm::cross(d, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-18) continue;
    const Vec3d s = o - a;
    const double u = glm::dot(s, p) / det;
    if (u < 0 || u > 1) continue;
    const Vec3d q = glm::cross(s, e1);
    const double v = glm::dot(d, q) / det;
    if (v < 0 || u + v > 1) continue;
    if (glm::dot(e2, q) / det > 0) ++hits;
  }
  return hits;
}

}  // namespace raylod::test
