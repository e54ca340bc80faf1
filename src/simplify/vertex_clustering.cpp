// Reference uniform vertex clustering (see vertex_clustering.h). Written for
// obviousness, not speed: std::map cells, std::set duplicate check.
#include "simplify/vertex_clustering.h"

#include <array>
#include <cmath>
#include <map>
#include <set>

#include "streaming/octree_store.h"

namespace raylod {
namespace {

struct Cell {
  Quadric quadric;
  Vec3d vertex_sum{0};
  uint64_t count = 0;
  Vec3d normal_sum{0};
  double weight_sum = 0;
  int output = -1;  // index in the output mesh
};

using GridIndex = std::array<int64_t, 3>;

}  // namespace

Vec3d quadric_plane_normal(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3* normals) {
  if (normals) {
    const Vec3d m = Vec3d(normals[0]) + Vec3d(normals[1]) + Vec3d(normals[2]);
    const double len = glm::length(m);
    if (len > kCancelledNormalSum) return m / len;
  }
  return face_normal(a, b, c);
}

IndexedMesh cluster_vertices(const TriangleBatch& soup, const VertexClusteringConfig& config) {
  const bool has_normals = !soup.normals.empty();
  const int64_t n = int64_t(1) << config.level;
  const double inv_cell = double(n) / config.root_size;
  auto grid_index = [&](const Vec3& p) {
    GridIndex g;
    for (int a = 0; a < 3; ++a) {
      const double t = std::floor((double(p[a]) - config.root_lo[a]) * inv_cell);
      g[a] = std::clamp<int64_t>(int64_t(t), 0, n - 1);
    }
    return g;
  };

  // Pass 1: per-cell quadrics, means and normals.
  std::map<GridIndex, Cell> cells;
  for (size_t t = 0; t < soup.size(); ++t) {
    Vec3d p[3];
    for (int k = 0; k < 3; ++k) p[k] = Vec3d(soup.positions[3 * t + k]) - config.origin;
    const Vec3* tn = has_normals ? &soup.normals[3 * t] : nullptr;
    const Vec3d plane_n = quadric_plane_normal(p[0], p[1], p[2], tn);
    const Vec3d cross = glm::cross(p[1] - p[0], p[2] - p[0]);
    const double area2 = glm::length(cross);
    for (int k = 0; k < 3; ++k) {
      Cell& c = cells[grid_index(soup.positions[3 * t + k])];
      if (area2 > 0) quadric_add(c.quadric, quadric_from_plane(plane_n, p[k], area2 / 6.0));
      c.vertex_sum += p[k];
      ++c.count;
      c.normal_sum += tn ? area2 * Vec3d(tn[k]) : cross;
      c.weight_sum += area2;
    }
  }

  // Pass 2: triangles between three different cells, first occurrence of
  // each oriented vertex triple.
  IndexedMesh mesh;
  std::set<std::array<int, 3>> seen;
  const double cell_side = config.root_size / double(n);
  for (size_t t = 0; t < soup.size(); ++t) {
    std::array<int, 3> v;
    for (int k = 0; k < 3; ++k) {
      const GridIndex g = grid_index(soup.positions[3 * t + k]);
      Cell& c = cells.at(g);
      if (c.output < 0) {
        Bbox box;
        for (int a = 0; a < 3; ++a) {
          box.lo[a] = config.root_lo[a] + double(g[a]) * cell_side - config.origin[a];
          box.hi[a] = box.lo[a] + cell_side;
        }
        const QemSolution s = solve_representative_vertex(c.quadric, c.vertex_sum / double(c.count), box, config.qem);
        c.output = int(mesh.positions.size());
        mesh.positions.push_back(Vec3(config.origin + s.position));
        const double len = glm::length(c.normal_sum);
        const Vec3d unit = (len > 1e-6 * c.weight_sum && len > 0) ? c.normal_sum / len : dominant_normal(c.quadric);
        mesh.normals.push_back(Vec3(unit));
      }
      v[k] = c.output;
    }
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) continue;
    const Vec3d a(mesh.positions[v[0]]), b(mesh.positions[v[1]]), c(mesh.positions[v[2]]);
    if (glm::cross(b - a, c - a) == Vec3d(0)) continue;  // collinear: zero area
    const int m = std::min({v[0], v[1], v[2]});
    std::array<int, 3> key = v;
    while (key[0] != m) key = {key[1], key[2], key[0]};
    if (!seen.insert(key).second) continue;
    for (int k = 0; k < 3; ++k) mesh.indices.push_back(uint32_t(v[k]));
  }
  return mesh;
}

}  // namespace raylod
