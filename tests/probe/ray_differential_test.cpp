// Ray differentials against the truth: the hit points of the actual
// neighbouring rays through (x + h, y) and (x, y + h), traced with an
// independent Snell's-law tracer, must match P + h dP/dx to first order, so
// the relative error must halve when h halves (Igehy 1999; METHOD.md eq. 2).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>

#include "geometry/optics.h"
#include "geometry/ray_differential.h"
#include "scene/scene_camera.h"
#include "test_scenes.h"

namespace raylod {
namespace {

using test::Mat;
using test::Prim;
using test::Scene3;

struct FdStats {
  std::vector<double> ratios;  // rel_error(h) / rel_error(h/2), ideally 2
  std::vector<double> rel;     // rel_error(h)
  int exact = 0;               // error at rounding level (e.g. flat mirrors)
  int max_bounces_seen = 0;
  int paths = 0;
  int dropped = 0;
};

// Compares the base path's differentials with finite differences at one pixel.
// `unit`: the scene's unit of length, below which coordinates count as zero
// for the rounding test.
void fd_sample(const Scene3& scene, const PinholeCamera& cam, double px, double py, int max_bounces, unsigned mask,
               double tmin, FdStats& st, double unit = 1.0) {
  const auto base = test::trace_path(scene, camera_ray_differential(cam, px, py), max_bounces, mask, true, tmin);
  if (base.empty()) return;
  ++st.paths;
  const double h1 = 0.05, h2 = 0.025;
  for (int axis = 0; axis < 2; ++axis) {
    std::vector<test::PathPoint> n[2];
    int k = 0;
    for (double h : {h1, h2}) {
      RayDifferential r;
      r.ray = cam.generate(px + (axis == 0 ? h : 0), py + (axis == 1 ? h : 0));
      n[k++] = test::trace_path(scene, r, max_bounces, mask, false, tmin);
    }
    for (size_t b = 0; b < base.size(); ++b) {
      // Compare only while the neighbours follow the same surfaces, triangles
      // and TIR decisions (across an edge of a tessellation the first-order
      // model legitimately breaks).
      bool same = true;
      for (int j = 0; j < 2; ++j)
        for (size_t c = 0; c <= b; ++c)
          same = same && c < n[j].size() && n[j][c].prim == base[c].prim && n[j][c].tri == base[c].tri &&
                 (c == b || n[j][c].tir == base[c].tir);
      if (!same) break;
      const RayDifferential& rd = base[b].rd;
      if (!rd.has_differentials) { ++st.dropped; break; }
      const Vec3d dp = axis == 0 ? rd.dp_dx : rd.dp_dy;
      const Vec3d p = base[b].p;
      const double d1 = glm::length(n[0][b].p - p), d2 = glm::length(n[1][b].p - p);
      if (!(d1 > 0 && d2 > 0)) continue;
      const double e1 = glm::length(n[0][b].p - (p + h1 * dp)), e2 = glm::length(n[1][b].p - (p + h2 * dp));
      st.max_bounces_seen = std::max(st.max_bounces_seen, int(b));
      const double scale = std::max({unit, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
      if (e1 < 256 * 2.2e-16 * scale) { ++st.exact; continue; }  // rounding level
      st.rel.push_back(e1 / d1);
      st.ratios.push_back((e1 / d1) / (e2 / d2));
    }
  }
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// First-order convergence: the ratio of relative errors at h and h/2 is ~2.
void expect_first_order(const FdStats& st, const std::string& name, int min_compared, int min_bounces) {
  SCOPED_TRACE(name);
  const int compared = int(st.ratios.size()) + st.exact;
  EXPECT_GE(compared, min_compared) << "too few comparable samples (paths " << st.paths << ")";
  EXPECT_GE(st.max_bounces_seen, min_bounces);
  if (st.ratios.empty()) return;
  const double med = median(st.ratios);
  EXPECT_GT(med, 1.8);
  EXPECT_LT(med, 2.2);
  int good = 0;
  for (double r : st.ratios) good += r > 1.5 && r < 2.7;
  EXPECT_GE(good, int(0.9 * double(st.ratios.size()))) << "ratios outside [1.5, 2.7]: " << st.ratios.size() - good;
  std::vector<double> rel = st.rel;
  std::sort(rel.begin(), rel.end());
  // Sanity bound only: near silhouettes the second-order term is large.
  EXPECT_LT(rel[rel.size() * 9 / 10], 0.2) << "90th percentile of the relative error at h = 0.05 px";
  std::printf("[ fd ] %-28s samples %4d (exact %3d) median ratio %.3f  median rel.err %.2e  max bounce %d\n",
              name.c_str(), compared, st.exact, med, median(st.rel), st.max_bounces_seen);
}

struct CaseSpec {
  std::string name;
  Scene3 scene;
  Vec3d target{0};
  double radius_lo = 3, radius_hi = 7;
  int max_bounces = 4;
  int samples = 250;
  int min_bounces = 0;
  double tmin = 1e-7;
  bool glass_mask = false;  // randomise reflection/refraction choices at glass
  double unit = 1;          // the scene's unit of length (fd_sample)
};

FdStats run_case(const CaseSpec& spec, uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  FdStats st;
  for (int s = 0; s < spec.samples; ++s) {
    // A random camera above the floor looking at the target.
    const double th = 0.15 + 1.2 * u(rng), ph = 2 * M_PI * u(rng);
    const double R = spec.radius_lo + (spec.radius_hi - spec.radius_lo) * u(rng);
    Camera c;
    c.eye = spec.target + R * Vec3d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
    c.look_at = spec.target + 0.3 * Vec3d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    c.up = Vec3d(0, 1, 0);
    c.fov_y_deg = 20 + 40 * u(rng);
    c.width = 100 + int(700 * u(rng));
    c.height = 100 + int(500 * u(rng));
    const PinholeCamera cam = make_pinhole_camera(c);
    // Pixels around the centre (where the object is).
    const double px = c.width * (0.3 + 0.4 * u(rng)), py = c.height * (0.3 + 0.4 * u(rng));
    const unsigned mask = spec.glass_mask ? unsigned(rng()) : 0u;
    fd_sample(spec.scene, cam, px, py, spec.max_bounces, mask, spec.tmin, st, spec.unit);
  }
  return st;
}

Scene3 offset_scene(Scene3 s, const Vec3d& off) {
  for (Prim& p : s) p.c += off;
  return s;
}

Prim floor_plane(double y = -1.2) { return Prim{Prim::Plane, Vec3d(0, y, 0), Vec3d(0, 1, 0), 1, Mat::Diffuse}; }
Prim sphere(const Vec3d& c, double r, Mat m) { return Prim{Prim::Sphere, c, Vec3d(0), r, m}; }

std::vector<CaseSpec> analytic_cases() {
  std::vector<CaseSpec> cases;
  cases.push_back({"plane, primary", {Prim{Prim::Plane, Vec3d(0), glm::normalize(Vec3d(0.2, 1, -0.1)), 1, Mat::Diffuse}}});
  cases.push_back({"sphere, primary", {sphere(Vec3d(0), 1, Mat::Diffuse)}});
  CaseSpec mirrors{"two mirror spheres", {sphere(Vec3d(-1.02, 0, 0), 1, Mat::Mirror), sphere(Vec3d(1.02, 0, 0), 1, Mat::Mirror),
                                          floor_plane()}};
  mirrors.radius_lo = 2.5;
  mirrors.min_bounces = 3;
  mirrors.samples = 400;
  cases.push_back(mirrors);
  CaseSpec glass{"glass sphere", {sphere(Vec3d(0), 1, Mat::Glass), floor_plane()}};
  glass.min_bounces = 2;
  glass.glass_mask = true;
  cases.push_back(glass);
  CaseSpec mixed{"mirror + glass spheres", {sphere(Vec3d(-1.1, 0, 0), 1, Mat::Mirror), sphere(Vec3d(1.1, 0, 0), 1, Mat::Glass),
                                            floor_plane()}};
  mixed.min_bounces = 3;
  mixed.samples = 400;
  cases.push_back(mixed);
  return cases;
}

TEST(RayDifferentialFd, AnalyticSurfacesFirstOrder) {
  uint32_t seed = 11;
  for (const CaseSpec& c : analytic_cases()) expect_first_order(run_case(c, seed++), c.name, 150, c.min_bounces);
}

TEST(RayDifferentialFd, VeryLargeCoordinates) {
  const Vec3d off(1e6, -1e6, 1e6);
  uint32_t seed = 101;
  for (CaseSpec c : analytic_cases()) {
    c.scene = offset_scene(c.scene, off);
    c.target += off;
    c.tmin = 1e-6;
    c.name += " @1e6";
    expect_first_order(run_case(c, seed++), c.name, 150, c.min_bounces);
  }
}

// The blow-up rule has no unit of length (ray_differential.h): the same
// scenes 1e11 times as large keep their differentials and stay first-order
// (before, |dP| past 1e8 world units dropped every differential of a scene
// 1e10 across; this harness's own intersection tests are not scale-free
// below 1, so the small side is left to the probe's tests).
Scene3 scale_scene(Scene3 s, double k) {
  for (Prim& p : s) {
    p.c *= k;
    p.r *= k;
  }
  return s;
}

TEST(RayDifferentialFd, ScenesOfAnyScale) {
  const double k = 1e11;
  uint32_t seed = 201;
  for (CaseSpec c : analytic_cases()) {
    c.scene = scale_scene(c.scene, k);
    c.target *= k;
    c.radius_lo *= k;
    c.radius_hi *= k;
    c.tmin *= k;
    c.unit = k;
    c.name += " @x1e11";
    expect_first_order(run_case(c, seed++), c.name, 150, c.min_bounces);
  }
}

TEST(RayDifferentialFd, TessellatedSphereWithVertexNormals) {
  const test::TestMesh ball = test::uv_sphere(Vec3d(0), 1, 24, 48);
  for (Mat m : {Mat::Mirror, Mat::Glass}) {
    CaseSpec c{m == Mat::Mirror ? "mesh sphere, mirror" : "mesh sphere, glass",
               {Prim{Prim::Mesh, Vec3d(0), Vec3d(0), 1, m, 1.5, &ball}, sphere(Vec3d(2.05, 0, 0), 1, Mat::Mirror), floor_plane()}};
    c.min_bounces = 2;
    c.samples = 200;
    c.glass_mask = m == Mat::Glass;
    expect_first_order(run_case(c, m == Mat::Mirror ? 7 : 8), c.name, 100, c.min_bounces);
  }
}

TEST(RayDifferentialFd, TessellatedTeapot) {
  auto surface = make_generated_surface("teapot", 3000);
  ASSERT_TRUE(surface) << surface.status().message();
  // Scaled to about 1.2 units, centred near the origin.
  const test::TestMesh pot = test::mesh_from_surface(*surface.value(), 0.35, Vec3d(0, -0.55, 0));
  ASSERT_GT(pot.size(), 2000u);
  for (Mat m : {Mat::Mirror, Mat::Glass}) {
    CaseSpec c{m == Mat::Mirror ? "teapot, mirror" : "teapot, glass",
               {Prim{Prim::Mesh, Vec3d(0), Vec3d(0), 1, m, 1.5, &pot}, floor_plane(-0.6)}};
    c.min_bounces = 1;
    c.samples = 150;
    c.radius_lo = 2.5;
    c.radius_hi = 5;
    c.glass_mask = m == Mat::Glass;
    expect_first_order(run_case(c, m == Mat::Mirror ? 21 : 22), c.name, 80, c.min_bounces);
  }
}

// Library refraction against Snell's law (angles and coplanarity), both sides.
TEST(RayDifferential, RefractionObeysSnell) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 200; ++i) {
    HitSurface s;
    s.geometric_normal = s.normal = glm::normalize(Vec3d(u(rng), u(rng), u(rng)));
    RayDifferential r;
    r.ray.direction = glm::normalize(Vec3d(u(rng), u(rng), u(rng)));
    const double ior = 1.5;
    Refraction rf = refract(r, s, ior);
    const Vec3d d = r.ray.direction, t = rf.ray.ray.direction;
    const double cos_i = std::abs(glm::dot(d, s.normal));
    const double n1 = rf.entering ? 1.0 : ior, n2 = rf.entering ? ior : 1.0;
    const double sin_i = std::sqrt(std::max(0.0, 1 - cos_i * cos_i));
    if (rf.total_internal_reflection) {
      EXPECT_GT(n1 * sin_i, n2 * (1 - 1e-12));
      EXPECT_NEAR(glm::dot(t, s.normal), -glm::dot(d, s.normal), 1e-12);
    } else {
      const double cos_t = std::abs(glm::dot(t, s.normal));
      const double sin_t = std::sqrt(std::max(0.0, 1 - cos_t * cos_t));
      EXPECT_NEAR(n1 * sin_i, n2 * sin_t, 1e-9);
      EXPECT_NEAR(glm::dot(glm::cross(d, s.normal), t), 0.0, 1e-9);                          // coplanar
      EXPECT_GT(glm::dot(t, s.geometric_normal) * glm::dot(d, s.geometric_normal), 0.0);  // goes through
    }
  }
}

// Refraction::tilt_gain is how far the transmitted ray turns per radian the
// normal tilts: against finite differences of the direction (the angle
// between the rays refracted at the normal and at the normal tilted by h, in
// the plane of incidence and out of it), for seeded directions on both sides.
// Exact cases: 1/3 entering glass of index 1.5 head-on, 1/2 leaving it. And
// Refraction::fresnel is the renderer's Fresnel term for that hit.
TEST(RayDifferential, TiltGainMatchesFiniteDifferencesOfTheTransmittedRay) {
  HitSurface flat;
  RayDifferential head_on;
  head_on.ray.direction = Vec3d(0, 0, -1);
  EXPECT_NEAR(refract(head_on, flat, 1.5).tilt_gain, 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(refract(head_on, flat, 1.5).fresnel, 0.04, 1e-12);
  head_on.ray.direction = Vec3d(0, 0, 1);
  EXPECT_NEAR(refract(head_on, flat, 1.5).tilt_gain, 0.5, 1e-12);

  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  auto angle = [](const Vec3d& a, const Vec3d& b) { return 2 * std::asin(std::min(1.0, glm::length(a - b) / 2)); };
  int checked = 0;
  for (int i = 0; i < 300; ++i) {
    HitSurface s;
    s.geometric_normal = s.normal = glm::normalize(Vec3d(u(rng), u(rng), u(rng)));
    RayDifferential r;
    r.ray.direction = glm::normalize(Vec3d(u(rng), u(rng), u(rng)));
    const Refraction rf = refract(r, s, 1.5);
    if (rf.total_internal_reflection) {
      EXPECT_EQ(rf.fresnel, 1.0);
      continue;
    }
    const Vec3d d = r.ray.direction, n = s.normal;
    const double cos_i = std::abs(glm::dot(d, n));
    EXPECT_NEAR(rf.fresnel, fresnel_dielectric(cos_i, dielectric_eta(rf.entering, 1.5)), 1e-12);
    const double cos_t = std::abs(glm::dot(rf.ray.ray.direction, n));
    if (cos_t < 0.2 || cos_i < 0.05) continue;  // near the critical angle or grazing: second order dominates
    // The plane of incidence holds d and n; out of it is their cross product.
    const Vec3d out = glm::normalize(glm::cross(d, n)), in = glm::normalize(glm::cross(n, out));
    const double h = 1e-6;
    double turn[2];
    for (int k = 0; k < 2; ++k) {
      HitSurface tilted = s;
      tilted.geometric_normal = tilted.normal = glm::normalize(n + h * (k == 0 ? in : out));
      const Refraction rt = refract(r, tilted, 1.5);
      ASSERT_FALSE(rt.total_internal_reflection);
      turn[k] = angle(rt.ray.ray.direction, rf.ray.ray.direction) / h;
    }
    EXPECT_NEAR(turn[0], rf.tilt_gain, 1e-4 * std::max(1.0, rf.tilt_gain)) << "direction " << i;
    EXPECT_LE(turn[1], rf.tilt_gain * (1 + 1e-4)) << "direction " << i;  // out of the plane: cos t times it
    EXPECT_NEAR(turn[1], rf.tilt_gain * cos_t, 1e-4 * std::max(1.0, rf.tilt_gain)) << "direction " << i;
    ++checked;
  }
  EXPECT_GT(checked, 150);
}

// Grazing incidence on a plane: differentials are either finite and
// consistent, or dropped -- never Inf or NaN.
TEST(RayDifferential, GrazingIncidenceDropsNotNan) {
  const Vec3d n(0, 1, 0);
  int dropped = 0, kept = 0;
  for (double angle = 0.3; angle > 1e-12; angle *= 0.3) {
    RayDifferential r;
    r.ray.origin = Vec3d(0, 1, 0);
    r.ray.direction = glm::normalize(Vec3d(std::cos(angle), -std::sin(angle), 0));
    r.dd_dx = Vec3d(0, 0, 1e-3);
    r.dd_dy = Vec3d(-std::sin(angle), -std::cos(angle), 0) * 1e-3;
    r.has_differentials = true;
    const double t = 1.0 / std::sin(angle);
    transfer(r, t, n);
    EXPECT_TRUE(is_finite(r.dp_dx) && is_finite(r.dp_dy) && is_finite(r.ray.origin));
    EXPECT_TRUE(std::isfinite(footprint(r)));
    if (!r.has_differentials) {
      ++dropped;
      EXPECT_LT(std::sin(angle), 1e-4 * 1.0001);
      EXPECT_EQ(footprint(r), 0.0);
    } else {
      ++kept;
      EXPECT_TRUE(differentials_ok(r));
      // The along-slope footprint grows like t / sin(angle) (1e-3 rad per pixel).
      EXPECT_NEAR(glm::length(r.dp_dy), 1e-3 * t / std::sin(angle), 1e-6 * t / std::sin(angle));
    }
  }
  EXPECT_GT(dropped, 0);
  EXPECT_GT(kept, 0);
}

// Around the critical angle (leaving glass): refraction keeps finite
// differentials or drops them; past it, total internal reflection keeps them.
TEST(RayDifferential, CriticalAngle) {
  const double ior = 1.5, crit = std::asin(1 / ior);
  HitSurface s;  // surface y = 0, glass below (outward normal +y)
  s.geometric_normal = s.normal = Vec3d(0, 1, 0);
  int tir = 0, refracted = 0, dropped = 0;
  for (double delta : {-1e-1, -1e-3, -1e-5, -1e-7, -1e-9, 0.0, 1e-9, 1e-7, 1e-5, 1e-3, 1e-1}) {
    const double th = crit + delta;
    RayDifferential r;
    r.ray.origin = Vec3d(0);
    r.ray.direction = Vec3d(std::sin(th), std::cos(th), 0);  // upwards, leaving the glass
    r.dd_dx = Vec3d(std::cos(th), -std::sin(th), 0) * 1e-3;
    r.dd_dy = Vec3d(0, 0, 1e-3);
    r.dp_dx = Vec3d(1e-3, 0, 0);
    r.has_differentials = true;
    Refraction rf = refract(r, s, ior);
    EXPECT_FALSE(rf.entering);
    const RayDifferential& o = rf.ray;
    EXPECT_TRUE(is_finite(o.ray.direction) && is_finite(o.dd_dx) && is_finite(o.dd_dy));
    if (rf.total_internal_reflection) {
      ++tir;
      EXPECT_GE(delta, 0.0);
      EXPECT_TRUE(o.has_differentials);
      EXPECT_LT(o.ray.direction.y, 0);
    } else {
      ++refracted;
      EXPECT_LE(delta, 1e-15);
      if (!o.has_differentials) ++dropped;
      else EXPECT_TRUE(differentials_ok(o));
    }
  }
  EXPECT_GT(tir, 0);
  EXPECT_GT(refracted, 0);
  EXPECT_GT(dropped, 0);  // within 1e-4 of grazing exit
}

// A TIR prism: rays enter the top face, meet a 45-degree face beyond the
// critical angle (41.8 degrees) and reflect; the truth test holds through it.
TEST(RayDifferentialFd, TotalInternalReflectionPrism) {
  Scene3 prism{Prim{Prim::Plane, Vec3d(0), Vec3d(0, 1, 0), 1, Mat::Glass},
               Prim{Prim::Plane, Vec3d(0, -1, 0), glm::normalize(Vec3d(1, -1, 0)), 1, Mat::Glass},
               Prim{Prim::Plane, Vec3d(-5, 0, 0), Vec3d(1, 0, 0), 1, Mat::Diffuse}};
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  FdStats st;
  int tir_paths = 0;
  for (int s = 0; s < 200; ++s) {
    Camera c;
    c.eye = Vec3d(0.5 * u(rng), 4 + u(rng), 0.3 * (u(rng) - 0.5));
    c.look_at = Vec3d(0.2 * (u(rng) - 0.5), 0, 0.2 * (u(rng) - 0.5));
    c.up = Vec3d(0, 0, 1);
    c.fov_y_deg = 10 + 10 * u(rng);
    c.width = c.height = 200;
    const PinholeCamera cam = make_pinhole_camera(c);
    const double px = 200 * u(rng), py = 200 * u(rng);
    auto path = test::trace_path(prism, camera_ray_differential(cam, px, py), 4, 0, true);
    for (const auto& p : path) tir_paths += p.tir;
    fd_sample(prism, cam, px, py, 4, 0, 1e-7, st);
  }
  EXPECT_GT(tir_paths, 50);
  expect_first_order(st, "TIR prism", 150, 2);
}

// Rays through vertices and along edges of a tessellated mirror: the
// watertight test never lets them slip through, the flat mirror transfers
// differentials exactly, and rays in the plane of the mesh are clean misses.
TEST(RayDifferential, EdgesAndVerticesOfATessellation) {
  test::TestMesh grid;
  const int N = 8;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) {
      auto v = [&](int a, int b) { return Vec3d(-1 + 2.0 * a / N, 0, -1 + 2.0 * b / N); };
      for (Vec3d p : {v(i, j), v(i, j + 1), v(i + 1, j + 1), v(i, j), v(i + 1, j + 1), v(i + 1, j)}) {
        grid.p.push_back(p);
        grid.n.push_back(Vec3d(0, 1, 0));
      }
    }
  Scene3 scene{Prim{Prim::Mesh, Vec3d(0), Vec3d(0), 1, Mat::Mirror, 1.5, &grid},
               Prim{Prim::Plane, Vec3d(0, 3, 0), Vec3d(0, -1, 0), 1, Mat::Diffuse}};
  Camera c;
  c.eye = Vec3d(0.31, 2.0, 2.7);
  c.look_at = Vec3d(0, 0, 0);
  c.width = 640;
  c.height = 480;
  const PinholeCamera cam = make_pinhole_camera(c);
  // Pixel coordinates of a world point (inverse of the camera mapping).
  auto pixel_of = [&](const Vec3d& p, double& px, double& py) {
    const Vec3d d = p - cam.eye;
    const double w = glm::dot(d, cam.forward);
    px = (glm::dot(d, cam.right) / w / cam.tan_half_x + 1) * 0.5 * cam.width;
    py = (1 - glm::dot(d, cam.up) / w / cam.tan_half_y) * 0.5 * cam.height;
  };
  int targets = 0;
  FdStats st;
  for (int i = 1; i < N; ++i)
    for (int j = 1; j < N; ++j)
      for (Vec3d off : {Vec3d(0), Vec3d(1.0 / N, 0, 0), Vec3d(0, 0, 1.0 / N), Vec3d(1.0 / N, 0, 1.0 / N)}) {
        // Vertices, edge midpoints and diagonal midpoints.
        const Vec3d target = Vec3d(-1 + 2.0 * i / N, 0, -1 + 2.0 * j / N) + off;
        // The ray exactly through the target, from the eye.
        const Vec3d d = glm::normalize(target - cam.eye);
        auto h = test::intersect(scene, cam.eye, d, 0, -1, -1);
        ASSERT_TRUE(h.found() && h.prim == 0) << "slipped through at " << target.x << "," << target.z;
        EXPECT_LT(glm::length(h.s.point - target), 1e-12);
        ++targets;
        double px, py;
        pixel_of(target, px, py);
        fd_sample(scene, cam, px, py, 2, 0, 1e-9, st);
      }
  EXPECT_EQ(targets, (N - 1) * (N - 1) * 4);
  // A flat mirror maps neighbouring rays exactly (up to the perspective's
  // second-order term in the final transfer); compare as for smooth cases.
  EXPECT_GE(int(st.ratios.size()) + st.exact, targets);
  EXPECT_EQ(st.dropped, 0);
  // Rays in the plane of the mesh, along an edge: a clean miss, no NaN.
  for (int j = 0; j <= N; ++j) {
    const Vec3d o(-3, 0, -1 + 2.0 * j / N);
    auto h = test::intersect(scene, o, Vec3d(1, 0, 0), 0, -1, -1);
    EXPECT_FALSE(h.found() && h.prim == 0);
  }
}

// Degenerate vertex normals (cancelling) drop the differentials at that hit.
TEST(RayDifferential, DegenerateNormalsDrop) {
  const Vec3d p0(0, 0, 0), p1(1, 0, 0), p2(0, 0, 1);
  const Vec3d n[3] = {Vec3d(0, 1, 0), Vec3d(0, -1, 0), Vec3d(0, 1, 0)};
  // b0 = b1 = 0.5, b2 = 0: n0 and n1 cancel.
  HitSurface s = triangle_surface_point(p0, p1, p2, n, 0.5, 0.0);
  EXPECT_TRUE(s.normal_degenerate);
  RayDifferential r;
  r.ray.direction = Vec3d(0, -1, 0);
  r.dd_dx = Vec3d(1e-3, 0, 0);
  r.has_differentials = true;
  RayDifferential out = reflect(r, s);
  EXPECT_FALSE(out.has_differentials);
  EXPECT_TRUE(is_finite(out.ray.direction));
  EXPECT_EQ(footprint(out), 0.0);
}

// The interpolated-normal Jacobian matches finite differences of the normal.
TEST(RayDifferential, NormalJacobianMatchesFiniteDifferences) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 100; ++i) {
    Vec3d p[3], n[3];
    for (int k = 0; k < 3; ++k) {
      p[k] = Vec3d(u(rng), u(rng), u(rng));
      n[k] = glm::normalize(Vec3d(u(rng), u(rng), u(rng)) * 0.5 + Vec3d(0, 0, 1));
    }
    const double b1 = 0.2 + 0.3 * (u(rng) + 1) / 2, b2 = 0.1 + 0.3 * (u(rng) + 1) / 2;
    HitSurface s = triangle_surface_point(p[0], p[1], p[2], n, b1, b2);
    if (s.normal_degenerate) continue;
    const double h = 1e-6;
    HitSurface s1 = triangle_surface_point(p[0], p[1], p[2], n, b1 + h, b2);
    const Vec3d dp = s1.point - s.point;
    const Vec3d dn_fd = s1.normal - s.normal;
    const Vec3d dn = s.normal_jacobian * dp;
    EXPECT_LT(glm::length(dn - dn_fd), 1e-4 * glm::length(dn_fd) + 1e-12);
  }
}

TEST(RayDifferential, CameraRayMatchesRenderer) {
  Camera c;
  c.eye = Vec3d(1, 2, 3);
  c.look_at = Vec3d(0, 0.5, 0);
  c.width = 320;
  c.height = 200;
  const PinholeCamera cam = make_pinhole_camera(c);
  const RayDifferential r = camera_ray_differential(cam, 17.25, 140.5);
  const Ray ray = cam.generate(17.25, 140.5);
  EXPECT_EQ(r.ray.origin, ray.origin);
  EXPECT_EQ(r.ray.direction, ray.direction);
  // dD/dx against a central difference of the renderer's mapping.
  const double h = 1e-4;
  const Vec3d fd = (cam.generate(17.25 + h, 140.5).direction - cam.generate(17.25 - h, 140.5).direction) / (2 * h);
  EXPECT_LT(glm::length(fd - r.dd_dx), 1e-7 * glm::length(fd));
  EXPECT_EQ(r.dp_dx, Vec3d(0));
}

}  // namespace
}  // namespace raylod
