// Packet tracing (EmbreeScene::intersect_packet / occluded_packet and
// Integrator::trace_camera_packet / shade_camera_packet, pipelined by the
// renderer) against the single-ray path: the same hits, the same image bytes,
// for any thread count and for tiles that are not whole packets.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstring>
#include <random>

#include <tbb/task_arena.h>

#include "render/integrator.h"
#include "render/renderer.h"
#include "render_test_util.h"

namespace raylod {
namespace {

using namespace raylod::testing;
constexpr double kInf = std::numeric_limits<double>::infinity();

// A diffuse sphere beside a mirror box on a glossy floor, two lights.
Scene mirror_scene(int width, int height) {
  return sphere_box_scene(width, height, material("ball", MaterialType::Diffuse, Vec3(0.7f, 0.3f, 0.2f)));
}

RenderOptions all_aovs(bool packets) {
  RenderOptions o = quiet_options();
  o.aov_depth = o.aov_normal = o.aov_triangle_id = true;
  o.camera_packets = packets;
  return o;
}

void expect_same_bytes(const Image& a, const Image& b, const char* what) {
  ASSERT_EQ(a.pixels.size(), b.pixels.size()) << what;
  EXPECT_EQ(0, std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(float))) << what;
}

void expect_same_render(const RenderResult& a, const RenderResult& b) {
  expect_same_bytes(a.color, b.color, "colour");
  expect_same_bytes(a.depth, b.depth, "depth");
  expect_same_bytes(a.normal, b.normal, "normal");
  EXPECT_EQ(a.triangle_id, b.triangle_id);
  EXPECT_EQ(a.stats.rays.camera, b.stats.rays.camera);
  EXPECT_EQ(a.stats.rays.shadow, b.stats.rays.shadow);
  EXPECT_EQ(a.stats.rays.reflection, b.stats.rays.reflection);
}

TEST(PacketTraversal, SameHitsAndOcclusionAsSingleRays) {
  const Scene s = mirror_scene(64, 48);
  auto geometry = EmbreeScene::build(sphere_box_meshes(s));
  ASSERT_TRUE(geometry.is_ok()) << geometry.status().message();
  const EmbreeScene& g = **geometry;
  // Seeded random rays: camera-like packets from one eye, and scattered
  // shadow-like rays with per-lane lengths, some of whose lanes are inactive.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  int hits = 0, blocked = 0;
  for (int packet = 0; packet < 200; ++packet) {
    const size_t n = 1 + size_t(packet % EmbreeScene::kPacketSize);
    std::vector<Ray> rays(n);
    double tfar[EmbreeScene::kPacketSize];
    for (size_t i = 0; i < n; ++i) {
      const Vec3d origin = packet % 2 ? s.camera.eye : Vec3d(2 * u(rng), 1 + u(rng), 2 * u(rng));
      const Vec3d target(1.5 * u(rng), 0.8 + u(rng), 1.5 * u(rng));
      rays[i] = Ray{origin, glm::normalize(target - origin)};
      tfar[i] = packet % 3 ? 1.5 + u(rng) : kInf;
    }
    Hit packet_hits[EmbreeScene::kPacketSize];
    bool found[EmbreeScene::kPacketSize], occluded[EmbreeScene::kPacketSize];
    g.intersect_packet(rays, kInf, packet % 2 == 1, packet_hits, found);
    g.occluded_packet(rays, tfar, occluded);
    for (size_t i = 0; i < n; ++i) {
      Hit single;
      ASSERT_EQ(found[i], g.intersect(rays[i], 0.0, kInf, single)) << "packet " << packet << " lane " << i;
      EXPECT_EQ(occluded[i], g.occluded(rays[i], 0.0, tfar[i])) << "packet " << packet << " lane " << i;
      blocked += occluded[i];
      if (!found[i]) continue;
      ++hits;
      // Bit for bit: shading reads u and v, the depth AOV reads t.
      EXPECT_EQ(packet_hits[i].geom, single.geom);
      EXPECT_EQ(packet_hits[i].prim, single.prim);
      EXPECT_EQ(std::bit_cast<uint64_t>(packet_hits[i].t), std::bit_cast<uint64_t>(single.t));
      EXPECT_EQ(std::bit_cast<uint32_t>(packet_hits[i].u), std::bit_cast<uint32_t>(single.u));
      EXPECT_EQ(std::bit_cast<uint32_t>(packet_hits[i].v), std::bit_cast<uint32_t>(single.v));
    }
  }
  EXPECT_GT(hits, 500);
  EXPECT_GT(blocked, 100);
}

// Distance from p to segment ab, by brute force (the closest point's parameter).
double segment_distance(const Vec3d& p, const Vec3d& a, const Vec3d& b) {
  const Vec3d ab = b - a;
  const double t = std::clamp(glm::dot(p - a, ab) / glm::dot(ab, ab), 0.0, 1.0);
  return glm::length(p - (a + t * ab));
}

TEST(SurfacePoints, EveryLaneAsAlone_AndAsTheTriangleSays) {
  // Hits on the sphere (vertex normals) and the box and ground (face normals
  // only), 16 to a packet with some lanes missing: surface_points gives each
  // found lane exactly surface_point's bits, and those agree with the
  // triangle computed here from its corners.
  const Scene s = mirror_scene(64, 48);
  auto geometry = EmbreeScene::build(sphere_box_meshes(s));
  ASSERT_TRUE(geometry.is_ok()) << geometry.status().message();
  const EmbreeScene& g = **geometry;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  int checked = 0, skipped = 0;
  for (int packet = 0; packet < 100; ++packet) {
    const size_t n = 1 + size_t(packet % EmbreeScene::kPacketSize);
    std::vector<Ray> rays(n);
    for (size_t i = 0; i < n; ++i) {
      const Vec3d target(1.8 * u(rng), 0.8 + u(rng), 1.8 * u(rng));
      rays[i] = Ray{s.camera.eye, glm::normalize(target - s.camera.eye)};
    }
    Hit hits[EmbreeScene::kPacketSize];
    bool found[EmbreeScene::kPacketSize];
    g.intersect_packet(rays, kInf, true, hits, found);
    for (const bool edges : {false, true}) {
      SurfacePoint batch[EmbreeScene::kPacketSize];
      surface_points(g, {hits, n}, found, edges, batch);
      for (size_t i = 0; i < n; ++i) {
        if (!found[i]) { ++skipped; continue; }
        const SurfacePoint one = surface_point(g, hits[i], edges);
        EXPECT_EQ(0, std::memcmp(&one, &batch[i], sizeof(SurfacePoint))) << "packet " << packet << " lane " << i;
        const TriangleMesh& m = g.mesh(hits[i].geom);
        const uint32_t* tri = &m.indices[size_t(hits[i].prim) * 3];
        const Vec3d a(m.positions[tri[0]]), b(m.positions[tri[1]]), c(m.positions[tri[2]]);
        const double bu = hits[i].u, bv = hits[i].v;
        const Vec3d p = (1 - bu - bv) * a + bu * b + bv * c;
        EXPECT_LT(glm::length(batch[i].position - p), 1e-12);
        EXPECT_LT(glm::length(batch[i].position - rays[i].at(hits[i].t)), 1e-5);
        const Vec3d face = glm::normalize(glm::cross(b - a, c - a));
        EXPECT_NEAR(std::abs(glm::dot(batch[i].geometric, face)), 1.0, 1e-12);
        EXPECT_NEAR(glm::length(batch[i].shading), 1.0, 1e-12);
        EXPECT_GT(glm::dot(batch[i].geometric, batch[i].shading), 0.0);
        if (edges) {
          const double d = std::min({segment_distance(p, a, b), segment_distance(p, b, c), segment_distance(p, c, a)});
          EXPECT_NEAR(batch[i].edge_distance, d, 1e-9) << "packet " << packet << " lane " << i;
        }
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 1000);
  EXPECT_GT(skipped, 50);
}

TEST(Packets, SameImageAsSingleRaysWithDiffuseShadowsAndMirror) {
  const Scene s = mirror_scene(48, 36);
  auto geometry = EmbreeScene::build(sphere_box_meshes(s));
  ASSERT_TRUE(geometry.is_ok()) << geometry.status().message();
  const RenderResult packets = render_embree_scene(**geometry, s, all_aovs(true));
  const RenderResult single = render_embree_scene(**geometry, s, all_aovs(false));
  EXPECT_GT(single.stats.rays.shadow, 0u);
  EXPECT_GT(single.stats.rays.reflection, 0u);
  expect_same_render(packets, single);
}

TEST(Packets, SameImageForOneAndTwoThreadsAndForTheSingleRayPath) {
  const Scene s = mirror_scene(40, 28);
  auto geometry = EmbreeScene::build(sphere_box_meshes(s));
  ASSERT_TRUE(geometry.is_ok()) << geometry.status().message();
  auto render_with = [&](int threads, bool packets) {
    RenderOptions o = all_aovs(packets);
    o.tile_size = 8;
    RenderResult r;
    tbb::task_arena(threads).execute([&] { r = render_embree_scene(**geometry, s, o); });
    return r;
  };
  const RenderResult one = render_with(1, true), two = render_with(2, true);
  expect_same_render(one, two);
  expect_same_render(two, render_with(2, false));
}

TEST(Packets, TilesThatAreNotWholePacketsRenderEveryPixel) {
  // 37 x 23 pixels in tiles of 7: every tile edge cuts 4x4 blocks. The camera
  // looks straight down at the ground, so every pixel sees it.
  Scene s = base_scene(37, 23);
  s.spp = 3;  // strata 1 x 3 (or 3 x 1): samples per pixel not a square either
  s.camera.eye = {0, 5, 0.01};
  s.camera.look_at = {0, 0, 0};
  s.materials = {material("floor", MaterialType::Diffuse)};
  s.lights = {point_light({1, 4, 1}, 20)};
  auto geometry = EmbreeScene::build({make_ground_mesh(Ground{0, 50, 0}, s.camera)});
  ASSERT_TRUE(geometry.is_ok()) << geometry.status().message();
  RenderOptions o = all_aovs(true);
  o.tile_size = 7;
  const RenderResult r = render_embree_scene(**geometry, s, o);
  EXPECT_EQ(r.stats.rays.camera, uint64_t(37 * 23 * 3));
  for (int y = 0; y < 23; ++y)
    for (int x = 0; x < 37; ++x) {
      EXPECT_NE(r.triangle_id[size_t(y) * 37 + x], kNoTriangle) << x << "," << y;
      EXPECT_GT(r.color.at(x, y)[0], 0.0f) << x << "," << y;
    }
  o.camera_packets = false;
  expect_same_render(r, render_embree_scene(**geometry, s, o));
}

}  // namespace
}  // namespace raylod
