// Tiny in-memory meshes and scenes for the renderer's tests.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "render/embree_scene.h"
#include "render/renderer.h"
#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod::testing {

// This process's own scratch folder (see test_tmp.h), removed when it exits.
inline std::filesystem::path test_tmp(const std::string& sub) { return test::scratch_dir(sub); }

// Orients every triangle of a convex solid outward (away from the centroid of
// its vertices); the soup is then welded.
inline TriangleMesh convex_solid(std::vector<Vec3> soup, int material, const std::string& name) {
  Vec3d c(0);
  for (const Vec3& p : soup) c += Vec3d(p);
  c /= double(soup.size());
  for (size_t t = 0; t + 2 < soup.size(); t += 3) {
    const Vec3d a(soup[t]), b(soup[t + 1]), d(soup[t + 2]);
    if (glm::dot(glm::cross(b - a, d - a), (a + b + d) / 3.0 - c) < 0) std::swap(soup[t + 1], soup[t + 2]);
  }
  TriangleMesh m = weld_triangles(soup, {});
  m.material = material;
  m.name = name;
  return m;
}

inline TriangleMesh make_box(const Vec3& lo, const Vec3& hi, int material) {
  auto v = [&](int i) { return Vec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z); };
  const int quads[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
  std::vector<Vec3> soup;
  for (const auto& q : quads) {
    for (int k : {q[0], q[1], q[2], q[0], q[2], q[3]}) soup.push_back(v(k));
  }
  return convex_solid(soup, material, "box");
}

// Right-angle isosceles prism: cross-section (-s,0) (s,0) (0,s) in xy
// (right angle at (0,s), hypotenuse on y = 0), extruded over z in [-depth, depth].
inline TriangleMesh make_prism(float s, float depth, int material) {
  const Vec3 a0(-s, 0, -depth), b0(s, 0, -depth), c0(0, s, -depth);
  const Vec3 a1(-s, 0, depth), b1(s, 0, depth), c1(0, s, depth);
  std::vector<Vec3> soup = {a0, b0, c0, a1, b1, c1,              // caps
                            a0, b0, b1, a0, b1, a1,              // hypotenuse
                            a0, c0, c1, a0, c1, a1,              // leg AC
                            b0, c0, c1, b0, c1, b1};             // leg BC
  return convex_solid(soup, material, "prism");
}

// UV sphere with exact vertex normals.
inline TriangleMesh make_sphere(const Vec3& center, float radius, int rings, int segments, int material) {
  TriangleMesh m;
  m.material = material;
  m.name = "sphere";
  const double pi = 3.14159265358979323846;
  for (int i = 0; i <= rings; ++i) {
    const double th = pi * i / rings;
    for (int j = 0; j <= segments; ++j) {
      const double ph = 2 * pi * j / segments;
      const Vec3d n(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
      m.positions.push_back(center + radius * Vec3(n));
      m.normals.push_back(Vec3(n));
    }
  }
  auto id = [&](int i, int j) { return uint32_t(i * (segments + 1) + j); };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      // (i,j) -> (i,j+1) -> (i+1,j) winds outward for this parameterisation.
      if (i > 0) for (uint32_t k : {id(i, j), id(i, j + 1), id(i + 1, j)}) m.indices.push_back(k);
      if (i < rings - 1) for (uint32_t k : {id(i, j + 1), id(i + 1, j + 1), id(i + 1, j)}) m.indices.push_back(k);
    }
  return m;
}

inline Material material(const std::string& name, MaterialType type, Vec3 color = Vec3(0.8f)) {
  Material m;
  m.name = name;
  m.type = type;
  m.color = color;
  if (type == MaterialType::Mirror || type == MaterialType::Glass) m.color = Vec3(0.0f);
  return m;
}

inline Scene base_scene(int width, int height) {
  Scene s;
  s.camera.width = width;
  s.camera.height = height;
  s.spp = 4;
  s.max_depth = 5;
  s.seed = 7;
  return s;
}

inline Light point_light(Vec3d pos, float intensity) {
  Light l;
  l.type = LightType::Point;
  l.position = pos;
  l.intensity = intensity;
  return l;
}

inline RenderOptions quiet_options() {
  RenderOptions o;
  o.progress = false;
  return o;
}

// A sphere (material 0, vertex normals), a mirror box (material 1) and a
// floor with Phong highlights (material 2) under a point and a directional
// light: diffuse, shadows, and specular rays that land on shadowed surfaces.
// `sphere` is the sphere's material.
inline Scene sphere_box_scene(int width, int height, const Material& sphere) {
  Scene s = base_scene(width, height);
  s.camera.eye = {0.5, 2, 5};
  s.camera.look_at = {0, 0.8, 0};
  s.materials = {sphere, material("mirror", MaterialType::Mirror), material("floor", MaterialType::Diffuse)};
  s.materials[2].specular = Vec3(0.3f);
  s.lights = {point_light({2, 5, 3}, 30)};
  Light sun;
  sun.type = LightType::Directional;
  sun.direction = glm::normalize(Vec3d(0.3, -1, -0.4));
  s.lights.push_back(sun);
  return s;
}

inline std::vector<TriangleMesh> sphere_box_meshes(const Scene& s) {
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_sphere({-0.6f, 1, 0}, 0.8f, 16, 32, 0));
  meshes.push_back(make_box({0.6f, 0, -1}, {1.6f, 1.5f, 0}, 1));
  meshes.push_back(make_ground_mesh(Ground{0, 20, 2}, s.camera));
  return meshes;
}

// Builds the meshes into an Embree scene and renders it.
inline RenderResult render_meshes(std::vector<TriangleMesh> meshes, const Scene& scene,
                                  const RenderOptions& options = quiet_options()) {
  auto geometry = EmbreeScene::build(std::move(meshes));
  if (!geometry) throw std::runtime_error(geometry.status().message());
  return render_embree_scene(**geometry, scene, options);
}

}  // namespace raylod::testing
