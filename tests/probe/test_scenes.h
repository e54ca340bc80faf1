// Test harness for the probe tests: tiny analytic scenes (planes, spheres)
// and triangle meshes intersected by brute force, with an independent
// Snell's-law tracer for the "truth" neighbouring rays.
#pragma once

#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "gen/generate.h"
#include "gen/grid_mesh.h"
#include "geometry/ray_differential.h"
#include "probe/store_tracer.h"

namespace raylod::test {

enum class Mat { Diffuse, Mirror, Glass };

struct TestMesh {
  std::vector<Vec3d> p;  // 3 per triangle
  std::vector<Vec3d> n;  // 3 per triangle (vertex normals), or empty
  size_t size() const { return p.size() / 3; }
};

struct Prim {
  enum Kind { Plane, Sphere, Mesh } kind = Plane;
  Vec3d c{0};      // plane point / sphere centre / mesh offset
  Vec3d n{0, 1, 0};  // plane normal (outward side for glass)
  double r = 1;    // sphere radius
  Mat mat = Mat::Diffuse;
  double ior = 1.5;
  const TestMesh* mesh = nullptr;  // vertices already include any offset
};

struct TestHit {
  double t = std::numeric_limits<double>::infinity();
  int prim = -1;
  int tri = -1;
  HitSurface s;
  bool found() const { return prim >= 0; }
};

using Scene3 = std::vector<Prim>;

inline TestHit intersect(const Scene3& scene, const Vec3d& o, const Vec3d& d, double tmin, int skip_prim, int skip_tri) {
  TestHit best;
  for (int i = 0; i < int(scene.size()); ++i) {
    const Prim& pr = scene[size_t(i)];
    if (pr.kind == Prim::Plane) {
      if (i == skip_prim) continue;
      const double dn = glm::dot(d, pr.n);
      if (dn == 0) continue;
      const double t = glm::dot(pr.c - o, pr.n) / dn;
      if (t > tmin && t < best.t) {
        best.t = t;
        best.prim = i;
        best.tri = -1;
        best.s = HitSurface{};
        best.s.point = o + t * d;
        best.s.geometric_normal = best.s.normal = glm::normalize(pr.n);
      }
    } else if (pr.kind == Prim::Sphere) {
      const Vec3d oc = o - pr.c;
      const double b = glm::dot(oc, d), c = glm::dot(oc, oc) - pr.r * pr.r;
      const double disc = b * b - c;
      if (disc < 0) continue;
      const double sq = std::sqrt(disc);
      // Stable roots: q = -(b + sign(b) sq); t1 = q, t2 = c / q.
      const double q = -(b + std::copysign(sq, b));
      double roots[2] = {q, q != 0 ? c / q : q};
      if (roots[0] > roots[1]) std::swap(roots[0], roots[1]);
      for (double t : roots) {
        if (t > tmin && t < best.t) {
          best.t = t;
          best.prim = i;
          best.tri = -1;
          best.s = HitSurface{};
          best.s.point = o + t * d;
          const Vec3d nn = glm::normalize(best.s.point - pr.c);
          best.s.geometric_normal = best.s.normal = nn;
          // N = (P - C) / r: dN = (I - N N^T) dP / r for the unit normal.
          best.s.normal_jacobian = (Mat3d(1.0) - glm::outerProduct(nn, nn)) * (1.0 / pr.r);
          break;
        }
      }
    } else {
      const TestMesh& m = *pr.mesh;
      for (size_t k = 0; k < m.size(); ++k) {
        if (i == skip_prim && int(k) == skip_tri) continue;
        double t, b1, b2;
        if (intersect_triangle(o, d, m.p[3 * k], m.p[3 * k + 1], m.p[3 * k + 2], tmin, best.t, t, b1, b2)) {
          best.t = t;
          best.prim = i;
          best.tri = int(k);
          best.s = triangle_surface_point(m.p[3 * k], m.p[3 * k + 1], m.p[3 * k + 2],
                                          m.n.empty() ? nullptr : &m.n[3 * k], b1, b2);
        }
      }
    }
  }
  return best;
}

// Snell's law written independently of ray_differential.cpp (the classic
// vector form), for the truth rays.
inline Vec3d snell(const Vec3d& d, const HitSurface& s, double ior, bool& tir) {
  const bool entering = glm::dot(d, s.geometric_normal) < 0;
  const double eta = entering ? 1.0 / ior : ior;
  Vec3d n = s.normal;
  if (glm::dot(d, n) > 0) n = -n;
  const double cos_i = -glm::dot(d, n);
  const double sin2_t = eta * eta * (1.0 - cos_i * cos_i);
  if (sin2_t > 1.0) {
    tir = true;
    return glm::normalize(d + 2.0 * cos_i * n);
  }
  tir = false;
  return glm::normalize(eta * d + (eta * cos_i - std::sqrt(1.0 - sin2_t)) * n);
}

struct PathPoint {
  Vec3d p{0};
  int prim = -1, tri = -1;
  bool tir = false;
  RayDifferential rd;  // transferred to the hit (differential paths only)
};

// Follows a specular path: mirror reflects, glass refracts (or reflects if
// bit k of reflect_mask is set, or on total internal reflection), diffuse
// stops. With differentials uses the library; without, snell() above.
inline std::vector<PathPoint> trace_path(const Scene3& scene, RayDifferential rd, int max_bounces, unsigned reflect_mask,
                                         bool differentials, double tmin_secondary = 1e-9) {
  std::vector<PathPoint> path;
  int skip_prim = -1, skip_tri = -1;
  for (int k = 0; k <= max_bounces; ++k) {
    const double tmin = k == 0 ? 0 : tmin_secondary;
    TestHit h = intersect(scene, rd.ray.origin, rd.ray.direction, tmin, skip_prim, skip_tri);
    if (!h.found()) break;
    PathPoint pp;
    pp.prim = h.prim;
    pp.tri = h.tri;
    if (differentials) {
      transfer(rd, h.t, h.s.geometric_normal);
      pp.p = rd.ray.origin;
    } else {
      pp.p = rd.ray.origin + h.t * rd.ray.direction;
      rd.ray.origin = pp.p;
    }
    const Prim& pr = scene[size_t(h.prim)];
    skip_prim = pr.kind == Prim::Sphere ? -1 : h.prim;
    skip_tri = h.tri;
    if (pr.mat == Mat::Diffuse || k == max_bounces) {
      pp.rd = rd;
      path.push_back(pp);
      break;
    }
    const bool want_reflect = pr.mat == Mat::Mirror || ((reflect_mask >> k) & 1u);
    if (differentials) {
      if (want_reflect) {
        pp.rd = rd;
        rd = reflect(rd, h.s);
      } else {
        Refraction rf = refract(rd, h.s, pr.ior);
        pp.tir = rf.total_internal_reflection;
        pp.rd = rd;
        rd = rf.ray;
      }
    } else {
      Vec3d n = h.s.normal;
      if (want_reflect) {
        rd.ray.direction = glm::normalize(rd.ray.direction - 2.0 * glm::dot(rd.ray.direction, n) * n);
      } else {
        bool tir = false;
        rd.ray.direction = snell(rd.ray.direction, h.s, pr.ior, tir);
        pp.tir = tir;
      }
    }
    path.push_back(pp);
  }
  return path;
}

// A triangle soup (with vertex normals) from a generated grid surface,
// scaled and offset.
inline TestMesh mesh_from_surface(const GridSurface& surface, double scale, const Vec3d& offset) {
  TestMesh mesh;
  std::vector<Vec3d> vp, vn;
  std::vector<uint32_t> idx;
  uint64_t base = 0;
  for (size_t piece = 0; piece < surface.pieces().size(); ++piece) {
    const GridPiece& g = surface.pieces()[piece];
    for (uint32_t row = 0; row < g.rows; ++row) {
      const uint32_t n = grid_row_vertices(g, row);
      std::vector<Vec3> p(n), nn(n);
      surface.eval_row(piece, row, p, nn);
      for (uint32_t i = 0; i < n; ++i) {
        vp.push_back(Vec3d(p[i]) * scale + offset);
        vn.push_back(glm::normalize(Vec3d(nn[i])));
      }
    }
    grid_band_indices(g, base, 0, g.rows - 1, idx);
    base += grid_vertex_count(g);
  }
  for (uint32_t i : idx) {
    mesh.p.push_back(vp[i]);
    mesh.n.push_back(vn[i]);
  }
  return mesh;
}

// A UV sphere with analytic vertex normals.
inline TestMesh uv_sphere(const Vec3d& c, double r, int rings, int segments) {
  TestMesh m;
  auto vertex = [&](int i, int j, Vec3d& p, Vec3d& n) {
    const double th = M_PI * i / rings, ph = 2 * M_PI * j / segments;
    n = Vec3d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
    p = c + r * n;
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      Vec3d p[4], n[4];
      vertex(i, j, p[0], n[0]);
      vertex(i + 1, j, p[1], n[1]);
      vertex(i + 1, j + 1, p[2], n[2]);
      vertex(i, j + 1, p[3], n[3]);
      auto tri = [&](int a, int b, int cc) {
        // Outward winding: (b - a) x (c - a) along the normal.
        Vec3d g = glm::cross(p[b] - p[a], p[cc] - p[a]);
        if (glm::length(g) < 1e-14) return;  // pole triangles with a repeated vertex
        if (glm::dot(g, n[a] + n[b] + n[cc]) < 0) std::swap(b, cc);
        for (int v : {a, b, cc}) {
          m.p.push_back(p[v]);
          m.n.push_back(n[v]);
        }
      };
      tri(0, 1, 2);
      tri(0, 2, 3);
    }
  return m;
}

}  // namespace raylod::test
