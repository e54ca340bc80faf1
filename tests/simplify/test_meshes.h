// Small meshes and helpers shared by the simplify tests.
#pragma once

#include <array>
#include <cmath>
#include <map>
#include <random>
#include <vector>

#include "core/math.h"
#include "geometry/qem_solve.h"
#include "simplify/vertex_clustering.h"
#include "streaming/draco_io.h"
#include "streaming/mesh_reader.h"
#include "streaming/octree_store.h"

namespace raylod::test {

inline void add_tri(TriangleBatch& b, const Vec3& p0, const Vec3& p1, const Vec3& p2) {
  b.positions.insert(b.positions.end(), {p0, p1, p2});
}
inline void add_tri_n(TriangleBatch& b, const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& n0, const Vec3& n1,
                      const Vec3& n2) {
  b.positions.insert(b.positions.end(), {p0, p1, p2});
  b.normals.insert(b.normals.end(), {n0, n1, n2});
}

// Closed axis-aligned box [lo, hi] with each face split into n x n quads
// (two triangles each), outward winding, shared corner positions.
inline TriangleBatch closed_box(const Vec3& lo, const Vec3& hi, int n) {
  TriangleBatch b;
  auto lerp = [&](int axis, int i) { return lo[axis] + (hi[axis] - lo[axis]) * float(i) / float(n); };
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
          auto pt = [&](int a, int c) {
            Vec3 p;
            p[axis] = side ? hi[axis] : lo[axis];
            p[u] = lerp(u, a);
            p[v] = lerp(v, c);
            return p;
          };
          Vec3 p00 = pt(i, j), p10 = pt(i + 1, j), p11 = pt(i + 1, j + 1), p01 = pt(i, j + 1);
          // (u, v, axis) is right-handed, so u x v = +axis: CCW in (u, v) faces +axis.
          if (side) { add_tri(b, p00, p10, p11); add_tri(b, p00, p11, p01); }
          else { add_tri(b, p00, p11, p10); add_tri(b, p00, p01, p11); }
        }
      }
    }
  }
  return b;
}

// UV sphere with exact unit vertex normals (a smooth CAD-like surface).
inline TriangleBatch uv_sphere(const Vec3& c, float r, int stacks, int slices) {
  TriangleBatch b;
  auto at = [&](int i, int j) {
    if (i == 0 || i == stacks) return Vec3d(0, i == 0 ? 1 : -1, 0);  // exact poles: closed by position
    const double th = M_PI * double(i) / stacks, ph = 2 * M_PI * double(j % slices) / slices;
    return Vec3d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
  };
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      Vec3d n00 = at(i, j), n01 = at(i, j + 1), n10 = at(i + 1, j), n11 = at(i + 1, j + 1);
      auto P = [&](const Vec3d& n) { return c + r * Vec3(n); };
      if (i != 0) add_tri_n(b, P(n00), P(n01), P(n11), Vec3(n00), Vec3(n01), Vec3(n11));
      if (i != stacks - 1) add_tri_n(b, P(n00), P(n11), P(n10), Vec3(n00), Vec3(n11), Vec3(n10));
    }
  }
  return b;
}

// In-memory node records at one level, as the octree store build defines
// them: per corner, the plane quadric of its triangle relative to origin
// (weight area / 3), the corner position, and its area-weighted normal.
struct MemoryNodes {
  Vec3d root_lo{0};
  double root_size = 1;
  int level = 0;
  Vec3d origin{0};
  std::map<uint64_t, NodeRecord> nodes;  // by Morton code

  Bbox cell_bounds(uint64_t code) const {
    uint32_t x, y, z;
    morton_decode(code, x, y, z);
    const double s = root_size / double(uint64_t(1) << level);
    const Vec3d lo = root_lo + Vec3d(x, y, z) * s;
    return Bbox{lo, lo + Vec3d(s)};
  }
};

inline MemoryNodes accumulate_nodes(const TriangleBatch& soup, const Vec3d& root_lo, double root_size, int level,
                                    const Vec3d& origin) {
  MemoryNodes m{root_lo, root_size, level, origin, {}};
  const double n = double(uint64_t(1) << level);
  for (size_t t = 0; t < soup.size(); ++t) {
    Vec3d p[3];
    for (int k = 0; k < 3; ++k) p[k] = Vec3d(soup.positions[3 * t + k]) - origin;
    const Vec3* tn = soup.normals.empty() ? nullptr : &soup.normals[3 * t];
    const Vec3d plane_n = quadric_plane_normal(p[0], p[1], p[2], tn);
    const Vec3d cross = glm::cross(p[1] - p[0], p[2] - p[0]);
    const double area2 = glm::length(cross);
    for (int k = 0; k < 3; ++k) {
      uint32_t c[3];
      for (int a = 0; a < 3; ++a)
        c[a] = uint32_t(std::clamp(std::floor((double(soup.positions[3 * t + k][a]) - root_lo[a]) * (n / root_size)),
                                   0.0, n - 1));
      NodeRecord& r = m.nodes[morton_encode(c[0], c[1], c[2])];
      r.code = morton_encode(c[0], c[1], c[2]);
      if (area2 > 0) quadric_add(r.quadric, quadric_from_plane(plane_n, p[k], area2 / 6.0));
      r.vertex_sum += p[k];
      // As the store build: area / 3 per corner, the weight of the quadric.
      if (area2 > 0) r.normal_sum += (area2 / 6.0) * (tn ? Vec3d(tn[k]) : cross / area2);
      ++r.corner_count;
    }
  }
  return m;
}

// Triangles of an indexed mesh as position triples rotated to start at the
// lexicographically smallest corner (orientation kept), sorted: a canonical
// form for comparing meshes whose vertex and face order differ.
using PosTri = std::array<std::array<float, 3>, 3>;
inline std::vector<PosTri> canonical_triangles(const IndexedMesh& m) {
  std::vector<PosTri> out;
  for (size_t t = 0; t < m.triangle_count(); ++t) {
    PosTri tri;
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = m.positions[m.indices[3 * t + k]];
      tri[k] = {p.x, p.y, p.z};
    }
    int s = 0;
    for (int k = 1; k < 3; ++k) if (tri[k] < tri[s]) s = k;
    out.push_back({tri[s], tri[(s + 1) % 3], tri[(s + 2) % 3]});
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Directed edges by position; a closed, consistently oriented surface has, for
// every directed edge a->b, as many b->a.
inline bool edges_paired(const IndexedMesh& m, size_t* unpaired = nullptr) {
  std::map<std::pair<std::array<float, 3>, std::array<float, 3>>, int> count;
  auto key = [&](uint32_t i) { const Vec3& p = m.positions[i]; return std::array<float, 3>{p.x, p.y, p.z}; };
  for (size_t t = 0; t < m.triangle_count(); ++t)
    for (int k = 0; k < 3; ++k) ++count[{key(m.indices[3 * t + k]), key(m.indices[3 * t + (k + 1) % 3])}];
  size_t bad = 0;
  for (const auto& [e, c] : count) {
    auto it = count.find({e.second, e.first});
    if (it == count.end() || it->second != c) ++bad;
  }
  if (unpaired) *unpaired = bad;
  return bad == 0;
}

inline bool inside(const Vec3d& p, const Bbox& b) { return is_finite(p) && b.contains(p); }

}  // namespace raylod::test
