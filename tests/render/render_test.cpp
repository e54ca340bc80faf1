// Renderer unit tests: welding, Embree scene, specular chains (slab offset,
// prism TIR), effect switches and ray counters, determinism across thread
// counts, memory limit and errors. The camera mapping and the optics are
// tested in tests/geometry.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <span>
#include <fstream>

#if defined(__linux__)
#include <sys/prctl.h>
#endif
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#include <glm/gtc/matrix_transform.hpp>

#include "core/system.h"
#include "render/integrator.h"
#include "render/renderer.h"
#include "render/srgb.h"
#include "render_test_util.h"
#include "streaming/draco_io.h"

namespace raylod {
namespace {

using namespace raylod::testing;
constexpr double kInf = std::numeric_limits<double>::infinity();

TEST(Weld, SharedCornersBecomeOneVertexUnlessNormalsDiffer) {
  const std::vector<Vec3> soup = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  TriangleMesh m = weld_triangles(soup, {});
  EXPECT_EQ(m.positions.size(), 4u);
  EXPECT_EQ(m.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  std::vector<Vec3> normals(6, Vec3(0, 0, 1));
  normals[3] = Vec3(0, 1, 0);  // a crease at corner 0 of the second triangle
  TriangleMesh c = weld_triangles(soup, normals);
  EXPECT_EQ(c.positions.size(), 5u);
}

TEST(EmbreeSceneTest, HitDistanceBarycentricsAndTriangleIds) {
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_box({-1, -1, -1}, {1, 1, 1}, 0));
  meshes.push_back(make_box({-1, -1, -6}, {1, 1, -4}, 0));
  auto scene = EmbreeScene::build(std::move(meshes));
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  EXPECT_EQ((*scene)->info().triangles, 24u);
  Hit hit;
  ASSERT_TRUE((*scene)->intersect(Ray{{0.25, 0.5, 5}, {0, 0, -1}}, 0, kInf, hit));
  EXPECT_NEAR(hit.t, 4.0, 1e-6);
  const SurfacePoint sp = surface_point(**scene, hit);
  EXPECT_NEAR(glm::length(sp.position - Vec3d(0.25, 0.5, 1)), 0, 1e-6);
  EXPECT_NEAR(sp.geometric.z, 1.0, 1e-9);  // outward
  // Starting past the first box hits the second one, whose ids follow the first's.
  ASSERT_TRUE((*scene)->intersect(Ray{{0.25, 0.5, -2}, {0, 0, -1}}, 0, kInf, hit));
  EXPECT_EQ(hit.geom, 1u);
  EXPECT_GE((*scene)->triangle_id(hit.geom, hit.prim), 12u);
  EXPECT_TRUE((*scene)->occluded(Ray{{0, 0, 5}, {0, 0, -1}}, 0, 10));
  EXPECT_FALSE((*scene)->occluded(Ray{{0, 0, 5}, {0, 0, -1}}, 0, 3.9));
}

TEST(EmbreeSceneTest, SmallPagesOnlyWhileTheGuardLives) {
#if defined(__linux__) && defined(PR_SET_THP_DISABLE)
  ASSERT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 0);
  {
    const ScopedSmallPages outer;
    EXPECT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 1);
    {
      const ScopedSmallPages inner;  // nested: leaves the outer one's setting alone
    }
    EXPECT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 1);
  }
  EXPECT_EQ(prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0), 0);
#else
  GTEST_SKIP() << "no PR_SET_THP_DISABLE here";
#endif
}

TEST(EmbreeSceneTest, RejectsBadInMemoryMeshes) {
  TriangleMesh m = make_box({0, 0, 0}, {1, 1, 1}, 0);
  m.indices[5] = 99;
  std::vector<TriangleMesh> v;
  v.push_back(m);
  auto s = EmbreeScene::build(std::move(v));
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.status().message().find("out of range"), std::string::npos);
  auto empty = EmbreeScene::build({});
  EXPECT_FALSE(empty.is_ok());
}

Scene glass_scene() {
  Scene s = base_scene(8, 8);
  s.materials = {material("glass", MaterialType::Glass), material("floor", MaterialType::Diffuse)};
  return s;
}

TEST(SpecularChain, SlabDisplacesTheRayByTheAnalyticOffset) {
  const double h = 0.5, n = 1.5;
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_box({-5, -5, float(-h / 2)}, {5, 5, float(h / 2)}, 0));
  auto geometry = EmbreeScene::build(std::move(meshes));
  ASSERT_TRUE(geometry.is_ok());
  const Scene s = glass_scene();
  for (double deg : {0.0, 15.0, 30.0, 60.0}) {
    const double th = glm::radians(deg);
    const Ray ray{{-2 * std::sin(th), 0.1, 2 * std::cos(th)}, {std::sin(th), 0, -std::cos(th)}};
    const auto chain = trace_specular_chain(**geometry, s, ray, 8);
    ASSERT_EQ(chain.size(), 3u) << deg;
    EXPECT_EQ(chain[0].event, ChainVertex::Event::Refract);
    EXPECT_EQ(chain[1].event, ChainVertex::Event::Refract);
    EXPECT_EQ(chain[2].event, ChainVertex::Event::Escape);
    // Snell inside, and the exit direction is parallel to the incident one.
    const double tt = std::asin(std::sin(th) / n);
    EXPECT_NEAR(chain[0].direction_out.x, std::sin(tt), 1e-6);
    EXPECT_NEAR(glm::length(chain[1].direction_out - ray.direction), 0, 1e-6);
    const double expected = h * std::sin(th - tt) / std::cos(tt);
    const double offset = glm::length(glm::cross(chain[1].position - ray.origin, ray.direction));
    EXPECT_NEAR(offset, expected, 2e-5) << deg << " degrees";
  }
}

TEST(SpecularChain, NoSelfIntersectionFarFromTheOriginOrAtGrazingAngles) {
  // CAD coordinates far from the origin: float vertices are 1e-3 apart at
  // 1e4, so spawn offsets must scale with the coordinates or secondary rays
  // re-hit the surface they leave (extra events in the chain).
  const double h = 0.5, n = 1.5;
  for (double far : {0.0, 1e4}) {
    std::vector<TriangleMesh> meshes;
    meshes.push_back(make_box({float(far - 50), -5, float(-h / 2)}, {float(far + 50), 5, float(h / 2)}, 0));
    auto geometry = EmbreeScene::build(std::move(meshes));
    ASSERT_TRUE(geometry.is_ok());
    const Scene s = glass_scene();
    for (double deg = 0; deg < 89.5; deg += 4.0 + (deg >= 84 ? -3.0 : 0.0)) {
      const double th = glm::radians(deg);
      const Vec3d dir(std::sin(th), 0, -std::cos(th));
      const Ray ray{Vec3d(far, 0.1, h) - 10.0 * dir, dir};  // starts above the slab
      const auto chain = trace_specular_chain(**geometry, s, ray, 8);
      ASSERT_EQ(chain.size(), 3u) << "far " << far << ", " << deg << " degrees";
      EXPECT_EQ(chain[0].event, ChainVertex::Event::Refract);
      EXPECT_EQ(chain[1].event, ChainVertex::Event::Refract);
      const double tt = std::asin(std::sin(th) / n);
      const double expected = h * std::sin(th - tt) / std::cos(tt);
      const double offset = glm::length(glm::cross(chain[1].position - ray.origin, ray.direction));
      // Float vertices at 1e4 are ~1e-3 apart: the offset is that exact there.
      EXPECT_NEAR(offset, expected, far > 0 ? 1e-2 : 1e-4) << "far " << far << ", " << deg << " degrees";
    }
  }
}

TEST(SpecularChain, PrismTurnsTheRayByTotalInternalReflection) {
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_prism(1, 1, 0));
  auto geometry = EmbreeScene::build(std::move(meshes));
  ASSERT_TRUE(geometry.is_ok());
  const Scene s = glass_scene();
  // Perpendicular onto leg AC at (-0.5, 0.5): 45 degrees at the hypotenuse,
  // past the critical angle asin(1/1.5) = 41.8 degrees.
  const Vec3d d = glm::normalize(Vec3d(1, -1, 0));
  const Ray ray{Vec3d(-0.5, 0.5, 0.2) - 2.0 * d, d};
  const auto chain = trace_specular_chain(**geometry, s, ray, 8);
  ASSERT_EQ(chain.size(), 4u);
  EXPECT_EQ(chain[0].event, ChainVertex::Event::Refract);
  EXPECT_EQ(chain[1].event, ChainVertex::Event::TotalInternalReflection);
  EXPECT_EQ(chain[2].event, ChainVertex::Event::Refract);
  EXPECT_EQ(chain[3].event, ChainVertex::Event::Escape);
  EXPECT_NEAR(glm::length(chain[1].position - Vec3d(0, 0, 0.2)), 0, 1e-5);
  EXPECT_NEAR(glm::length(chain[2].direction_out - glm::normalize(Vec3d(1, 1, 0))), 0, 1e-6);
  // At a shallower angle (30 degrees off the hypotenuse normal) the ray refracts out.
  const Vec3d d2 = glm::normalize(Vec3d(std::sin(glm::radians(30.0)), -std::cos(glm::radians(30.0)), 0));
  const auto chain2 = trace_specular_chain(**geometry, s, Ray{Vec3d(0, 0.5, 0) - 2.0 * d2, d2}, 8);
  ASSERT_GE(chain2.size(), 2u);
  EXPECT_EQ(chain2[1].event, ChainVertex::Event::Refract);
}

// Sphere on a floor; materials and lights chosen per test.
RenderResult render_counting(const std::vector<Material>& mats, std::vector<Light> lights, int max_depth = 5,
                             int spp = 2) {
  Scene s = base_scene(32, 24);
  s.camera.eye = {0, 2, 5};
  s.camera.look_at = {0, 0.8, 0};
  s.materials = mats;
  s.lights = std::move(lights);
  s.max_depth = max_depth;
  s.spp = spp;
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_sphere({0, 1, 0}, 1, 12, 24, 0));
  meshes.push_back(make_ground_mesh(Ground{0, 20, 1}, s.camera));
  return render_meshes(std::move(meshes), s);
}

TEST(Effects, DiffuseOnlySceneTracesNoReflectionOrRefractionRays) {
  auto r = render_counting({material("a", MaterialType::Diffuse), material("b", MaterialType::Diffuse)},
                           {point_light({2, 5, 3}, 30)});
  EXPECT_EQ(r.stats.rays.camera, 32u * 24u * 2u);
  EXPECT_GT(r.stats.rays.shadow, 0u);
  EXPECT_LE(r.stats.rays.shadow, r.stats.rays.camera);  // at most one per light per hit
  EXPECT_EQ(r.stats.rays.reflection, 0u);
  EXPECT_EQ(r.stats.rays.refraction, 0u);
  EXPECT_FALSE(r.stats.effects.reflection);
  EXPECT_FALSE(r.stats.effects.refraction);
  EXPECT_TRUE(r.stats.effects.shadows);
}

TEST(Effects, NoLightsMeansNoShadowRays) {
  auto r = render_counting({material("m", MaterialType::Mirror), material("b", MaterialType::Diffuse)}, {});
  EXPECT_EQ(r.stats.rays.shadow, 0u);
  EXPECT_GT(r.stats.rays.reflection, 0u);
  EXPECT_EQ(r.stats.rays.refraction, 0u);
  EXPECT_FALSE(r.stats.effects.shadows);
  EXPECT_EQ(r.stats.effects.describe(), "reflection");
}

TEST(Effects, GlossyHighlightsCostNoRays) {
  Material glossy = material("g", MaterialType::Glossy);
  glossy.specular = Vec3(0.5f);
  auto d = render_counting({material("a", MaterialType::Diffuse), material("b", MaterialType::Diffuse)},
                           {point_light({2, 5, 3}, 30)});
  auto g = render_counting({glossy, material("b", MaterialType::Diffuse)}, {point_light({2, 5, 3}, 30)});
  EXPECT_TRUE(g.stats.effects.glossy);
  EXPECT_FALSE(d.stats.effects.glossy);
  EXPECT_EQ(g.stats.rays.total(), d.stats.rays.total());
  EXPECT_NE(0, std::memcmp(g.color.pixels.data(), d.color.pixels.data(), g.color.pixels.size() * sizeof(float)));
}

TEST(Effects, GlassSpawnsRefractionAndMaxDepthZeroSwitchesBouncesOff) {
  auto g = render_counting({material("g", MaterialType::Glass), material("b", MaterialType::Diffuse)},
                           {point_light({2, 5, 3}, 30)});
  EXPECT_GT(g.stats.rays.refraction, 0u);
  EXPECT_GT(g.stats.rays.reflection, 0u);
  auto flat = render_counting({material("g", MaterialType::Glass), material("b", MaterialType::Diffuse)},
                              {point_light({2, 5, 3}, 30)}, 0);
  EXPECT_EQ(flat.stats.rays.refraction + flat.stats.rays.reflection, 0u);
  EXPECT_FALSE(flat.stats.effects.refraction);
}

TEST(Effects, OnlyMaterialsTheGeometryUsesCount) {
  Scene s = base_scene(4, 4);
  s.materials = {material("d", MaterialType::Diffuse), material("glass", MaterialType::Glass)};
  s.lights.push_back(point_light({0, 5, 0}, 1));
  const std::vector<int> used = {0};
  const Effects e = effects_for(s, used);
  EXPECT_FALSE(e.refraction);
  EXPECT_FALSE(e.reflection);
  EXPECT_EQ(e.describe(), "diffuse, shadows (1 light)");
}

// The effects line says what is traced: glass of ior 1 reflects nothing,
// glass of tint 0 lets nothing through (it reported both on while tracing
// none of them), and the rays agree.
TEST(Effects, GlassThatReflectsOrTransmitsNothingSaysSo) {
  Material clear = material("g", MaterialType::Glass);
  clear.ior = 1.0f;
  auto same = render_counting({clear, material("b", MaterialType::Diffuse)}, {point_light({2, 5, 3}, 30)});
  EXPECT_FALSE(same.stats.effects.reflection);
  EXPECT_TRUE(same.stats.effects.refraction);
  EXPECT_EQ(same.stats.rays.reflection, 0u);
  EXPECT_GT(same.stats.rays.refraction, 0u);
  Material opaque = material("g", MaterialType::Glass);
  opaque.tint = Vec3(0.0f);
  auto dark = render_counting({opaque, material("b", MaterialType::Diffuse)}, {point_light({2, 5, 3}, 30)});
  EXPECT_TRUE(dark.stats.effects.reflection);
  EXPECT_FALSE(dark.stats.effects.refraction);
  EXPECT_GT(dark.stats.rays.reflection, 0u);
  EXPECT_EQ(dark.stats.rays.refraction, 0u);
}

TEST(Determinism, SameImageForOneAndTwoThreads) {
  // The renderer sets no thread limit of its own: the arena it runs in bounds it.
  auto render_with_threads = [](int threads) {
    const Scene s = sphere_box_scene(48, 36, material("glass", MaterialType::Glass));
    std::vector<TriangleMesh> meshes = sphere_box_meshes(s);
    RenderOptions o = quiet_options();
    o.aov_depth = o.aov_triangle_id = true;
    o.tile_size = 8;
    RenderResult result;
    tbb::task_arena(threads).execute([&] { result = render_meshes(std::move(meshes), s, o); });
    return result;
  };
  const RenderResult a = render_with_threads(1), b = render_with_threads(2);
  // The parallelism each render ran with, as reported: the arena's, within
  // the process's limit (all cores here).
  const int cores = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  EXPECT_EQ(a.stats.threads, 1);
  EXPECT_EQ(b.stats.threads, std::min(2, cores));
  ASSERT_EQ(a.color.pixels.size(), b.color.pixels.size());
  EXPECT_EQ(0, std::memcmp(a.color.pixels.data(), b.color.pixels.data(), a.color.pixels.size() * sizeof(float)));
  EXPECT_EQ(0, std::memcmp(a.depth.pixels.data(), b.depth.pixels.data(), a.depth.pixels.size() * sizeof(float)));
  EXPECT_EQ(a.triangle_id, b.triangle_id);
  EXPECT_EQ(a.stats.rays.total(), b.stats.rays.total());
  EXPECT_EQ(a.stats.rays.refraction, b.stats.rays.refraction);
}

// A scene and the same scene a hundred-thousandth the size (positions, camera,
// ground; point lights' intensity by the square, as they fall off with
// distance) shade alike: the secondary rays' offset scales with objects
// smaller than a unit (IntegratorConfig::offset_floor). With an absolute
// 2e-6, 714 of the 9,216 channels differed by more than 0.02.
TEST(Determinism, SameImageAtAHundredThousandthOfTheSize) {
  auto render_at = [](double scale) {
    Scene s = sphere_box_scene(64, 48, material("ball", MaterialType::Diffuse));
    s.camera.eye *= scale;
    s.camera.look_at *= scale;
    for (Light& l : s.lights) {
      l.position *= scale;
      if (l.type == LightType::Point) l.intensity *= float(scale * scale);
    }
    std::vector<TriangleMesh> meshes;
    meshes.push_back(make_sphere({-0.6f, 1, 0}, 0.8f, 16, 32, 0));
    meshes.push_back(make_box({0.6f, 0, -1}, {1.6f, 1.5f, 0}, 1));
    for (TriangleMesh& m : meshes)
      for (Vec3& p : m.positions) p *= float(scale);
    meshes.push_back(make_ground_mesh(Ground{0, 20 * scale, 2}, s.camera));
    return render_meshes(std::move(meshes), s);
  };
  const RenderResult a = render_at(1.0), b = render_at(1e-5);
  ASSERT_EQ(a.color.pixels.size(), b.color.pixels.size());
  size_t differ = 0;
  for (size_t i = 0; i < a.color.pixels.size(); ++i) differ += std::abs(a.color.pixels[i] - b.color.pixels[i]) > 0.02f;
  EXPECT_LE(differ, a.color.pixels.size() / 200) << differ << " of " << a.color.pixels.size() << " channels differ";
}

// The builder by scene size and by the camera rays the BVH serves: small
// scenes high quality; large ones medium, or low where the frame has fewer
// camera rays than the scene has triangles (its build is then most of the
// render). The memory estimate covers the low builder's larger compact
// peak, and a limit only the medium compact build meets falls back to it.
TEST(BvhQualityChoice, BySizeAndCameraRays) {
  BvhConfig c;
  EXPECT_EQ(choose_bvh_quality(1000, c), BvhQuality::High);
  EXPECT_EQ(choose_bvh_quality(c.high_quality_below, c), BvhQuality::Medium);  // rays unknown
  c.camera_rays = 1280 * 960 * 4;
  EXPECT_EQ(choose_bvh_quality(1000, c), BvhQuality::High);
  EXPECT_EQ(choose_bvh_quality(c.camera_rays, c), BvhQuality::Medium);
  EXPECT_EQ(choose_bvh_quality(c.camera_rays + 1, c), BvhQuality::Low);
  EXPECT_EQ(choose_bvh_quality(10'000'000, c), BvhQuality::Low);
  c.low_quality_below_rays_per_triangle = 0.25;
  EXPECT_EQ(choose_bvh_quality(10'000'000, c), BvhQuality::Medium);
  EXPECT_EQ(choose_bvh_quality(4 * c.camera_rays + 4, c), BvhQuality::Low);

  BvhConfig low;
  low.camera_rays = 1;
  BvhConfig medium;
  const uint64_t n = 30'000'000;  // compact from 20M
  EXPECT_GT(estimate_render_memory(n, low), estimate_render_memory(n, medium));
  EXPECT_EQ(estimate_render_memory(5'000'000, low), estimate_render_memory(5'000'000, medium));
  // Between the two compact estimates: the medium compact build is chosen.
  const uint64_t limit = (estimate_render_memory(n, low) + estimate_render_memory(n, medium)) / 2;
  const BvhConfig chosen = bvh_for_memory_limit(n, limit, low);
  EXPECT_EQ(chosen.compact_from, 0u);
  EXPECT_EQ(choose_bvh_quality(n, chosen), BvhQuality::Medium);
  EXPECT_LE(estimate_render_memory(n, chosen), limit);
  // With room for it, the low compact build stays.
  EXPECT_EQ(choose_bvh_quality(n, bvh_for_memory_limit(n, estimate_render_memory(n, low), low)), BvhQuality::Low);
}

// The low-quality (Morton) build gives the same image for one and two
// threads, and the same hits as the medium build but where two triangles
// tie at a ray (a shared edge): a closest hit does not depend on the tree.
TEST(BvhQualityChoice, LowBuildIsDeterministicAndFindsTheSameHits) {
  const Scene s = sphere_box_scene(64, 48, material("glass", MaterialType::Glass));
  auto render_with = [&](const BvhConfig& config, int threads) {
    RenderOptions o = quiet_options();
    o.aov_depth = o.aov_triangle_id = true;
    RenderResult result;
    tbb::task_arena(threads).execute([&] {
      auto geometry = EmbreeScene::build(sphere_box_meshes(s), config);
      if (!geometry) throw std::runtime_error(geometry.status().message());
      EXPECT_EQ((*geometry)->info().quality.substr(0, 3), config.camera_rays == 1 ? "low" : "med");
      result = render_embree_scene(**geometry, s, o);
    });
    return result;
  };
  BvhConfig low, medium;
  low.high_quality_below = medium.high_quality_below = 0;
  low.camera_rays = 1;
  const RenderResult a = render_with(low, 1), b = render_with(low, 2), m = render_with(medium, 2);
  ASSERT_EQ(a.color.pixels.size(), b.color.pixels.size());
  EXPECT_EQ(0, std::memcmp(a.color.pixels.data(), b.color.pixels.data(), a.color.pixels.size() * sizeof(float)));
  EXPECT_EQ(a.triangle_id, b.triangle_id);
  size_t differ = 0;
  for (size_t i = 0; i < m.triangle_id.size(); ++i) differ += m.triangle_id[i] != b.triangle_id[i];
  EXPECT_LE(differ, m.triangle_id.size() / 200) << differ << " of " << m.triangle_id.size() << " pixels";
  for (size_t i = 0; i < m.depth.pixels.size(); ++i) EXPECT_NEAR(m.depth.pixels[i], b.depth.pixels[i], 1e-4f) << i;
}

TEST(TileShares, RunsOfTilesCoverTheFrameOnceWithLengthsOneApart) {
  EXPECT_EQ(tile_run_bounds(10, 4, 0), std::make_pair(uint64_t(0), uint64_t(3)));
  EXPECT_EQ(tile_run_bounds(10, 4, 1), std::make_pair(uint64_t(3), uint64_t(6)));
  EXPECT_EQ(tile_run_bounds(10, 4, 2), std::make_pair(uint64_t(6), uint64_t(8)));
  EXPECT_EQ(tile_run_bounds(10, 4, 3), std::make_pair(uint64_t(8), uint64_t(10)));
  for (uint64_t tiles : {1, 7, 35, 8160})
    for (uint64_t runs = 1; runs <= std::min<uint64_t>(tiles, 100); ++runs) {
      uint64_t next = 0, shortest = UINT64_MAX, longest = 0;
      for (uint64_t k = 0; k < runs; ++k) {
        const auto [first, last] = tile_run_bounds(tiles, runs, k);
        ASSERT_EQ(first, next) << tiles << " tiles, " << runs << " runs, run " << k;
        shortest = std::min(shortest, last - first);
        longest = std::max(longest, last - first);
        next = last;
      }
      EXPECT_EQ(next, tiles);
      EXPECT_GE(shortest, 1u);
      EXPECT_LE(longest - shortest, 1u);
    }
}

// The tile-share tests' scene: a sphere of `sphere` over a ground plane,
// 50 x 37 pixels (partial 8 x 8 tiles at the right and bottom), and its meshes.
Scene sphere_on_ground(const Material& sphere, double light) {
  Scene s = base_scene(50, 37);
  s.camera.eye = {0.5, 2, 5};
  s.camera.look_at = {0, 0.8, 0};
  s.materials = {sphere, material("floor", MaterialType::Diffuse)};
  s.lights = {point_light({2, 5, 3}, light)};
  return s;
}
std::vector<TriangleMesh> sphere_on_ground_meshes(const Scene& s) {
  std::vector<TriangleMesh> m;
  m.push_back(make_sphere({0, 1, 0}, 0.8f, 16, 32, 0));
  m.push_back(make_ground_mesh(Ground{0, 20, 1}, s.camera));
  return m;
}
// Whether pixel (x, y) of that 50 x 37 frame, cut into 8 x 8 tiles and
// those into `run_count` runs, lies in one of `runs`.
bool in_runs(int x, int y, uint64_t run_count, std::span<const uint64_t> runs) {
  const int tiles_x = (50 + 7) / 8, tiles = tiles_x * ((37 + 7) / 8);
  const uint64_t t = uint64_t((y / 8) * tiles_x + x / 8);
  for (uint64_t k : runs) {
    const auto [first, last] = tile_run_bounds(uint64_t(tiles), run_count, k);
    if (t >= first && t < last) return true;
  }
  return false;
}

// What `mpirun raylod render` does on each rank: the runs of tiles it was
// handed (unevenly, as a rank that finishes early takes more), each pixel
// as the whole frame has it, the rest 0, and the rays of the shares adding
// up to the frame's.
TEST(TileShares, TheRanksRunsMakeTheFrame) {
  const Scene s = sphere_on_ground(material("mirror", MaterialType::Mirror), 30);
  auto meshes = [&] { return sphere_on_ground_meshes(s); };
  RenderOptions o = quiet_options();
  o.tile_size = 8;
  const RenderResult whole = render_meshes(meshes(), s, o);
  EXPECT_EQ(whole.tile_runs, std::vector<uint64_t>{0});
  o.tile_runs = 8;  // 35 tiles: runs of 5 and 4
  const std::vector<std::vector<uint64_t>> dealt = {{3, 0, 1, 2}, {7}, {4, 6, 5}};
  RayCounters rays;
  std::vector<int> covered(size_t(50) * 37, 0);
  for (size_t r = 0; r < dealt.size(); ++r) {
    size_t given = 0;
    o.next_tile_run = [&]() -> std::optional<uint64_t> {
      if (given == dealt[r].size()) return std::nullopt;
      return dealt[r][given++];
    };
    const RenderResult share = render_meshes(meshes(), s, o);
    std::vector<uint64_t> runs = dealt[r];
    std::sort(runs.begin(), runs.end());
    EXPECT_EQ(share.tile_runs, runs);
    rays += share.stats.rays;
    for (int y = 0; y < 37; ++y)
      for (int x = 0; x < 50; ++x) {
        const bool mine = in_runs(x, y, 8, runs);
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(share.color.at(x, y)[c], mine ? whole.color.at(x, y)[c] : 0.0f) << x << "," << y << " rank " << r;
        covered[size_t(y) * 50 + x] += mine;
      }
  }
  EXPECT_EQ(std::count(covered.begin(), covered.end(), 1), 50 * 37);
  EXPECT_EQ(rays.total(), whole.stats.rays.total());
  EXPECT_EQ(rays.reflection, whole.stats.rays.reflection);
}

// RenderOptions::srgb_color: each pixel encoded where its tile is finished
// gives the bytes of encoding the linear frame, for the whole frame and for
// a rank's runs of tiles, and the same PNG file; a float format refuses it.
TEST(SrgbColor, EncodedTileByTileIsTheLinearFrameEncoded) {
  // A light bright enough to clip: bytes at 255.
  const Scene s = sphere_on_ground(material("glossy", MaterialType::Glossy), 80);
  auto meshes = [&] { return sphere_on_ground_meshes(s); };
  RenderOptions o = quiet_options();
  o.tile_size = 8;
  const RenderResult linear = render_meshes(meshes(), s, o);
  std::vector<uint8_t> expected(linear.color.pixels.size());
  srgb_bytes(linear.color.pixels, expected);
  size_t clipped = 0, black = 0;
  for (uint8_t b : expected) clipped += b == 255, black += b == 0;
  EXPECT_GT(clipped, 0u);
  EXPECT_GT(black, 0u);
  o.srgb_color = true;
  const RenderResult encoded = render_meshes(meshes(), s, o);
  EXPECT_TRUE(encoded.color.empty());
  ASSERT_EQ(encoded.srgb.width, 50);
  ASSERT_EQ(encoded.srgb.height, 37);
  ASSERT_EQ(encoded.srgb.channels, 3);
  EXPECT_EQ(encoded.srgb.pixels, expected);
  EXPECT_EQ(encoded.stats.rays.total(), linear.stats.rays.total());
  // A rank's share: its runs' pixels as the whole frame has them.
  o.tile_runs = 8;
  const std::vector<uint64_t> dealt = {6, 1, 3};
  size_t given = 0;
  o.next_tile_run = [&]() -> std::optional<uint64_t> {
    if (given == dealt.size()) return std::nullopt;
    return dealt[given++];
  };
  const RenderResult share = render_meshes(meshes(), s, o);
  size_t mine_pixels = 0;
  for (int y = 0; y < 37; ++y)
    for (int x = 0; x < 50; ++x) {
      if (!in_runs(x, y, 8, dealt)) continue;
      ++mine_pixels;
      for (int c = 0; c < 3; ++c) ASSERT_EQ(share.srgb.at(x, y)[c], encoded.srgb.at(x, y)[c]) << x << "," << y;
    }
  EXPECT_GT(mine_pixels, 0u);
  // The same file as the linear frame's.
  const auto dir = test_tmp("render-srgb");
  ASSERT_TRUE(write_image(dir / "linear.png", linear.color).is_ok());
  ASSERT_TRUE(write_image(dir / "encoded.png", encoded.srgb).is_ok());
  auto bytes = [](const std::filesystem::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  EXPECT_FALSE(bytes(dir / "linear.png").empty());
  EXPECT_EQ(bytes(dir / "linear.png"), bytes(dir / "encoded.png"));
  // write_color writes whichever frame the render made.
  ASSERT_TRUE(write_color(dir / "from_encoded.png", encoded).is_ok());
  ASSERT_TRUE(write_color(dir / "from_linear.png", linear).is_ok());
  EXPECT_EQ(bytes(dir / "from_encoded.png"), bytes(dir / "linear.png"));
  EXPECT_EQ(bytes(dir / "from_linear.png"), bytes(dir / "linear.png"));
  ASSERT_TRUE(write_color(dir / "from_linear.exr", linear).is_ok());
  EXPECT_FALSE(write_color(dir / "from_encoded.exr", encoded).is_ok());
  const Status exr = write_image(dir / "encoded.exr", encoded.srgb);
  ASSERT_FALSE(exr.is_ok());
  EXPECT_NE(exr.message().find("encoded.exr"), std::string::npos) << exr.message();
  EXPECT_NE(exr.message().find("linear"), std::string::npos) << exr.message();
  EXPECT_FALSE(std::filesystem::exists(dir / "encoded.exr"));
  // The frame's memory estimate counts the 8-bit frame, not the float one.
  RenderOptions bytes_only;
  bytes_only.srgb_color = true;
  EXPECT_LT(estimate_image_memory(3840, 2160, bytes_only), estimate_image_memory(3840, 2160, RenderOptions{}) / 2);
}

TEST(Aov, DepthNormalAndTriangleIdOfTheCentrePixel) {
  Scene s = base_scene(33, 33);
  s.camera.eye = {0, 0, 5};
  s.camera.look_at = {0, 0, 0};
  s.materials = {material("d", MaterialType::Diffuse)};
  s.spp = 1;
  std::vector<TriangleMesh> meshes;
  meshes.push_back(make_box({-1, -1, -1}, {1, 1, 1}, 0));
  RenderOptions o = quiet_options();
  o.aov_depth = o.aov_normal = o.aov_triangle_id = true;
  RenderResult r = render_meshes(std::move(meshes), s, o);
  EXPECT_NEAR(*r.depth.at(16, 16), 4.0f, 1e-3f);
  EXPECT_NEAR(r.normal.at(16, 16)[2], 1.0f, 1e-5f);
  EXPECT_LT(r.triangle_id[16 * 33 + 16], 12u);
  EXPECT_EQ(*r.depth.at(0, 0), 0.0f);  // the corner sees the sky
  EXPECT_EQ(r.triangle_id[0], kNoTriangle);
  // Written next to the output as EXR, and read back exactly.
  const auto dir = test_tmp("render-aov");
  auto written = write_aovs(dir / "out.png", r);
  ASSERT_TRUE(written.is_ok()) << written.status().message();
  ASSERT_EQ(written->size(), 3u);
  EXPECT_EQ((*written)[0], dir / "out.depth.exr");
  auto depth = read_image(dir / "out.depth.exr");
  ASSERT_TRUE(depth.is_ok());
  EXPECT_EQ(depth->pixels, r.depth.pixels);
  // Beside an 8-bit image, which `render -o X.png` makes without a linear
  // frame (srgb_color): the triangle ids took that frame's size, 0 x 0, and
  // failed ("triangle id buffer has the wrong size").
  std::vector<TriangleMesh> again;
  again.push_back(make_box({-1, -1, -1}, {1, 1, 1}, 0));
  o.srgb_color = true;
  const RenderResult bytes = render_meshes(std::move(again), s, o);
  ASSERT_TRUE(bytes.color.empty());
  auto beside_png = write_aovs(dir / "png.png", bytes);
  ASSERT_TRUE(beside_png.is_ok()) << beside_png.status().message();
  auto ids = read_image(dir / "png.triangle-id.exr");
  ASSERT_TRUE(ids.is_ok()) << ids.status().message();
  EXPECT_EQ(ids->width, 33);
  EXPECT_EQ(ids->height, 33);
}

// An image and its AOVs are written all or none, and a failed write leaves
// the files of an earlier render of the same names as they were (it
// removed those the failed call had already replaced).
TEST(ImageIo, AFailedAovWriteLeavesEarlierFilesAsTheyWere) {
  const auto dir = test_tmp("render-aov-batch");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  Image earlier(4, 4, 1);
  for (size_t i = 0; i < earlier.pixels.size(); ++i) earlier.pixels[i] = float(i);
  ASSERT_TRUE(write_image(dir / "out.depth.exr", earlier).is_ok());
  Image earlier_color(4, 4, 3);
  ASSERT_TRUE(write_image(dir / "out.exr", earlier_color).is_ok());
  RenderResult r;
  r.stats.width = r.stats.height = 3;
  r.color = Image(3, 3, 3);
  r.depth = Image(3, 3, 1);
  r.normal = Image(3, 3, 3);
  r.triangle_id.assign(5, 0);  // the wrong size: the third AOV's write fails
  {
    ImageBatch batch;
    ASSERT_TRUE(write_color(dir / "out.exr", r, &batch).is_ok());
    auto aovs = write_aovs(dir / "out.exr", r, &batch);
    ASSERT_FALSE(aovs.is_ok());
    EXPECT_NE(aovs.status().message().find("wrong size"), std::string::npos) << aovs.status().message();
  }
  auto depth = read_image(dir / "out.depth.exr");
  ASSERT_TRUE(depth.is_ok());
  EXPECT_EQ(depth->width, 4);
  EXPECT_EQ(depth->pixels, earlier.pixels);
  auto color = read_image(dir / "out.exr");
  ASSERT_TRUE(color.is_ok());
  EXPECT_EQ(color->width, 4);
  EXPECT_FALSE(std::filesystem::exists(dir / "out.normal.exr"));
  // Without a batch of the caller's, the same.
  EXPECT_FALSE(write_aovs(dir / "out.exr", r).is_ok());
  depth = read_image(dir / "out.depth.exr");
  ASSERT_TRUE(depth.is_ok());
  EXPECT_EQ(depth->pixels, earlier.pixels);
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"out.depth.exr", "out.exr"}));
  // Committed, all are replaced.
  r.triangle_id.assign(9, 0);
  ImageBatch batch;
  ASSERT_TRUE(write_color(dir / "out.exr", r, &batch).is_ok());
  ASSERT_TRUE(write_aovs(dir / "out.exr", r, &batch).is_ok());
  depth = read_image(dir / "out.depth.exr");
  ASSERT_TRUE(depth.is_ok());
  EXPECT_EQ(depth->width, 4);  // not yet: the batch has not committed
  ASSERT_TRUE(batch.commit().is_ok());
  depth = read_image(dir / "out.depth.exr");
  ASSERT_TRUE(depth.is_ok());
  EXPECT_EQ(depth->width, 3);
  EXPECT_TRUE(std::filesystem::exists(dir / "out.triangle-id.exr"));
  std::filesystem::remove_all(dir);
}

TEST(ImageIo, PngAndExrRoundTripAndLeaveNoTemporaries) {
  Image img(5, 3, 3);
  for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = float(i) / float(img.pixels.size());
  const auto dir = test_tmp("render-io");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  ASSERT_TRUE(write_image(dir / "a.exr", img).is_ok());
  ASSERT_TRUE(write_image(dir / "a.png", img).is_ok());
  auto exr = read_image(dir / "a.exr");
  auto png = read_image(dir / "a.png");
  ASSERT_TRUE(exr.is_ok() && png.is_ok());
  EXPECT_EQ(exr->pixels, img.pixels);
  for (size_t i = 0; i < img.pixels.size(); ++i) EXPECT_NEAR(png->pixels[i], img.pixels[i], 0.01f);
  size_t files = 0;
  for (auto& e : std::filesystem::directory_iterator(dir)) { (void)e; ++files; }
  EXPECT_EQ(files, 2u);
  EXPECT_FALSE(check_output_image(dir / "a.unknownext").is_ok());
  EXPECT_FALSE(check_output_image(dir / "missing-dir" / "a.png").is_ok());
  EXPECT_TRUE(check_output_image(dir / "b.jpg").is_ok());
}

// --- Scenes from files: loading, transforms, memory limit, errors ---

std::filesystem::path write_file(const std::filesystem::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
  return p;
}

const char* kTetraPly =
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

std::string scene_json(const std::string& mesh, const std::string& extra = "") {
  return R"({"camera": {"eye": [3, 3, 3], "look_at": [0, 0, 0], "width": 16, "height": 12},
             "materials": {"m": {"type": "diffuse"}},
             "objects": [{"mesh": ")" + mesh + R"(", "material": "m",
                          "transform": {"translate": [10, 0, 0], "scale": 2}}],
             "lights": [{"type": "point", "position": [5, 5, 5], "intensity": 20}])" + extra + "}";
}

TEST(SceneFiles, LoadsTransformsAndRenders) {
  const auto dir = test_tmp("render-scenes");
  write_file(dir / "tetra.ply", kTetraPly);
  auto scene = parse_scene(scene_json("tetra.ply"), dir, "test.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  RenderStats stats;
  auto meshes = load_scene_meshes(*scene, quiet_options(), stats);
  ASSERT_TRUE(meshes.is_ok()) << meshes.status().message();
  ASSERT_EQ(meshes->size(), 1u);
  const TriangleMesh& m = (*meshes)[0];
  EXPECT_EQ(m.triangle_count(), 4u);
  // No normals in the file: crease-angle normals; every tetrahedron edge is
  // a crease, so each corner has its own face's normal.
  EXPECT_EQ(m.positions.size(), 12u);
  ASSERT_EQ(m.normals.size(), 12u);
  for (size_t t = 0; t < 4; ++t) {
    const uint32_t* f = &m.indices[3 * t];
    const Vec3d n = face_normal(Vec3d(m.positions[f[0]]), Vec3d(m.positions[f[1]]), Vec3d(m.positions[f[2]]));
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(glm::distance(Vec3d(m.normals[f[k]]), n), 0.0, 1e-6) << "face " << t;
  }
  Bbox b;
  for (const Vec3& p : m.positions) b.expand(p);
  EXPECT_EQ(b.lo, Vec3d(10, 0, 0));
  EXPECT_EQ(b.hi, Vec3d(12, 2, 2));
  auto r = render(*scene, quiet_options());
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  EXPECT_EQ(r->stats.triangles, 4u);
}

TEST(SceneFiles, MirroringTransformKeepsFacesOutward) {
  const auto dir = test_tmp("render-scenes");
  write_file(dir / "tetra.ply", kTetraPly);
  std::string json = scene_json("tetra.ply");
  json.replace(json.find("\"scale\": 2"), 10, "\"scale\": [-1, 1, 1]");
  auto scene = parse_scene(json, dir, "test.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  RenderStats stats;
  auto meshes = load_scene_meshes(*scene, quiet_options(), stats);
  ASSERT_TRUE(meshes.is_ok());
  const TriangleMesh& m = (*meshes)[0];
  Vec3d c(0);
  for (const Vec3& p : m.positions) c += Vec3d(p) / double(m.positions.size());
  for (size_t t = 0; t < 4; ++t) {
    const Vec3d a(m.positions[m.indices[3 * t]]), b(m.positions[m.indices[3 * t + 1]]), d(m.positions[m.indices[3 * t + 2]]);
    EXPECT_GT(glm::dot(glm::cross(b - a, d - a), (a + b + d) / 3.0 - c), 0) << "face " << t;
  }
}

TEST(SceneFiles, MemoryLimitStopsBeforeLoadingAndSaysWhatFits) {
  const auto dir = test_tmp("render-scenes");
  write_file(dir / "tetra.ply", kTetraPly);
  auto scene = parse_scene(scene_json("tetra.ply"), dir, "test.json");
  ASSERT_TRUE(scene.is_ok());
  RenderOptions o = quiet_options();
  o.memory_limit = 1 << 20;
  auto r = render(*scene, o);
  ASSERT_FALSE(r.is_ok());
  const std::string msg = r.status().message();
  EXPECT_NE(msg.find("memory limit"), std::string::npos) << msg;
  EXPECT_NE(msg.find("would fit"), std::string::npos) << msg;
  EXPECT_NE(msg.find("raylod run"), std::string::npos) << msg;
  // The need it states is the least of any layout's (the compact one with the
  // medium builder), and that much is enough.
  BvhConfig tight;
  tight.high_quality_below = 0;
  tight.compact_from = 0;
  tight.camera_rays = 0;
  EXPECT_NE(msg.find("need about " + format_bytes(estimate_render_memory(4, tight))), std::string::npos) << msg;
  // The frame counts too (estimate_image_memory): beside the mesh's need,
  // and alone past the limit it is what the message names.
  const uint64_t image = estimate_image_memory(scene->camera.width, scene->camera.height, o);
  EXPECT_GT(image, 0u);
  o.memory_limit = estimate_render_memory(4, tight) + image;
  EXPECT_TRUE(render(*scene, o).is_ok());
  o.memory_limit = estimate_render_memory(4) + image;
  EXPECT_TRUE(render(*scene, o).is_ok());
  o.memory_limit = image;
  auto frame = render(*scene, o);
  ASSERT_FALSE(frame.is_ok());
  EXPECT_NE(frame.status().message().find("image needs about " + format_bytes(image)), std::string::npos)
      << frame.status().message();
  // The advertised count is consistent with the estimate of the layout the
  // renderer would pick (the compact one where only that fits).
  for (uint64_t budget : {uint64_t(64) << 20, uint64_t(1) << 30, uint64_t(2) << 30, uint64_t(8) << 30}) {
    const uint64_t fit = triangles_that_fit(budget);
    auto need = [&](uint64_t n) { return estimate_render_memory(n, bvh_for_memory_limit(n, budget)); };
    EXPECT_LE(need(fit), budget);
    EXPECT_GT(need(fit + 1), budget);
    for (uint64_t n = fit + 1; n < fit * 4; n += fit / 16 + 1) EXPECT_GT(need(n), budget) << n;
  }
  EXPECT_GE(triangles_that_fit(uint64_t(2) << 30), BvhConfig{}.compact_from);
  // A limit that only the compact layout meets: the render switches to it
  // instead of failing, and says so.
  BvhConfig compact;
  compact.high_quality_below = compact.compact_from = 0;
  o.memory_limit = estimate_render_memory(4, compact) + image;
  ASSERT_LT(o.memory_limit, estimate_render_memory(4) + image);
  std::string said;
  o.log = [&](const std::string& m) { said += m + "\n"; };
  EXPECT_TRUE(render(*scene, o).is_ok());
  EXPECT_NE(said.find("compact BVH layout"), std::string::npos) << said;
}

TEST(SceneFiles, RendersADracoMeshInPlaceOfTheSceneMesh) {
  const auto dir = test_tmp("render-scenes");
  write_file(dir / "tetra.ply", kTetraPly);
  const TriangleMesh sphere = make_sphere({0, 0, 0}, 1, 8, 16, 0);
  IndexedMesh im;
  im.positions = sphere.positions;
  im.normals = sphere.normals;
  im.indices = sphere.indices;
  auto written = write_draco(dir / "sphere.drc", im, DracoOptions{});
  ASSERT_TRUE(written.is_ok()) << written.status().message();
  auto scene = parse_scene(scene_json("tetra.ply"), dir, "test.json");
  ASSERT_TRUE(scene.is_ok());
  RenderOptions o = quiet_options();
  o.mesh_override = {dir / "sphere.drc"};
  auto r = render(*scene, o);
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  EXPECT_EQ(r->stats.triangles, sphere.triangle_count());
}

// A .drc loads indexed as Draco decoded it (no welding); every triangle has
// the corners, in order, that welding the reader's corner soup gives, with
// and without normals, and under a transform.
TEST(SceneFiles, DracoLoadsIndexedWithTheCornersOfTheWeldedSoup) {
  const auto dir = test_tmp("render-scenes");
  const TriangleMesh sphere = make_sphere({0.2f, 0.1f, 0}, 1, 9, 17, 0);
  const glm::dmat4 xf = glm::translate(glm::scale(glm::dmat4(1.0), glm::dvec3(2, 1, 0.5)), glm::dvec3(1, 2, 3));
  for (bool normals : {true, false}) {
    IndexedMesh im;
    im.positions = sphere.positions;
    if (normals) im.normals = sphere.normals;
    im.indices = sphere.indices;
    const auto path = dir / (normals ? "with_normals.drc" : "positions_only.drc");
    ASSERT_TRUE(write_draco(path, im, DracoOptions{}).is_ok());
    auto loaded = load_triangle_mesh(path, xf, 0, 30.0);
    ASSERT_TRUE(loaded.is_ok()) << loaded.status().message();
    // The reference: the reader's soup welded, crease normals, the same transform.
    auto reader = open_mesh(path);
    ASSERT_TRUE(reader.is_ok());
    TriangleBatch all, batch;
    while (reader.value()->next(batch).value()) {
      all.positions.insert(all.positions.end(), batch.positions.begin(), batch.positions.end());
      all.normals.insert(all.normals.end(), batch.normals.begin(), batch.normals.end());
    }
    TriangleMesh ref = weld_triangles(all.positions, all.normals);
    add_crease_normals(ref, 30.0);
    ASSERT_EQ(loaded->triangle_count(), ref.triangle_count());
    ASSERT_EQ(loaded->triangle_count(), sphere.triangle_count());
    ASSERT_FALSE(loaded->normals.empty());
    for (size_t c = 0; c < ref.indices.size(); ++c) {
      const Vec3 want = Vec3(Vec3d(xf * glm::dvec4(Vec3d(ref.positions[ref.indices[c]]), 1.0)));
      ASSERT_EQ(loaded->positions[loaded->indices[c]], want) << "corner " << c;
      const glm::dmat3 nm = glm::transpose(glm::inverse(glm::dmat3(xf)));
      const Vec3 want_n = Vec3(glm::normalize(nm * Vec3d(ref.normals[ref.indices[c]])));
      ASSERT_EQ(loaded->normals[loaded->indices[c]], want_n) << "corner " << c;
    }
  }
}

TEST(SceneFiles, BadMeshesGiveClearErrors) {
  const auto dir = test_tmp("render-scenes");
  std::string truncated = kTetraPly;
  truncated.resize(truncated.size() - 20);
  write_file(dir / "truncated.ply", truncated);
  write_file(dir / "garbage.stl", "this is not an stl file at all");
  for (const char* name : {"truncated.ply", "garbage.stl"}) {
    auto scene = parse_scene(scene_json(name), dir, "test.json");
    ASSERT_TRUE(scene.is_ok()) << scene.status().message();
    auto r = render(*scene, quiet_options());
    ASSERT_FALSE(r.is_ok()) << name;
    EXPECT_NE(r.status().message().find(name), std::string::npos) << r.status().message();
  }
}

TEST(SceneFiles, UnresolvedGeneratedMeshAndTooManyOverridesAreErrors) {
  auto scene = default_scene();
  ASSERT_TRUE(scene.is_ok());
  auto r = render(*scene, quiet_options());
  ASSERT_FALSE(r.is_ok());
  EXPECT_NE(r.status().message().find("teapot"), std::string::npos) << r.status().message();
  RenderOptions o = quiet_options();
  o.mesh_override = {"a.ply", "b.ply"};
  auto r2 = render(*scene, o);
  ASSERT_FALSE(r2.is_ok());
  EXPECT_NE(r2.status().message().find("replacement"), std::string::npos) << r2.status().message();
}

TEST(SceneFiles, MeshOverrideReplacesTheObjectMesh) {
  const auto dir = test_tmp("render-scenes");
  write_file(dir / "tetra.ply", kTetraPly);
  auto scene = default_scene();
  ASSERT_TRUE(scene.is_ok());
  scene->camera.width = 8;
  scene->camera.height = 6;
  RenderOptions o = quiet_options();
  o.mesh_override = {dir / "tetra.ply"};
  auto r = render(*scene, o);
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  EXPECT_EQ(r->stats.triangles, 4u + 2u);  // plus the ground
}

}  // namespace
}  // namespace raylod
