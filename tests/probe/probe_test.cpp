// The probe end to end on small stores built with build_store: the store
// tracer against brute force, the page cache bound, the cut file format, the
// effects a scene calls for (counters), hard camera set-ups, a corrupt page,
// thread-count determinism and the properties of the cut.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <optional>
#include <set>
#include <tuple>

#include <sys/resource.h>
#include <unistd.h>

#include <glm/gtc/matrix_transform.hpp>
#include <tbb/task_arena.h>

#include "core/system.h"
#include "gen/generate.h"
#include "geometry/collapse_deviation.h"
#include "geometry/optics.h"
#include "probe/bvh.h"
#include "probe/probe.h"
#include "probe/store_tracer.h"
#include "scene/scene_camera.h"
#include "streaming/cut_file.h"
#include "streaming/mesh_writer.h"
#include "streaming/octree_store.h"
#include "cut_grading_check.h"
#include "one_object_scene.h"
#include "test_scenes.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// Per process (ctest runs the cases in parallel processes), removed at exit.
fs::path tmp_dir() { return test::scratch_dir("probe"); }

fs::path write_ply(const test::TestMesh& m, const std::string& name) {
  const fs::path path = tmp_dir() / name;
  TriangleBatch batch;
  for (size_t i = 0; i < m.p.size(); ++i) {
    batch.positions.push_back(Vec3(m.p[i]));
    batch.normals.push_back(Vec3(m.n[i]));
  }
  auto w = create_mesh_writer(path);
  EXPECT_TRUE(w) << w.status().message();
  EXPECT_TRUE(w.value()->write(batch));
  EXPECT_TRUE(w.value()->finish());
  return path;
}

struct Built {
  fs::path mesh, store_path;
  std::unique_ptr<OctreeStore> store;
  test::TestMesh soup;  // the triangles as the store holds them (float)
};

// A small teapot (~20k triangles) or sphere, stored with small pages.
Built build(const std::string& name, const test::TestMesh& mesh) {
  Built b;
  b.mesh = write_ply(mesh, name + ".ply");
  b.store_path = tmp_dir() / (name + ".raylod");
  StoreOptions o;
  o.memory_limit = uint64_t(256) << 20;
  o.max_depth = 8;
  o.page_triangles = 512;
  auto r = build_store(b.mesh, b.store_path, o);
  EXPECT_TRUE(r) << r.status().message();
  auto s = OctreeStore::open(b.store_path);
  EXPECT_TRUE(s) << s.status().message();
  b.store = std::move(s.value());
  // The pages as decoded (quantised positions, octahedral normals), in page order.
  TriangleBatch page;
  for (size_t i = 0; i < b.store->pages().size(); ++i) {
    EXPECT_TRUE(b.store->read_page(i, page).is_ok());
    for (size_t k = 0; k < page.positions.size(); ++k) {
      b.soup.p.push_back(Vec3d(page.positions[k]));
      b.soup.n.push_back(Vec3d(page.normals[k]));
    }
  }
  EXPECT_EQ(b.soup.size(), mesh.size());
  return b;
}

const Built& teapot() {
  static Built b = [] {
    auto surface = make_generated_surface("teapot", 20000);
    EXPECT_TRUE(surface);
    return build("teapot20k", test::mesh_from_surface(*surface.value(), 1.0, Vec3d(0)));
  }();
  return b;
}

Scene make_scene(MaterialType type, const Vec3d& eye, const Vec3d& look_at, bool ground = true, bool lights = true) {
  Scene s = test::one_object_scene(type, eye, look_at, 320, 240, 40, ground, lights);
  s.max_depth = 5;
  return s;
}

// The one store of a test as one object (material 0; the identity transform
// unless given), as the spans the probe takes.
struct OneObject {
  ProbeStore store;
  ProbeObject object;
  explicit OneObject(const Built& b, const glm::dmat4& xf = glm::dmat4(1.0))
      : store{b.store.get(), b.store_path}, object{0, xf, 0} {}
  std::span<const ProbeStore> stores() const { return {&store, 1}; }
  std::span<const ProbeObject> objects() const { return {&object, 1}; }
};

// The probe with config `c` in a task arena of `threads`: the probe uses the
// parallelism of the arena it is called in (core/parallelism.h).
StatusOr<ProbeResult> probe_with_config(const Scene& scene, const Built& b, const ProbeConfig& c, int threads = 2) {
  const OneObject one(b);
  StatusOr<ProbeResult> result = Status::error("not run");
  tbb::task_arena(threads).execute([&] { result = run_probe(scene, one.stores(), one.objects(), c); });
  return result;
}

StatusOr<ProbeResult> probe(const Scene& scene, const Built& b, uint64_t rays, int threads = 2, double k = 1.0,
                            uint64_t cache = uint64_t(64) << 20) {
  ProbeConfig c;
  c.rays = rays;
  c.seed = 7;
  c.footprint_scale = k;
  c.cache_bytes = cache;
  return probe_with_config(scene, b, c, threads);
}

const Vec3d kEye(6.5, 4.8, 8.5), kLook(0.2, 1.3, 0.0);

TEST(StoreTracer, MatchesBruteForce) {
  const Built& b = teapot();
  ASSERT_GT(b.store->pages().size(), 8u);
  PageCache cache(uint64_t(64) << 20);
  StoreTracer tracer(*b.store, cache);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1, 1);
  const test::Scene3 scene{test::Prim{test::Prim::Mesh, Vec3d(0), Vec3d(0), 1, test::Mat::Diffuse, 1.5, &b.soup}};
  int hits = 0;
  for (int i = 0; i < 300; ++i) {
    // Half from outside, half from inside the bounds.
    const Vec3d o = i % 2 ? Vec3d(6 * u(rng), 3 + 4 * u(rng), 6 * u(rng)) : Vec3d(1.5 * u(rng), 1.5 + u(rng), 1.5 * u(rng));
    const Vec3d target(2 * u(rng), 1.5 + 1.2 * u(rng), 1.5 * u(rng));
    const Vec3d d = glm::normalize(target - o);
    TriangleHit h;
    TraceCounters tc;
    ASSERT_TRUE(tracer.intersect(o, d, 0, 1e30, {}, h, &tc));
    const test::TestHit ref = test::intersect(scene, o, d, 0, -1, -1);
    ASSERT_EQ(h.found(), ref.found()) << "ray " << i;
    if (!ref.found()) continue;
    ++hits;
    EXPECT_NEAR(h.t, ref.t, 1e-12 * (1 + ref.t));
    const Vec3d p = o + h.t * d;
    EXPECT_LT(glm::length(p - ref.s.point), 1e-9);
    EXPECT_LT(tc.page_visits, b.store->pages().size());  // front to back: not every page
  }
  EXPECT_GT(hits, 100);
}

// A box is closed: a ray parallel to one axis that runs in the plane of the
// box's hi face enters it, as one in the plane of its lo face does. The huge
// inverse that stands in for a zero direction read (hi - o) * inv = 0 as
// leaving the slab at t = 0, so the ray grazing a vertical triangle's top
// edge missed its tight box while it hit the triangle (found by a review).
TEST(Bvh, ARayInThePlaneOfABoxFaceEntersIt) {
  const Vec3d a(0, 0, -1), b(0, 1, -1), c(0, 1, 1);
  Bbox box;
  box.expand(a);
  box.expand(b);
  box.expand(c);
  for (double y : {1.0, 0.0}) {  // the hi face's plane, then the lo face's
    const Vec3d o(-1, y, 0), d(1, 0, 0);
    for (double tmin : {0.0, 1e-9}) {
      double t, b1, b2, tn;
      if (y == 1.0) {  // on the edge b c
        EXPECT_TRUE(intersect_triangle(o, d, a, b, c, tmin, 1e30, t, b1, b2));
      }
      EXPECT_TRUE(intersect_box(box, ray_box_precomp(o, d), tmin, 1e30, tn)) << "y " << y << ", tmin " << tmin;
      EXPECT_NEAR(tn, 1.0, 1e-12);
    }
    // Just outside the slab: missed.
    double tn;
    EXPECT_FALSE(intersect_box(box, ray_box_precomp(Vec3d(-1, y + (y > 0 ? 1e-12 : -1e-12), 0), d), 0, 1e30, tn));
  }
}

TEST(Bvh, ReusedArraysGiveTheFreshBuild) {
  // build_bvh into a Bvh and scratch that held a larger and then a smaller
  // tree gives exactly the tree a fresh build gives.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-5, 5);
  auto boxes_of = [&](size_t n) {
    std::vector<Bbox> boxes(n);
    for (Bbox& b : boxes) {
      const Vec3d c(u(rng), u(rng), u(rng));
      b.expand(c);
      b.expand(c + Vec3d(0.1 + 0.01 * u(rng), 0.2, 0.05));
    }
    return boxes;
  };
  Bvh reused;
  BvhScratch scratch;
  for (size_t n : {3000u, 17u, 700u, 1u, 0u, 250u}) {
    const std::vector<Bbox> boxes = boxes_of(n);
    const Bvh fresh = build_bvh(boxes, 8);
    build_bvh(boxes, 8, reused, scratch);
    ASSERT_EQ(reused.order, fresh.order) << n;
    ASSERT_EQ(reused.nodes.size(), fresh.nodes.size()) << n;
    for (size_t i = 0; i < fresh.nodes.size(); ++i) {
      EXPECT_EQ(reused.nodes[i].first, fresh.nodes[i].first);
      EXPECT_EQ(reused.nodes[i].count, fresh.nodes[i].count);
      EXPECT_EQ(reused.nodes[i].box.lo, fresh.nodes[i].box.lo);
      EXPECT_EQ(reused.nodes[i].box.hi, fresh.nodes[i].box.hi);
    }
    for (uint32_t i = 0; i < n; ++i)  // every item once
      EXPECT_EQ(std::count(fresh.order.begin(), fresh.order.end(), i), 1);
  }
}

TEST(PageCache, BoundedCacheGivesSameHits) {
  const Built& b = teapot();
  PageCache big(uint64_t(1) << 30), tiny(1);
  StoreTracer t1(*b.store, big), t2(*b.store, tiny);
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 200; ++i) {
    const Vec3d o(6 * u(rng), 4 + 2 * u(rng), 6 * u(rng));
    const Vec3d d = glm::normalize(Vec3d(u(rng), 1.5 + u(rng), u(rng)) - o);
    TriangleHit h1, h2;
    ASSERT_TRUE(t1.intersect(o, d, 0, 1e30, {}, h1));
    ASSERT_TRUE(t2.intersect(o, d, 0, 1e30, {}, h2));
    EXPECT_EQ(h1.found(), h2.found());
    EXPECT_EQ(h1.t, h2.t);
    EXPECT_EQ(h1.ref, h2.ref);
  }
  const PageCacheCounters cb = big.counters(), ct = tiny.counters();
  EXPECT_EQ(cb.evictions, 0u);
  EXPECT_GT(ct.evictions, 0u);
  EXPECT_GT(ct.pages_read, cb.pages_read);
  EXPECT_EQ(cb.pages_read, cb.misses);
  EXPECT_GT(cb.hits, 0u);
  // The tiny cache keeps one page at a time.
  EXPECT_LT(ct.resident_bytes, cb.peak_bytes);
}

TEST(CutFile, RoundTripAndCorruption) {
  Cut cut;
  cut.store_hash = 0x1234;
  cut.store_path = "/x/teapot.ply.raylod";
  cut.key = "abcdef0123456789";
  cut.rays = 5000;
  cut.seed = 3;
  cut.footprint_scale = 0.5;
  cut.min_footprint = 0.25f;
  cut.counters = {{"hits", 10}, {"rays_primary", 5000}};
  cut.cells = {{CellKey{2, 5}, 0.5f, 3}, {CellKey{3, 7}, 0.0f, 0}, {CellKey{3, 0x1ff}, 1.0f, 1}};
  const fs::path path = tmp_dir() / "round.cut";
  ASSERT_TRUE(write_cut(path, cut));
  EXPECT_TRUE(is_cut_file(path));
  auto back = read_cut(path);
  ASSERT_TRUE(back) << back.status().message();
  EXPECT_EQ(back->store_hash, cut.store_hash);
  EXPECT_EQ(back->store_path, cut.store_path);
  EXPECT_EQ(back->key, cut.key);
  EXPECT_EQ(back->counters, cut.counters);
  ASSERT_EQ(back->cells.size(), 3u);
  EXPECT_EQ(back->cells[2].key, (CellKey{3, 0x1ff}));
  EXPECT_EQ(back->cells[0].hits, 3u);
  EXPECT_EQ(back->footprint_scale, 0.5);

  std::string bytes;
  {
    std::ifstream f(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), {});
  }
  auto write_bytes = [&](const std::string& b) {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(b.data(), std::streamsize(b.size()));
  };
  std::string flipped = bytes;
  flipped[bytes.size() - 3] ^= 0x40;
  write_bytes(flipped);
  auto bad = read_cut(path);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("checksum"), std::string::npos) << bad.status().message();
  write_bytes(bytes.substr(0, bytes.size() - 5));
  bad = read_cut(path);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("truncated"), std::string::npos) << bad.status().message();
  write_bytes("not a cut file at all, just text");
  EXPECT_FALSE(is_cut_file(path));
  EXPECT_FALSE(read_cut(path));

  // A cell inside another marked cell is not a cut.
  cut.cells = {{CellKey{2, 5}, 0, 0}, {CellKey{3, 5 * 8 + 1}, 0, 0}};
  ASSERT_TRUE(write_cut(path, cut));
  bad = read_cut(path);
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("inside another"), std::string::npos) << bad.status().message();
}

// Found by tests/fuzz/fuzz_cut: a header claiming a 1 GiB payload made
// read_cut allocate (and zero) 1 GiB before finding that the file is 40 bytes.
TEST(CutFile, PayloadSizeBeyondTheFileIsRejectedBeforeAllocating) {
  Cut cut;
  cut.cells = {{CellKey{1, 3}, 0.5f, 1}};
  const fs::path path = tmp_dir() / "huge-claim.cut";
  ASSERT_TRUE(write_cut(path, cut));
  std::string bytes;
  {
    std::ifstream f(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), {});
  }
  const uint64_t claimed = uint64_t(1) << 30;
  ASSERT_GE(bytes.size(), 24u);
  std::memcpy(bytes.data() + 16, &claimed, 8);  // the payload size field
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), std::streamsize(bytes.size()));
  }
  // Each test runs in its own process, so the peak RSS before is this test's small start.
  auto peak_mib = [] {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_maxrss / 1024;  // KiB on Linux
  };
  const long before = peak_mib();
  auto bad = read_cut(path);
  const long grown = peak_mib() - before;
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.status().message().find("truncated"), std::string::npos) << bad.status().message();
  EXPECT_LT(grown, 256) << "read_cut touched " << grown << " MiB for a " << bytes.size() << "-byte file";
}

TEST(Probe, DiffuseSceneTracesNoSecondaryRays) {
  auto r = probe(make_scene(MaterialType::Diffuse, kEye, kLook), teapot(), 2000);
  ASSERT_TRUE(r) << r.status().message();
  EXPECT_EQ(r->counters.at("rays_primary"), 2000u);
  EXPECT_EQ(r->counters.at("rays_reflection"), 0u);
  EXPECT_EQ(r->counters.at("rays_refraction"), 0u);
  EXPECT_GT(r->counters.at("hits"), 200u);
  EXPECT_GT(r->counters.at("hits_ground"), 200u);
  EXPECT_EQ(r->magnification, 1.0);
  // Glossy is not specular either.
  auto g = probe(make_scene(MaterialType::Glossy, kEye, kLook), teapot(), 500);
  ASSERT_TRUE(g);
  EXPECT_EQ(g->counters.at("rays_reflection") + g->counters.at("rays_refraction"), 0u);
}

TEST(Probe, MirrorSceneReflectsOnly) {
  auto r = probe(make_scene(MaterialType::Mirror, kEye, kLook), teapot(), 1000);
  ASSERT_TRUE(r) << r.status().message();
  EXPECT_GT(r->counters.at("rays_reflection"), 100u);
  EXPECT_EQ(r->counters.at("rays_refraction"), 0u);
}

TEST(Probe, GlassSceneRefractsAndHandlesTir) {
  auto r = probe(make_scene(MaterialType::Glass, kEye, kLook), teapot(), 1000);
  ASSERT_TRUE(r) << r.status().message();
  EXPECT_GT(r->counters.at("rays_refraction"), 100u);
  EXPECT_GT(r->counters.at("rays_reflection"), 100u);
  EXPECT_GT(r->counters.at("total_internal_reflections"), 0u);
  EXPECT_LE(r->magnification, 1.0);
  EXPECT_GT(r->magnification, 0.0);
  // Secondary rays per test ray are bounded by the max depth (a binary tree of depth 5).
  const uint64_t all = r->counters.at("rays_primary") + r->counters.at("rays_reflection") + r->counters.at("rays_refraction");
  EXPECT_LE(all, 1000u * 63u);
}

// Per hit of a trace, how many mesh hits its path met before it (0 for a
// camera ray's hit): parents come before their children.
std::vector<int> hits_before(const ProbeTrace& t) {
  std::vector<int> n(t.hits.size(), 0);
  for (size_t i = 0; i < t.hits.size(); ++i)
    if (t.hits[i].parent >= 0) n[i] = n[size_t(t.hits[i].parent)] + 1;
  return n;
}

// On a mirror a tilt t turns the reflected ray by 2t, which must stay under
// the narrowest beam along the rest of its path: a hit's tilt is at most
// that of each hit its rays lead to, and the path links point backwards.
TEST(Probe, MirrorTiltIsHalfTheNarrowestBeamAlongThePath) {
  const Built& b = teapot();
  const OneObject one(b);
  ProbeConfig c;
  c.rays = 4000;
  c.seed = 7;
  auto t = trace_probe(make_scene(MaterialType::Mirror, kEye, kLook), one.stores(), one.objects(), c);
  ASSERT_TRUE(t) << t.status().message();
  size_t linked = 0, lowered = 0;
  const std::vector<int> depth = hits_before(*t);
  for (size_t i = 0; i < t->hits.size(); ++i) {
    const ProbeHit& h = t->hits[i];
    // At the depth limit no ray leaves (the renderer traces none either).
    if (depth[i] < 5) EXPECT_TRUE(std::isfinite(h.tilt) && h.tilt > 0) << "hit " << i;
    else EXPECT_TRUE(std::isinf(h.tilt)) << "hit " << i;
    if (h.parent < 0) continue;
    ASSERT_LT(size_t(h.parent), i);
    const ProbeHit& p = t->hits[size_t(h.parent)];
    ++linked;
    EXPECT_LE(p.tilt, h.tilt) << "hit " << i << " of parent " << h.parent;
    lowered += p.tilt == h.tilt;
  }
  // The teapot reflects itself (spout, handle, lid).
  EXPECT_GT(linked, 20u);
  // Somewhere a later surface narrows the beam, so the minimum is inherited.
  EXPECT_GT(lowered, 0u);
}

// The probe follows the rays the renderer traces (throughput at least
// kMinThroughput, render/integrator.cpp): a mirror too dark to show leaves
// no reflected ray and no normal bound; a mirror of reflectance 1/2 gives
// the same hits and tilts as one of reflectance 1 (its paths keep a
// throughput of at least 1/2^5 within the depth limit of 5), and one of 1/4
// loses just the rays that would be a fifth reflection in a row.
TEST(Probe, ProbeFollowsTheRaysTheRendererTraces) {
  const Built& b = teapot();
  const OneObject one(b);
  ProbeConfig c;
  c.rays = 2000;
  c.seed = 7;
  Scene full = make_scene(MaterialType::Mirror, kEye, kLook);
  Scene half = full, quarter = full, dark = full;
  half.materials[0].reflectance = 0.5f;
  quarter.materials[0].reflectance = 0.25f;
  dark.materials[0].reflectance = 0.5f * kMinThroughput;
  auto a = trace_probe(full, one.stores(), one.objects(), c);
  auto h = trace_probe(half, one.stores(), one.objects(), c);
  auto q = trace_probe(quarter, one.stores(), one.objects(), c);
  auto d = trace_probe(dark, one.stores(), one.objects(), c);
  ASSERT_TRUE(a && h && q && d);
  EXPECT_GT(a->counters.at("rays_reflection"), 100u);
  EXPECT_EQ(h->counters.at("rays_reflection"), a->counters.at("rays_reflection"));
  ASSERT_EQ(h->hits.size(), a->hits.size());
  for (size_t i = 0; i < a->hits.size(); ++i) EXPECT_EQ(h->hits[i].tilt, a->hits[i].tilt) << "hit " << i;
  // Fifth reflections in a row: those of the full mirror's hits with four
  // mesh hits above them.
  const std::vector<int> before = hits_before(*a);
  const uint64_t fifth = uint64_t(std::count(before.begin(), before.end(), 4));
  EXPECT_EQ(q->counters.at("rays_reflection") + fifth, a->counters.at("rays_reflection"));
  EXPECT_EQ(d->counters.at("rays_reflection"), 0u);
  EXPECT_EQ(d->counters.at("rays_pruned"), d->hits.size());  // each camera ray hit's reflection
  EXPECT_EQ(q->counters.at("rays_pruned"), fifth);
  EXPECT_EQ(a->counters.at("rays_pruned"), 0u);
  for (const ProbeHit& x : d->hits) {
    EXPECT_LT(x.parent, 0);
    EXPECT_TRUE(std::isinf(x.tilt));
  }
  // The key tells the materials apart: a cached cut is not reused for another.
  EXPECT_NE(probe_key(full, *b.store, one.objects(), 0, c), probe_key(half, *b.store, one.objects(), 0, c));
}

// An object outside the view whose shadow falls in it (the camera looks down
// at the ground beside the teapot, a low light casts the teapot's shadow
// there): a deviation d at the object moves the shadow's edge by d /
// sin(elevation), so every cell whose ground shadow is in view and reaches
// ground the light lights stays finer than K times the pixel footprint at
// that shadow times sin(elevation) (probe.h, "Shadows on the ground";
// which ground is lit found here by brute force against the triangles).
// Before, such cells took the lenient shadow_factor (4) times the pinhole
// bound at the cell, and the shadow's outline moved by about a pixel (6.7 dB
// below the noise floor on a CAD part). A cell whose shadow falls only
// inside the shadow of other parts moves no shadow's edge: some are left
// coarser than that.
TEST(Probe, CellsWhoseShadowIsInViewAreAsFineAsTheShadowNeeds) {
  const Built& b = teapot();
  Scene scene = make_scene(MaterialType::Diffuse, Vec3d(8, 4, 0), Vec3d(8, 0, 0.01));
  scene.camera.up = Vec3d(0, 0, -1);
  const Vec3d light_dir = glm::normalize(Vec3d(1, -0.35, 0));
  Light sun;
  sun.type = LightType::Directional;
  sun.direction = light_dir;
  scene.lights = {sun};
  const double K = 64.0;  // the default: the deviation bound decides, K caps
  auto lit = probe(scene, b, 1000, 2, K);
  scene.lights.clear();
  auto dark = probe(scene, b, 1000, 2, K);
  ASSERT_TRUE(lit && dark);
  const PinholeCamera cam = make_pinhole_camera(scene.camera);
  double a_min = 1e30;
  for (double px : {0.0, 0.5 * cam.width, double(cam.width)})
    for (double py : {0.0, 0.5 * cam.height, double(cam.height)}) {
      const RayDerivatives d = cam.derivatives(px, py);
      a_min = std::min({a_min, glm::length(d.dd_dx), glm::length(d.dd_dy)});
    }
  const double sin_elevation = -light_dir.y;
  // The view's footprint on the ground, brute force: where the corner rays
  // meet y = 0 (the camera looks straight down, so the view is that box).
  Bbox view;
  for (double px : {0.0, double(cam.width)})
    for (double py : {0.0, double(cam.height)}) {
      const Ray r = cam.generate(px, py);
      view.expand(r.origin + (-r.origin.y / r.direction.y) * r.direction);
    }
  // Ground points of the view the light reaches past the teapot, brute
  // force on a grid.
  std::vector<Vec3d> lit_ground;
  const test::TestMesh& soup = b.soup;
  const test::Scene3 teapot_only{test::Prim{test::Prim::Mesh, Vec3d(0), Vec3d(0, 1, 0), 1, test::Mat::Diffuse, 1.5, &soup}};
  constexpr int kGrid = 32;
  for (int i = 0; i < kGrid; ++i)
    for (int j = 0; j < kGrid; ++j) {
      const Vec3d p(view.lo.x + (i + 0.5) / kGrid * view.extent().x, 0, view.lo.z + (j + 0.5) / kGrid * view.extent().z);
      if (!test::intersect(teapot_only, p, -light_dir, 1e-9, -1, -1).found()) lit_ground.push_back(p);
    }
  ASSERT_FALSE(lit_ground.empty());
  ASSERT_LT(lit_ground.size(), size_t(kGrid * kGrid));  // the teapot's shadow is in view
  // Per finest cell (the probe's need is theirs, the minimum over them
  // above): its shadow; if that is in view and covers lit ground, its
  // collapsed ancestor (if any) must be finer than K times the footprint
  // there.
  const Cut& cut = lit->cuts[0];
  std::set<CellKey> collapsed;
  for (const CollapsedCell& c : cut.cells) {
    EXPECT_EQ(c.hits, 0u);  // no test ray reaches the teapot
    collapsed.insert(c.key);
  }
  const int Q = b.store->header().quadric_depth;
  // The probe knows the ground its test rays met: the view's inner 80%,
  // clear of the sparse border, is sure to be that.
  const Vec3d margin = 0.1 * view.extent();
  view.lo += margin;
  view.hi -= margin;
  size_t in_view = 0, in_shade = 0, coarser_in_shade = 0;
  for (const NodeRecord& n : b.store->level(Q)) {
    const CellKey key{uint32_t(Q), n.code};
    std::optional<CellKey> ancestor;
    for (CellKey a = key;; a = a.parent()) {
      if (collapsed.count(a)) { ancestor = a; break; }
      if (a.level == 0) break;
    }
    if (!ancestor) continue;
    const Bbox box = b.store->cell_bounds(key);
    Bbox shadow;
    for (int i = 0; i < 8; ++i) {
      const Vec3d p(i & 1 ? box.hi.x : box.lo.x, i & 2 ? box.hi.y : box.lo.y, i & 4 ? box.hi.z : box.lo.z);
      shadow.expand(p.y > 0 ? p + (-p.y / light_dir.y) * light_dir : Vec3d(p.x, 0, p.z));
    }
    const bool seen = shadow.lo.x <= view.hi.x && shadow.hi.x >= view.lo.x && shadow.lo.z <= view.hi.z &&
                      shadow.hi.z >= view.lo.z;
    if (!seen) continue;
    const Vec3d q = glm::max(shadow.lo - cam.eye, glm::max(Vec3d(0), cam.eye - shadow.hi));
    // The angle of the pixels the shadow covers (no mirror or glass shows
    // it elsewhere; checked against every pixel in the camera's tests), at
    // least the image's smallest.
    std::array<Vec3d, 4> shadow_corners;
    for (int i = 0; i < 4; ++i)
      shadow_corners[size_t(i)] = Vec3d(i & 1 ? shadow.hi.x : shadow.lo.x, 0, i & 2 ? shadow.hi.z : shadow.lo.z);
    const double a = std::max(a_min, smallest_pixel_angle_over(cam, shadow_corners));
    const double bound = K * a * glm::length(q) * sin_elevation * (1 + 1e-9);
    const bool on_lit_ground = std::any_of(lit_ground.begin(), lit_ground.end(), [&](const Vec3d& p) {
      return p.x >= shadow.lo.x && p.x <= shadow.hi.x && p.z >= shadow.lo.z && p.z <= shadow.hi.z;
    });
    if (!on_lit_ground) {
      ++in_shade;
      if (!(b.store->cell_diagonal(int(ancestor->level)) < bound)) ++coarser_in_shade;
      continue;
    }
    ++in_view;
    EXPECT_LT(b.store->cell_diagonal(int(ancestor->level)), bound) << "level " << ancestor->level;
  }
  EXPECT_GT(in_view, 0u);
  EXPECT_GT(in_shade, 0u);
  EXPECT_GT(coarser_in_shade, 0u);
  // The same cut without the rule for shadows within shadows (and unseen
  // cells): those cells keep the bound too.
  {
    ProbeConfig c;
    c.rays = 1000;
    c.seed = 7;
    c.footprint_scale = K;
    c.unseen_cells = false;
    Scene lit_scene = scene;
    lit_scene.lights = {sun};
    auto before = probe_with_config(lit_scene, b, c);
    ASSERT_TRUE(before) << before.status().message();
    EXPECT_GT(before->cuts[0].cells.size(), lit->cuts[0].cells.size());
  }
  // Without the light nothing is seen of the teapot: it collapses hard.
  EXPECT_LT(dark->cuts[0].cells.size(), lit->cuts[0].cells.size() / 4);
  // Where the light stands decides the cut, so it is part of the cut's key:
  // a cached cut is not reused under another light.
  const OneObject one(b);
  ProbeConfig c;
  Scene low = scene, high = scene;
  low.lights = {sun};
  high.lights = {sun};
  high.lights[0].direction = Vec3d(0, -1, 0);
  EXPECT_NE(probe_key(low, *b.store, one.objects(), 0, c), probe_key(high, *b.store, one.objects(), 0, c));
}

// ...but only where the view sees the ground: here the teapot fills the view,
// its shadow falls on ground inside the frustum behind it, and no test ray
// meets the ground, so the cut is the one without a ground at all. (Bounding
// every shadow in the frustum kept twice the triangles of the report's
// close-up at the same PSNR.)
TEST(Probe, ShadowsOnGroundTheViewDoesNotSeeDoNotBind) {
  const Built& b = teapot();
  Scene scene = make_scene(MaterialType::Diffuse, Vec3d(0, 1.5, 6), Vec3d(0, 1.5, 0));
  scene.camera.fov_y_deg = 20;
  Light sun;
  sun.type = LightType::Directional;
  sun.direction = glm::normalize(Vec3d(0.2, -0.35, -1));
  scene.lights = {sun};
  auto with_ground = probe(scene, b, 1000, 2, 64.0);
  scene.ground.reset();
  auto without = probe(scene, b, 1000, 2, 64.0);
  ASSERT_TRUE(with_ground && without);
  EXPECT_EQ(with_ground->counters.at("hits_ground"), 0u);  // the premise: the teapot hides the ground
  const Cut &a = with_ground->cuts[0], &c = without->cuts[0];
  ASSERT_EQ(a.cells.size(), c.cells.size());
  for (size_t i = 0; i < a.cells.size(); ++i) EXPECT_EQ(a.cells[i].key, c.cells[i].key);
}

// Properties of the cut: an antichain within quadric_depth; every marked cell
// is finer than K times the smallest footprint of the hits inside it; visible
// unreached cells are no coarser than the pinhole bound; larger K is coarser.
TEST(Probe, CutRespectsFinestNeedAndPolicy) {
  const Built& b = teapot();
  const Scene scene = make_scene(MaterialType::Diffuse, kEye, kLook);
  auto r1 = probe(scene, b, 2000, 2, 1.0);
  auto r4 = probe(scene, b, 2000, 2, 4.0);
  ASSERT_TRUE(r1 && r4);
  const Cut& cut = r1->cuts[0];
  const int Q = b.store->header().quadric_depth;
  ASSERT_FALSE(cut.cells.empty());
  const PinholeCamera cam = make_pinhole_camera(scene.camera);
  double a_min = 1e30;
  for (double px : {0.0, double(cam.width)})
    for (double py : {0.0, double(cam.height)}) {
      const RayDerivatives d = cam.derivatives(px, py);
      a_min = std::min({a_min, glm::length(d.dd_dx), glm::length(d.dd_dy)});
    }
  std::set<CellKey> keys;
  for (const CollapsedCell& c : cut.cells) {
    ASSERT_LE(int(c.key.level), Q);
    ASSERT_NE(b.store->find(c.key), nullptr);
    const double diag = b.store->cell_diagonal(int(c.key.level));
    if (c.hits > 0) {
      EXPECT_LT(diag, 1.0 * c.min_footprint * (1 + 1e-6));
    }
    // No cell is coarser than the pinhole bound at its nearest point allows
    // (for unreached parts); for cells with hits the measured need may exceed it.
    if (c.hits == 0) {
      const Bbox box = b.store->cell_bounds(c.key);
      const Vec3d q = glm::max(box.lo - cam.eye, glm::max(Vec3d(0), cam.eye - box.hi));
      EXPECT_LT(diag, a_min * glm::length(q) * (1 + 1e-9));
    }
    keys.insert(c.key);
  }
  for (const CollapsedCell& c : cut.cells)
    for (CellKey a = c.key; a.level > 0;) {
      a = a.parent();
      EXPECT_EQ(keys.count(a), 0u) << "not an antichain";
    }
  // Coverage of the finest level: K = 4 collapses at least as much as K = 1.
  auto covered = [&](const Cut& c) {
    uint64_t n = 0;
    for (const CollapsedCell& cell : c.cells) n += uint64_t(1) << (3 * (Q - int(cell.key.level)));
    return n;
  };
  EXPECT_GE(covered(r4->cuts[0]), covered(cut));
  EXPECT_GT(covered(cut), 0u);
}

TEST(Probe, SameCutOnOneOrTwoThreads) {
  const Scene scene = make_scene(MaterialType::Glass, kEye, kLook);
  auto a = probe(scene, teapot(), 800, 1, 1.0, uint64_t(1) << 30);
  auto b = probe(scene, teapot(), 800, 2, 1.0, uint64_t(1) << 18);  // and a cache that evicts
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->counters.at("cache_evictions"), 0u);
  EXPECT_GT(b->counters.at("cache_evictions"), 0u);
  const Cut &ca = a->cuts[0], &cb = b->cuts[0];
  ASSERT_EQ(ca.cells.size(), cb.cells.size());
  for (size_t i = 0; i < ca.cells.size(); ++i) {
    EXPECT_EQ(ca.cells[i].key, cb.cells[i].key);
    EXPECT_EQ(ca.cells[i].min_footprint, cb.cells[i].min_footprint);
    EXPECT_EQ(ca.cells[i].hits, cb.cells[i].hits);
  }
  for (const char* k : {"rays_primary", "rays_reflection", "rays_refraction", "hits", "hits_ground", "misses",
                        "total_internal_reflections", "differentials_dropped"})
    EXPECT_EQ(ca.counters.at(k), cb.counters.at(k)) << k;
  EXPECT_EQ(ca.min_footprint, cb.min_footprint);
  EXPECT_EQ(ca.key, cb.key);
}

// Unseen cells (probe.h): the far side of a closed sphere whose normals
// point outwards faces away from the eye, so with no light to cast its
// shadow it collapses; the side the camera sees keeps its cells. The same
// sphere turned inside out (normals pointing in) shows the camera back
// faces: it is not taken for closed and outward, and keeps its cut.
TEST(Probe, BackFacesOfAClosedMeshCollapseUnlessTheViewSeesThem) {
  const test::TestMesh out = test::uv_sphere(Vec3d(0, 1.5, 0), 1.0, 32, 64);
  test::TestMesh in = out;
  for (size_t t = 0; t < in.size(); ++t) {
    std::swap(in.p[3 * t + 1], in.p[3 * t + 2]);
    std::swap(in.n[3 * t + 1], in.n[3 * t + 2]);
  }
  for (Vec3d& n : in.n) n = -n;
  static const Built outward = build("sphere_out", out), inward = build("sphere_in", in);
  ASSERT_EQ(outward.store->boundary_leaves(), 0u);
  ASSERT_EQ(inward.store->boundary_leaves(), 0u);
  const Vec3d eye(0.3, 2.0, 6.0);
  const Scene scene = make_scene(MaterialType::Diffuse, eye, Vec3d(0, 1.5, 0), false, false);
  auto run = [&](const Built& b, bool unseen) {
    ProbeConfig c;
    c.rays = 2000;
    c.seed = 7;
    c.unseen_cells = unseen;
    return probe_with_config(scene, b, c);
  };
  auto with = run(outward, true), without = run(outward, false);
  ASSERT_TRUE(with && without);
  const Cut &a = with->cuts[0], &b = without->cuts[0];
  EXPECT_GT(a.counters.at("finest_cells_back_facing"), 0u);
  EXPECT_EQ(b.counters.at("finest_cells_back_facing"), 0u);
  EXPECT_LT(a.cells.size(), b.cells.size());
  // Where the sphere plainly faces the camera, the same cut cells.
  auto cut_cell_of = [](const Cut& cut, const OctreeStore& st, const Vec3d& p) {
    const int Q = st.header().quadric_depth;
    std::set<CellKey> cells;
    for (const CollapsedCell& c : cut.cells) cells.insert(c.key);
    for (CellKey k = st.cell_of(p, Q);; k = k.parent()) {
      if (cells.count(k)) return std::optional<CellKey>(k);
      if (k.level == 0) return std::optional<CellKey>();
    }
  };
  size_t facing = 0;
  for (size_t t = 0; t < outward.soup.size(); ++t) {
    const Vec3d* p = &outward.soup.p[3 * t];
    const Vec3d centre = (p[0] + p[1] + p[2]) / 3.0;
    const Vec3d n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
    if (!(glm::dot(n, glm::normalize(centre - eye)) < -0.5)) continue;
    ++facing;
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(cut_cell_of(a, *outward.store, p[k]), cut_cell_of(b, *outward.store, p[k])) << "triangle " << t;
  }
  EXPECT_GT(facing, 100u);
  // Inside out: the camera's rays meet back faces.
  auto in_with = run(inward, true), in_without = run(inward, false);
  ASSERT_TRUE(in_with && in_without);
  EXPECT_EQ(in_with->cuts[0].counters.at("finest_cells_back_facing"), 0u);
  EXPECT_EQ(in_with->cuts[0].cells.size(), in_without->cuts[0].cells.size());
  // The rule is part of the cut's key.
  const OneObject one(outward);
  ProbeConfig on, off;
  off.unseen_cells = false;
  EXPECT_NE(probe_key(scene, *outward.store, one.objects(), 0, on),
            probe_key(scene, *outward.store, one.objects(), 0, off));
}

TEST(Probe, CameraInsideTheBoundingBox) {
  // Eye inside the teapot's body: every ray hits the inside of the shell.
  const Built& b = teapot();
  auto r = probe(make_scene(MaterialType::Diffuse, Vec3d(0, 1.2, 0), Vec3d(1, 1.2, 0.3), false), b, 500);
  ASSERT_TRUE(r) << r.status().message();
  EXPECT_EQ(r->counters.at("hits"), 500u);
  // The cell holding the eye (at every level) is never collapsed.
  for (const CollapsedCell& c : r->cuts[0].cells) EXPECT_FALSE(b.store->cell_bounds(c.key).contains(Vec3d(0, 1.2, 0)));
}

TEST(Probe, MeshBehindTheCameraAndEmptyView) {
  const Built& b = teapot();
  // Looking away from the teapot, no ground, no lights: nothing can be seen,
  // shadowed or reflected, so the whole mesh collapses into the root.
  auto r = probe(make_scene(MaterialType::Diffuse, Vec3d(0, 1.5, 8), Vec3d(0, 1.5, 20), false, false), b, 500);
  ASSERT_TRUE(r) << r.status().message();
  EXPECT_EQ(r->counters.at("hits"), 0u);
  EXPECT_EQ(r->counters.at("misses"), 500u);
  ASSERT_EQ(r->cuts[0].cells.size(), 1u);
  EXPECT_EQ(r->cuts[0].cells[0].key, (CellKey{0, 0}));
  EXPECT_EQ(r->cuts[0].min_footprint, 0.0f);
  // With lights it may cast shadows into the view: collapsed, but not into one vertex.
  auto lit = probe(make_scene(MaterialType::Diffuse, Vec3d(0, 1.5, 8), Vec3d(0, 1.5, 20), true, true), b, 500);
  ASSERT_TRUE(lit);
  EXPECT_EQ(lit->counters.at("hits"), 0u);
  auto not_root = [](const Cut& c) {
    for (const CollapsedCell& cell : c.cells)
      if (cell.key.level == 0) return false;
    return true;
  };
  EXPECT_TRUE(not_root(lit->cuts[0]));
  // A mirror in the scene could show it: no hard collapse either.
  Scene mirror = make_scene(MaterialType::Mirror, Vec3d(0, 1.5, 8), Vec3d(0, 1.5, 20), false, false);
  auto m = probe(mirror, b, 500);
  ASSERT_TRUE(m);
  EXPECT_TRUE(not_root(m->cuts[0]));
  // An empty view beside the mesh (sky only) works too.
  auto sky = probe(make_scene(MaterialType::Diffuse, Vec3d(0, 1.5, 8), Vec3d(0, 30, 8.1), false), b, 300);
  ASSERT_TRUE(sky);
  EXPECT_EQ(sky->counters.at("hits"), 0u);
}

TEST(Probe, CorruptPageIsReportedNotTraced) {
  const Built& b = teapot();
  const fs::path bad = tmp_dir() / "teapot20k-corrupt.raylod";
  fs::copy_file(b.store_path, bad, fs::copy_options::overwrite_existing);
  // Flip a byte in the middle of every page's triangle data.
  {
    std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
    for (const PageInfo& p : b.store->pages()) {
      const uint64_t at = p.offset + 18 * p.triangle_count;
      f.seekg(std::streamoff(at));
      char c;
      f.read(&c, 1);
      c ^= 0x55;
      f.seekp(std::streamoff(at));
      f.write(&c, 1);
    }
  }
  auto opened = OctreeStore::open(bad);
  if (!opened) {
    EXPECT_NE(opened.status().message().find("corrupt"), std::string::npos);
    return;
  }
  Built corrupt;
  corrupt.store = std::move(opened.value());
  corrupt.store_path = bad;
  auto r = probe(make_scene(MaterialType::Diffuse, kEye, kLook), corrupt, 200);
  ASSERT_FALSE(r);
  EXPECT_NE(r.status().message().find("checksum"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("page"), std::string::npos) << r.status().message();
}

TEST(Probe, ObjectTransformScalesFootprints) {
  // The same mesh scaled by 2 in world: footprints measured in store units
  // are halved, so fewer cells collapse than with a camera twice as far.
  const Built& b = teapot();
  Scene scene = make_scene(MaterialType::Diffuse, kEye * 2.0, kLook * 2.0, false);
  const OneObject one(b, glm::scale(glm::dmat4(1.0), Vec3d(2.0)));
  ProbeConfig c;
  c.rays = 1000;
  c.seed = 7;
  c.footprint_scale = 1.0;  // as probe() below
  auto scaled = run_probe(scene, one.stores(), one.objects(), c);
  auto plain = probe(make_scene(MaterialType::Diffuse, kEye, kLook, false), b, 1000);
  ASSERT_TRUE(scaled && plain);
  // Twice the size seen from twice the distance is the same picture.
  EXPECT_NEAR(double(scaled->cuts[0].min_footprint), double(plain->cuts[0].min_footprint),
              1e-6 * double(plain->cuts[0].min_footprint));
  EXPECT_EQ(scaled->cuts[0].cells.size(), plain->cuts[0].cells.size());
}

// Seen at grazing incidence a pixel's footprint on the surface is drawn out
// along the ray, many times what the pixel resolves across it; the cut's
// min_footprint (which bounds the Draco quantisation) is the width across
// the ray. Found by a bug hunt: a 0.01-degree view of a teapot's lid grazing
// its knob quantised the kept vertices by 1.5 pixels, nothing collapsed.
const Built& plane();
TEST(Probe, MinFootprintIsTheWidthAcrossTheRay) {
  const Built& b = plane();  // y = 1, 4 x 4 around the axis
  const OneObject one(b);
  Scene scene = make_scene(MaterialType::Diffuse, Vec3d(0, 1.05, 6), Vec3d(0, 1, 0), false);
  scene.camera.fov_y_deg = 1.5;  // the plane fills the image's lower part
  ProbeConfig c;
  c.rays = 2000;
  c.seed = 7;
  auto t = trace_probe(scene, one.stores(), one.objects(), c);
  ASSERT_TRUE(t) << t.status().message();
  ASSERT_GT(t->hits.size(), 100u);
  const PinholeCamera cam = make_pinhole_camera(scene.camera);
  const double pixel = 2.0 * cam.tan_half_y / scene.camera.height;  // at the image centre; less towards the corners
  for (const ProbeHit& h : t->hits) {
    ASSERT_FALSE(h.estimated);
    // Hits lie 4 to 8 from the eye (the plane's near and far edges), at
    // most 0.05 / 4 radians below the rays: the surface stretches the
    // footprint by over 80 times, the width stays about a pixel's.
    EXPECT_GT(h.footprint, 50.0 * h.width);
    EXPECT_GT(h.width, 0.5 * pixel * 4.0);
    EXPECT_LT(h.width, 1.5 * pixel * 8.5);
  }
  auto cuts = select_cuts(*t, scene, one.stores(), one.objects(), c);
  ASSERT_TRUE(cuts) << cuts.status().message();
  double narrowest = std::numeric_limits<double>::infinity();
  for (const ProbeHit& h : t->hits) narrowest = std::min(narrowest, h.width);
  EXPECT_FLOAT_EQ(cuts->cuts[0].min_footprint, float(narrowest));
}

// A surface moved by d along its normal moves in the image by d sin(theta)
// across the ray, at a silhouette by d: the deviation tests take the width
// across the ray over sin(theta), at most the footprint (ProbeHit::
// shift_footprint). The plane y = 1 seen at three elevations.
TEST(Probe, AShiftFootprintIsTheWidthOverTheSineOfIncidence) {
  const Built& b = plane();
  const OneObject one(b);
  ProbeConfig c;
  c.rays = 1000;
  c.seed = 7;
  auto hits_from = [&](const Vec3d& eye) {
    Scene scene = make_scene(MaterialType::Diffuse, eye, Vec3d(0, 1, 0), false);
    scene.camera.fov_y_deg = 1.5;
    auto t = trace_probe(scene, one.stores(), one.objects(), c);
    EXPECT_TRUE(t) << t.status().message();
    EXPECT_GT(t->hits.size(), 100u);
    return t->hits;
  };
  // Grazing, 0.05 / 6 rad below the rays: sin(theta) is 1 to 1e-4, the
  // width binds.
  for (const ProbeHit& h : hits_from(Vec3d(0, 1.05, 6))) {
    EXPECT_GE(h.shift_footprint, h.width * (1 - 1e-9));
    EXPECT_LE(h.shift_footprint, h.width * 1.0001);
    EXPECT_GT(h.footprint, 50.0 * h.shift_footprint);
  }
  // Seen from 30 degrees above (theta = 60 degrees): the footprint is the
  // beam's width stretched by 1 / cos(theta) = 2, the shift footprint that
  // width over sin(theta), cot(60 deg) = 0.577 of the footprint.
  for (const ProbeHit& h : hits_from(Vec3d(0, 1 + 5 * std::sin(M_PI / 6), 5 * std::cos(M_PI / 6)))) {
    EXPECT_NEAR(h.shift_footprint / h.footprint, 1 / std::sqrt(3.0), 0.02);
  }
  // From almost straight above (theta under 45 degrees): the footprint.
  for (const ProbeHit& h : hits_from(Vec3d(0, 6, 0.5))) EXPECT_EQ(h.shift_footprint, h.footprint);
}

// The deviation criterion (probe.h): flat regions are bounded by K alone,
// curved ones also by the deviation their collapse causes.
StatusOr<ProbeResult> probe_with(const Scene& scene, const Built& b, CutCriterion criterion, double k, double tol) {
  const OneObject one(b);
  ProbeConfig c;
  c.rays = 2000;
  c.seed = 7;
  c.criterion = criterion;
  c.footprint_scale = k;
  c.tolerance_px = tol;
  return run_probe(scene, one.stores(), one.objects(), c);
}

const Built& plane() {
  static Built b = [] {
    test::TestMesh m;
    const int n = 64;
    auto at = [&](int i, int j) { return Vec3d(-2.0 + 4.0 * i / n, 1.0, -2.0 + 4.0 * j / n); };
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        for (const Vec3d& p : {at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i + 1, j)}) {
          m.p.push_back(p);
          m.n.push_back(Vec3d(0, 1, 0));
        }
      }
    return build("plane", m);
  }();
  return b;
}

TEST(ProbeDeviation, DefaultTolerancesTightenAboveFourSamplesPerPixel) {
  for (int spp : {1, 2, 4}) {
    EXPECT_EQ(default_tolerance_px(spp), kDefaultTolerancePx);
    EXPECT_EQ(default_angle_tolerance_px(spp), kDefaultAngleTolerancePx);
  }
  EXPECT_DOUBLE_EQ(default_tolerance_px(64), kDefaultTolerancePx / 8);  // (4 / 64)^0.75
  EXPECT_DOUBLE_EQ(default_angle_tolerance_px(64), kDefaultAngleTolerancePx / 8);
  for (int spp = 5; spp < 4096; spp *= 2) EXPECT_LT(default_tolerance_px(spp + 1), default_tolerance_px(spp));
}

TEST(ProbeDeviation, FlatPlaneCollapsesAsCoarselyAsKAllows) {
  const Scene scene = make_scene(MaterialType::Diffuse, Vec3d(0.5, 6, 4), Vec3d(0, 1, 0), false);
  const OctreeStore& st = *plane().store;
  for (double k : {2.0, 8.0, 32.0}) {
    const double tol = 0.5;
    auto dev = probe_with(scene, plane(), CutCriterion::Deviation, k, tol);
    auto diag = probe_with(scene, plane(), CutCriterion::Diagonal, k, tol);
    ASSERT_TRUE(dev && diag);
    // A plane's quadric has no residual: the deviation test never binds.
    EXPECT_EQ(dev->cuts[0].counters.at("cells_kept_for_deviation"), 0u) << "K " << k;
    // Away from its rim (an open boundary) the cut is the diagonal test's:
    // every cell the diagonal test collapses without touching the rim is
    // collapsed by the deviation test too, and a cell only the deviation
    // test collapses lies in a larger cell that the diagonal test collapsed
    // across the rim.
    std::set<std::pair<uint32_t, uint64_t>> by_dev, by_diag, diag_rim;
    for (const CollapsedCell& c : dev->cuts[0].cells)
      if (!st.touches_boundary(c.key)) by_dev.insert({c.key.level, c.key.code});
    for (const CollapsedCell& c : diag->cuts[0].cells)
      (st.touches_boundary(c.key) ? diag_rim : by_diag).insert({c.key.level, c.key.code});
    for (const auto& c : by_diag) EXPECT_EQ(by_dev.count(c), 1u) << "K " << k << " level " << c.first;
    for (const auto& [level, code] : by_dev) {
      if (by_diag.count({level, code})) continue;
      bool inside = false;
      for (uint32_t l = 0; l < level; ++l) inside = inside || diag_rim.count({l, code >> (3 * (level - l))});
      EXPECT_TRUE(inside) << "K " << k << " level " << level;
    }
    // At the rim, a cell collapses only while it is within the tolerance
    // of the footprints measured in it (the bound for cells no ray reached
    // is smaller still).
    if (k >= 32) {
      EXPECT_GT(dev->cuts[0].counters.at("cells_kept_for_boundary"), 0u) << "K " << k;
    }
    for (const CollapsedCell& c : dev->cuts[0].cells) {
      if (st.touches_boundary(c.key) && c.hits > 0) {
        EXPECT_LE(st.cell_diagonal(int(c.key.level)), tol * c.min_footprint * (1 + 1e-6)) << "K " << k;
      }
    }
  }
}

// A knife edge: a face and its underside meeting at a 0-degree dihedral
// along x = 2 (the underside drops 0.08 over the 4 units back), seen side on.
const Built& knife() {
  static Built b = [] {
    test::TestMesh m;
    const int n = 64;
    auto top = [&](int i, int j) { return Vec3d(-2.0 + 4.0 * i / n, 1.0, -2.0 + 4.0 * j / n); };
    auto bottom = [&](int i, int j) { return top(i, j) - Vec3d(0, 0.08 * (n - i) / n, 0); };
    const Vec3d up(0, 1, 0), down = glm::normalize(Vec3d(0.02, -1, 0));
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        for (const Vec3d& p : {top(i, j), top(i, j + 1), top(i + 1, j + 1), top(i, j), top(i + 1, j + 1), top(i + 1, j)}) {
          m.p.push_back(p);
          m.n.push_back(up);
        }
        for (const Vec3d& p :
             {bottom(i, j), bottom(i + 1, j + 1), bottom(i, j + 1), bottom(i, j), bottom(i + 1, j), bottom(i + 1, j + 1)}) {
          m.p.push_back(p);
          m.n.push_back(down);
        }
      }
    return build("knife", m);
  }();
  return b;
}

TEST(ProbeDeviation, FoldsCollapseOnlyWithinTheTolerance) {
  // The quadric of a knife edge's cell is one plane, so its deviation is
  // about zero; the representative would sit at the corners' mean, pulling
  // the edge in by up to the cell's size (found on an ABC CAD plate, whose
  // end showed the underside where the lit face had been). Such a cell
  // collapses only while the whole cell is within the tolerance, as a rim.
  const Scene scene = make_scene(MaterialType::Diffuse, Vec3d(20, 6, 12), Vec3d(2, 1, 0));
  const Built& b = knife();
  const OctreeStore& st = *b.store;
  const Vec3d origin = st.header().origin;
  // Against the shift footprint (ProbeHit::shift_footprint), at most the
  // footprint the cut records; at 0.5 pixels the knife's hit cells stay whole,
  // coarser tolerances collapse some.
  size_t folded = 0;
  for (const double tol : {0.5, 2.0, 8.0}) {
    auto r = probe_with(scene, b, CutCriterion::Deviation, 64, tol);
    ASSERT_TRUE(r);
    const Cut& cut = r->cuts[0];
    EXPECT_GT(cut.counters.at("cells_kept_for_fold"), 0u) << "tolerance " << tol;
    for (const CollapsedCell& c : cut.cells) {
      const Bbox cell = st.cell_bounds(c.key);
      const CollapseDeviation d =
          collapse_deviation(*st.find(c.key), Bbox{cell.lo - origin, cell.hi - origin}, node_normals_of(st.header()));
      if (!d.folded || c.hits == 0) continue;
      ++folded;
      EXPECT_LE(st.cell_diagonal(int(c.key.level)), tol * c.min_footprint * (1 + 1e-6))
          << "level " << c.key.level << ", tolerance " << tol;
    }
  }
  EXPECT_GT(folded, 0u);
}

TEST(ProbeDeviation, AWideViewBoundsCellsByThePixelsTheyCover) {
  // The teapot at the centre of a 150-degree view, as many pixels wide as
  // in the 40-degree one (the eye 0.0976 times as far: tan 20 / tan 75).
  // Cells no ray reached are bounded by the angle of the pixels they cover,
  // not by the image's corners, where a pixel subtends cos^2(75 deg) = 0.07
  // of the centre's. The wide view sees the near side of the teapot larger
  // and keeps 2.4 times the narrow view's corners (13,974 against 5,928);
  // bounded by the corners' pixels it kept 3.2 times (26,124 against 8,046).
  const Built& b = teapot();
  auto corners_kept = [&](const Scene& scene) {
    auto r = probe_with(scene, b, CutCriterion::Deviation, 64, 0.5);
    EXPECT_TRUE(r);
    uint64_t collapsed = 0;
    for (const CollapsedCell& c : r->cuts[0].cells) collapsed += b.store->find(c.key)->corner_count;
    return 3 * b.store->header().triangle_count - collapsed;
  };
  const uint64_t narrow = corners_kept(make_scene(MaterialType::Diffuse, kEye, kLook));
  Scene wide = make_scene(MaterialType::Diffuse, kLook + (kEye - kLook) * (std::tan(M_PI / 9) / std::tan(5 * M_PI / 12)), kLook);
  wide.camera.fov_y_deg = 150;
  const uint64_t kept_wide = corners_kept(wide);
  EXPECT_LT(double(kept_wide), 2.8 * double(narrow)) << "narrow " << narrow;
}

TEST(ProbeDeviation, CurvedCellsKeepTheirDeviationBelowTheTolerance) {
  const Built& b = teapot();
  const Scene scene = make_scene(MaterialType::Diffuse, kEye, kLook);
  const Vec3d origin = b.store->header().origin;
  uint64_t previous = 0;
  for (double tol : {2.0, 0.5, 0.125}) {
    auto r = probe_with(scene, b, CutCriterion::Deviation, 64, tol);
    ASSERT_TRUE(r);
    const Cut& cut = r->cuts[0];
    EXPECT_GT(cut.counters.at("cells_kept_for_deviation"), 0u) << "tolerance " << tol;
    // Every collapsed cell a test ray hit keeps its deviation under the
    // tolerance times the smallest footprint measured in it.
    size_t checked = 0;
    for (const CollapsedCell& c : cut.cells) {
      if (c.hits == 0) continue;
      const NodeRecord* node = b.store->find(c.key);
      ASSERT_NE(node, nullptr);
      const Bbox cell = b.store->cell_bounds(c.key);
      const CollapseDeviation d = collapse_deviation(*node, Bbox{cell.lo - origin, cell.hi - origin}, node_normals_of(b.store->header()));
      EXPECT_LE(d.position, tol * c.min_footprint * (1 + 1e-6)) << "level " << c.key.level;
      ++checked;
    }
    EXPECT_GT(checked, 0u);
    // A smaller tolerance never gives a coarser mesh.
    uint64_t corners = 0;
    for (const CollapsedCell& c : cut.cells) corners += b.store->find(c.key)->corner_count;
    if (previous) {
      EXPECT_LE(corners, previous) << "tolerance " << tol;
    }
    previous = corners;
  }
}

// Every collapsed cell a test ray hit moves the surface by at most the
// tolerance in pixels across each of those rays: its deviation is within
// the tolerance times the smallest shift footprint of its hits, which near
// the teapot's silhouettes is far below the footprint on the surface.
// The diffuse teapot's default view traced once (4000 test rays, seed 7),
// for tests that select cuts from that trace.
struct TracedTeapot {
  const Built& b = teapot();
  OneObject one{b};
  Scene scene = make_scene(MaterialType::Diffuse, kEye, kLook);
  ProbeConfig config = [] {
    ProbeConfig c;
    c.rays = 4000;
    c.seed = 7;
    return c;
  }();
  StatusOr<ProbeTrace> trace = trace_probe(scene, one.stores(), one.objects(), config);
};

TEST(ProbeDeviation, CollapsedCellsShiftTheImageByAtMostTheTolerance) {
  const TracedTeapot tt;
  ASSERT_TRUE(tt.trace) << tt.trace.status().message();
  const OneObject& one = tt.one;
  const OctreeStore& st = *tt.b.store;
  const Scene& scene = tt.scene;
  const Vec3d origin = st.header().origin;
  const int Q = st.header().quadric_depth;
  const ProbeConfig& c = tt.config;
  const ProbeTrace* t = &tt.trace.value();
  auto r = select_cuts(*t, scene, one.stores(), one.objects(), c);
  ASSERT_TRUE(r) << r.status().message();
  const Cut& cut = r->cuts[0];
  std::map<std::pair<uint32_t, uint64_t>, double> shift;  // cut cell -> its hits' smallest shift footprint
  for (const CollapsedCell& cell : cut.cells) shift[{cell.key.level, cell.key.code}] = std::numeric_limits<double>::infinity();
  size_t grazing = 0;
  for (const ProbeHit& h : t->hits)
    for (const Vec3d& corner : h.corners) {
      const uint64_t code = st.cell_of(corner, Q).code;
      for (int L = Q; L >= 0; --L) {
        auto it = shift.find({uint32_t(L), code >> (3 * (Q - L))});
        if (it == shift.end()) continue;
        it->second = std::min(it->second, h.shift_footprint);
        grazing += h.shift_footprint < 0.5 * h.footprint;
        break;
      }
    }
  EXPECT_GT(grazing, 10u);
  size_t checked = 0;
  for (const CollapsedCell& cell : cut.cells) {
    const double s = shift[{cell.key.level, cell.key.code}];
    if (!std::isfinite(s)) continue;
    const Bbox box = st.cell_bounds(cell.key);
    const CollapseDeviation d =
        collapse_deviation(*st.find(cell.key), Bbox{box.lo - origin, box.hi - origin}, node_normals_of(st.header()));
    EXPECT_LE(d.position, c.tolerance_px * s * (1 + 1e-6)) << "level " << cell.key.level;
    ++checked;
  }
  EXPECT_GT(checked, 100u);
}

// --shared-cut: one cut over several views' traces.
struct SharedViews {
  std::vector<ProbeTrace> traces;
  std::vector<Camera> cameras;
  std::vector<ProbeView> views() const {
    std::vector<ProbeView> v;
    for (size_t i = 0; i < traces.size(); ++i) v.push_back(ProbeView{&traces[i], cameras[i]});
    return v;
  }
};

ProbeConfig shared_config() {
  ProbeConfig c;
  c.rays = 1500;
  c.seed = 7;
  c.footprint_scale = 8;
  c.cache_bytes = uint64_t(64) << 20;
  return c;
}

// Three views of the teapot (two around it, one close up), traced in an arena of `threads`.
SharedViews trace_views(const Scene& scene, const Built& b, int threads) {
  SharedViews out;
  out.cameras = {scene.camera, scene.camera, scene.camera};
  out.cameras[1].eye = Vec3d(-8.5, 4.8, 6.5);
  out.cameras[2].eye = kLook + (kEye - kLook) * 0.35;
  const OneObject one(b);
  tbb::task_arena(threads).execute([&] {
    for (const Camera& c : out.cameras) {
      Scene s = scene;
      s.camera = c;
      auto t = trace_probe(s, one.stores(), one.objects(),
                           shared_config());
      EXPECT_TRUE(t.is_ok()) << t.status().message();
      out.traces.push_back(t.is_ok() ? std::move(t.value()) : ProbeTrace{});
    }
  });
  return out;
}

StatusOr<ProbeResult> select(std::span<const ProbeView> views, const Scene& scene, const Built& b, int threads = 2) {
  const OneObject one(b);
  StatusOr<ProbeResult> r = Status::error("not run");
  tbb::task_arena(threads).execute([&] {
    r = select_shared_cuts(views, scene, one.stores(), one.objects(),
                           shared_config());
  });
  return r;
}

std::vector<CellKey> cells_of(const Cut& cut) {
  std::vector<CellKey> keys;
  for (const CollapsedCell& c : cut.cells) keys.push_back(c.key);
  return keys;
}

// Whether `cell` or one of its ancestors is in `cut` (cut cells sorted by key).
bool collapsed_by(const Cut& cut, const CellKey& cell) {
  for (uint32_t level = 0; level <= cell.level; ++level) {
    const CellKey k{level, cell.code >> (3 * (cell.level - level))};
    if (std::binary_search(cut.cells.begin(), cut.cells.end(), CollapsedCell{k, 0.0f, 0},
                           [](const CollapsedCell& a, const CollapsedCell& b) { return a.key < b.key; }))
      return true;
  }
  return false;
}

TEST(SharedCut, OneViewIsSelectCutsExactly) {
  const Built& b = teapot();
  const Scene scene = make_scene(MaterialType::Diffuse, kEye, kLook);
  const SharedViews v = trace_views(scene, b, 2);
  const std::vector<ProbeView> views = v.views();
  auto shared = select(std::span<const ProbeView>(views.data(), 1), scene, b);
  const OneObject one(b);
  auto single = select_cuts(v.traces[0], scene, one.stores(),
                            one.objects(), shared_config());
  ASSERT_TRUE(shared.is_ok() && single.is_ok());
  EXPECT_EQ(shared->cuts[0].key, single->cuts[0].key);
  EXPECT_EQ(cells_of(shared->cuts[0]), cells_of(single->cuts[0]));
  EXPECT_EQ(shared->cuts[0].min_footprint, single->cuts[0].min_footprint);
}

// Two selections of the same cut: the same key, cells, counters, smallest
// footprint, and each cell's hits and footprint.
void expect_same_cut(const Cut& a, const Cut& f, const std::string& what) {
  EXPECT_EQ(a.key, f.key) << what;
  EXPECT_EQ(cells_of(a), cells_of(f)) << what;
  EXPECT_EQ(a.counters, f.counters) << what;
  EXPECT_EQ(a.min_footprint, f.min_footprint) << what;
  ASSERT_EQ(a.cells.size(), f.cells.size()) << what;
  for (size_t i = 0; i < a.cells.size(); ++i) {
    EXPECT_EQ(a.cells[i].hits, f.cells[i].hits) << what;
    EXPECT_EQ(a.cells[i].min_footprint, f.cells[i].min_footprint) << what;
  }
}

// One CutSelection serves many configurations (the memory limit's
// coarsening): each select() gives exactly what select_cuts gives for that
// configuration -- cells, key, counters, min footprint -- whatever
// configurations it selected before (the kept collapse deviations), on glass
// (the tilt allowance) and with both criteria.
TEST(CutSelection, EverySelectionIsSelectCutsExactly) {
  const Built& b = teapot();
  const OneObject one(b);
  const Scene scene = make_scene(MaterialType::Glass, kEye, kLook);
  ProbeConfig c;
  c.rays = 1000;
  c.seed = 7;
  auto t = trace_probe(scene, one.stores(), one.objects(), c);
  ASSERT_TRUE(t) << t.status().message();
  const ProbeView view{&t.value(), scene.camera};
  auto selection = CutSelection::make(std::span<const ProbeView>(&view, 1), scene, one.stores(), one.objects(), c);
  ASSERT_TRUE(selection) << selection.status().message();
  size_t distinct = 0;
  std::set<std::vector<CellKey>> seen;
  for (auto [criterion, k, tol] : {std::tuple{CutCriterion::Deviation, 64.0, 0.5}, {CutCriterion::Deviation, 4.0, 0.5},
                                   {CutCriterion::Deviation, 512.0, 4.0}, {CutCriterion::Diagonal, 10.0, 0.5},
                                   {CutCriterion::Deviation, 64.0, 0.5}, {CutCriterion::Deviation, 128.0, 1.0}}) {
    ProbeConfig cfg = c;
    cfg.criterion = criterion;
    cfg.footprint_scale = k;
    cfg.tolerance_px = tol;
    cfg.angle_tolerance_px = 2 * tol;
    auto kept = selection->select(cfg);
    auto fresh = select_cuts(*t, scene, one.stores(), one.objects(), cfg);
    ASSERT_TRUE(kept.is_ok() && fresh.is_ok());
    expect_same_cut(kept->cuts[0], fresh->cuts[0], std::to_string(k) + " " + std::to_string(tol));
    distinct += seen.insert(cells_of(kept->cuts[0])).second;
  }
  EXPECT_GE(distinct, 4u);  // the configurations select different cuts
  // A selection is for the shadow factor and the calibration of unreached
  // curved cells it was made with.
  ProbeConfig other = c;
  other.shadow_factor = 2 * c.shadow_factor;
  EXPECT_FALSE(selection->select(other).is_ok());
  other = c;
  other.curved_unreached_tilt = false;
  EXPECT_FALSE(selection->select(other).is_ok());
  other = c;
  other.calibration_quantile = 0.5;
  EXPECT_FALSE(selection->select(other).is_ok());
  other = c;
  other.unreached_angle_allowance = 1;
  EXPECT_FALSE(selection->select(other).is_ok());
}

// A SelectionCache shared by the selections of several views and
// configurations (a view sequence's) changes nothing: every cut equals the
// one a selection of its own gives, whichever views and configurations
// filled the cache before; and a cache keeps one entry per store.
TEST(CutSelection, ASharedSelectionCacheChangesNoCut) {
  const Built& b = teapot();
  const OneObject one(b);
  SelectionCache cache;
  // Traces `scene` into `trace` and selects its cut with the shared cache and
  // alone: the same cut.
  auto same_cut_with_cache = [&](const Scene& scene, const ProbeConfig& c, const std::string& what, ProbeTrace& trace) {
    auto t = trace_probe(scene, one.stores(), one.objects(), c);
    ASSERT_TRUE(t) << t.status().message();
    ProbeConfig shared = c;
    shared.selection_cache = &cache;
    auto with_cache = select_cuts(*t, scene, one.stores(), one.objects(), shared);
    auto alone = select_cuts(*t, scene, one.stores(), one.objects(), c);
    ASSERT_TRUE(with_cache.is_ok() && alone.is_ok());
    expect_same_cut(with_cache->cuts[0], alone->cuts[0], what);
    trace = std::move(*t);
  };
  const std::array<Vec3d, 3> eyes = {kEye, Vec3d(-kEye.x, kEye.y, kEye.z), Vec3d(kEye.z, 0.5 * kEye.y, -kEye.x)};
  size_t compared = 0;
  for (MaterialType type : {MaterialType::Glass, MaterialType::Diffuse})
    for (const Vec3d& eye : eyes)
      for (auto [k, tol] : {std::pair{64.0, 0.5}, {8.0, 2.0}}) {
        const Scene scene = make_scene(type, eye, kLook);
        ProbeConfig c;
        c.rays = 600;
        c.seed = 3;
        c.footprint_scale = k;
        c.tolerance_px = tol;
        ProbeTrace t;
        ASSERT_NO_FATAL_FAILURE(same_cut_with_cache(scene, c, std::to_string(k) + " " + std::to_string(tol), t));
        ++compared;
      }
  EXPECT_EQ(compared, 12u);
  const OctreeStore* store = one.stores()[0].store;
  const SelectionCache::Store& entry = cache.of(*store);
  EXPECT_EQ(&entry, &cache.of(*store));  // one entry per store
  ASSERT_EQ(entry.codes.size(), size_t(store->header().quadric_depth) + 1);
  size_t computed = 0;
  for (int L = 0; L <= store->header().quadric_depth; ++L) {
    ASSERT_EQ(entry.codes[size_t(L)].size(), store->level(L).size());
    for (size_t i = 0; i < store->level(L).size(); ++i) EXPECT_EQ(entry.codes[size_t(L)][i], store->level(L)[i].code);
    ASSERT_EQ(entry.slot[size_t(L)].size(), store->level(L).size());
    for (const uint32_t slot : entry.slot[size_t(L)]) {
      if (slot == 0) continue;
      ASSERT_LE(slot, entry.computed.size());
      EXPECT_GE(entry.computed[slot - 1].position, 0.0);
      ++computed;
    }
  }
  EXPECT_GT(computed, 0u);  // the deviations were kept
  EXPECT_EQ(computed, entry.computed.size());  // each in one slot
  uint64_t nodes = 0;
  for (int L = 0; L <= store->header().quadric_depth; ++L) nodes += store->level(L).size();
  const OctreeStore* list[] = {store};
  const size_t finest = store->level(store->header().quadric_depth).size();
  EXPECT_EQ(entry.finest_cones.size(), finest);
  EXPECT_EQ(SelectionCache::bytes_for(list), nodes * (sizeof(uint64_t) + sizeof(uint32_t)) +
                                                 finest * sizeof(SelectionCache::Store::NormalCone) +
                                                 nodes / SelectionCache::kComputedShare * sizeof(CollapseDeviation));

  // A cache holding more deviations than its bound lets them go before the
  // next selection, which then computes what it tests afresh: the same cut.
  SelectionCache::Store& held = cache.of(*store);
  const size_t before = held.computed.size();
  held.max_computed = 1;
  const Scene scene = make_scene(MaterialType::Glass, eyes[1], kLook);
  ProbeConfig c;
  c.rays = 600;
  c.seed = 3;
  ProbeTrace t;
  ASSERT_NO_FATAL_FAILURE(same_cut_with_cache(scene, c, "after the bound", t));
  // Only this selection's deviations are held: as many as a fresh cache's.
  SelectionCache fresh;
  ProbeConfig own = c;
  own.selection_cache = &fresh;
  ASSERT_TRUE(select_cuts(t, scene, one.stores(), one.objects(), own).is_ok());
  EXPECT_GT(before, 0u);
  EXPECT_EQ(held.computed.size(), fresh.of(*store).computed.size());
}

// The mirror and glass normal bound has its own tolerance (angle_tolerance_px):
// it moves the cut on a glass object and only there, every cell the
// stricter bound collapses stays collapsed under the looser one, and the
// bound is what kept the cells the looser one lets go.
// The teapot probed from kEye (2,000 test rays, seed 7) at an angle
// tolerance and a grading.
StatusOr<ProbeResult> probe_teapot(MaterialType type, double angle, CutBalance balance = CutBalance::Specular) {
  const OneObject one(teapot());
  ProbeConfig c;
  c.rays = 2000;
  c.seed = 7;
  c.angle_tolerance_px = angle;
  c.balance = balance;
  return run_probe(make_scene(type, kEye, kLook), one.stores(), one.objects(), c);
}

// Where an outline may run, the deviation tests take outline_tolerance times
// the tolerance (probe.h, "Outlines"): on the teapot, the cut at 0.5 is at
// least as fine as at 1 in every cell, finer in some, and each cell the
// looser cut collapses and the stricter one splits holds a finest cell
// whose normals reach across the direction from the eye (checked here from
// the store's nodes, not through the probe's code); the fraction is part
// of the cut's key, and one outside (0, 1] is refused.
TEST(ProbeDeviation, OutlinesTakeAFractionOfTheTolerance) {
  const TracedTeapot tt;
  ASSERT_TRUE(tt.trace) << tt.trace.status().message();
  auto select_at = [&](double outline) {
    ProbeConfig c = tt.config;
    c.outline_tolerance = outline;
    return select_cuts(tt.trace.value(), tt.scene, tt.one.stores(), tt.one.objects(), c);
  };
  auto loose = select_at(1), strict = select_at(0.5);
  ASSERT_TRUE(loose && strict);
  const OctreeStore& st = *tt.b.store;
  const int Q = st.header().quadric_depth;
  const Cut &l = loose->cuts[0], &s = strict->cuts[0];
  EXPECT_NE(l.key, s.key);
  for (const CollapsedCell& cell : s.cells) EXPECT_TRUE(collapsed_by(l, cell.key)) << "level " << cell.key.level;

  // Brute force: whether a finest node under `key` may hold an outline.
  const auto finest = st.level(Q);
  auto holds_outline = [&](const CellKey& key) {
    const int shift = 3 * (Q - int(key.level));
    for (const NodeRecord& node : finest) {
      if ((node.code >> shift) != key.code) continue;
      const double spread = normal_spread_angle(node);
      const Bbox box = st.cell_bounds(CellKey{uint32_t(Q), node.code});
      const Vec3d d = 0.5 * (box.lo + box.hi) + st.header().mesh_origin - tt.scene.camera.eye;
      const Vec3d n = node.normal_sum;
      const double reach = spread >= 0.5 * std::numbers::pi ? 1.0 : std::sin(spread);
      if (std::abs(glm::dot(n, d)) <= reach * glm::length(n) * glm::length(d) * (1 + 1e-9)) return true;
    }
    return false;
  };
  size_t split = 0;
  for (const CollapsedCell& cell : l.cells) {
    if (std::binary_search(s.cells.begin(), s.cells.end(), cell,
                           [](const CollapsedCell& x, const CollapsedCell& y) { return x.key < y.key; }))
      continue;
    ++split;
    EXPECT_TRUE(holds_outline(cell.key)) << "level " << cell.key.level << " code " << cell.key.code;
  }
  EXPECT_GT(split, 0u) << "the stricter outline tolerance should split some cells";

  for (double bad : {0.0, -0.5, 1.5}) {
    auto rejected = select_at(bad);
    ASSERT_FALSE(rejected) << bad;
    EXPECT_NE(rejected.status().message().find("outline tolerance"), std::string::npos) << rejected.status().message();
  }
}

TEST(ProbeDeviation, AngleToleranceLoosensOnlyMirrorAndGlass) {
  const Built& b = teapot();
  auto with_angle = [&](MaterialType type, double angle) { return probe_teapot(type, angle); };
  auto strict = with_angle(MaterialType::Glass, 0.5), loose = with_angle(MaterialType::Glass, 4.0);
  ASSERT_TRUE(strict && loose);
  const Cut &s = strict->cuts[0], &l = loose->cuts[0];
  EXPECT_GT(s.counters.at("cells_kept_for_normals"), l.counters.at("cells_kept_for_normals"));
  ASSERT_FALSE(s.cells.empty());
  size_t coarser = 0;
  for (const CollapsedCell& c : s.cells) EXPECT_TRUE(collapsed_by(l, c.key)) << "level " << c.key.level;
  for (const CollapsedCell& c : l.cells) coarser += !collapsed_by(s, c.key);
  EXPECT_GT(coarser, 0u) << "the looser angle should collapse cells the stricter one keeps";
  EXPECT_NE(s.key, l.key);  // cached cuts do not mix

  // A diffuse teapot has no normal bound: the angle changes nothing.
  auto d1 = with_angle(MaterialType::Diffuse, 0.5), d2 = with_angle(MaterialType::Diffuse, 4.0);
  ASSERT_TRUE(d1 && d2);
  EXPECT_EQ(cells_of(d1->cuts[0]), cells_of(d2->cuts[0]));
  EXPECT_EQ(d1->cuts[0].counters.at("cells_kept_for_normals"), 0u);

  ProbeConfig bad;
  bad.angle_tolerance_px = 0;
  const OneObject one(b);
  auto rejected = run_probe(make_scene(MaterialType::Glass, kEye, kLook), one.stores(), one.objects(), bad);
  ASSERT_FALSE(rejected);
  EXPECT_NE(rejected.status().message().find("angle tolerance"), std::string::npos) << rejected.status().message();
}

// A mirror of reflectance 0, or mirrors and glass in a scene of max_depth 0,
// reflect nothing the renderer traces: the cut holds none of the mirror's
// rules for them (it kept 2.8 times the triangles of the same diffuse
// object, for an image that shows no reflection).
TEST(ProbeDeviation, MirrorsThatReflectNothingTakeNoMirrorRules) {
  const Built& b = teapot();
  const OneObject one(b);
  ProbeConfig c;
  c.rays = 1000;
  c.seed = 3;
  auto cut = [&](const Scene& scene) {
    auto r = run_probe(scene, one.stores(), one.objects(), c);
    EXPECT_TRUE(r.is_ok()) << r.status().message();
    return r.is_ok() ? r->cuts[0] : Cut{};
  };
  const Cut diffuse = cut(make_scene(MaterialType::Diffuse, kEye, kLook));
  Scene black = make_scene(MaterialType::Mirror, kEye, kLook);
  black.materials[0].reflectance = 0;
  black.materials[0].color = Vec3(0.8f);
  Scene flat = make_scene(MaterialType::Glass, kEye, kLook);
  flat.max_depth = 0;
  flat.materials[0].color = Vec3(0.8f);
  const Scene diffuse_scene = make_scene(MaterialType::Diffuse, kEye, kLook);
  ASSERT_EQ(diffuse_scene.materials[0].color, Vec3(0.8f));
  for (const Scene& s : {black, flat}) {
    EXPECT_FALSE(s.traces_specular(s.materials[0]));
    const Cut got = cut(s);
    EXPECT_EQ(got.counters.at("cells_kept_for_normals"), 0u);
    EXPECT_EQ(cells_of(got), cells_of(diffuse));
  }
  const Scene mirror = make_scene(MaterialType::Mirror, kEye, kLook);
  EXPECT_TRUE(mirror.traces_specular(mirror.materials[0]));
  EXPECT_NE(cells_of(cut(mirror)), cells_of(diffuse));
}

// Cells no test ray reached are held to unreached_angle_allowance times the
// angle tolerance, measured cells to the tolerance itself: on a mirror
// teapot (grading off, so that no cell is split), raising the allowance
// only loosens the cut, and every cell it lets go coarser holds an
// unreached part (a cell of the stricter cut with no hit, or a finest cell
// the stricter cut kept whole); a diffuse teapot has no normal bound and
// does not change; an allowance of 0 is refused.
TEST(ProbeDeviation, UnreachedAllowanceLoosensOnlyWhereNoRayHit) {
  const Built& b = teapot();
  const OneObject one(b);
  auto probe = [&](MaterialType type, double allowance, double angle = 1) {
    ProbeConfig c;
    c.rays = 2000;
    c.seed = 7;
    c.angle_tolerance_px = angle;
    c.balance = CutBalance::Off;
    c.unreached_angle_allowance = allowance;
    // The position bound at outlines (OutlinesTakeAFractionOfTheTolerance)
    // would decide the few measured cells of this small teapot that the
    // angle bound decides without it: here the angle bounds alone are tested.
    c.outline_tolerance = 1;
    return run_probe(make_scene(type, kEye, kLook), one.stores(), one.objects(), c);
  };
  auto strict = probe(MaterialType::Mirror, 1), loose = probe(MaterialType::Mirror, 4);
  ASSERT_TRUE(strict && loose);
  const Cut &s = strict->cuts[0], &l = loose->cuts[0];
  EXPECT_NE(s.key, l.key);  // cached cuts do not mix
  for (const CollapsedCell& c : s.cells) EXPECT_TRUE(collapsed_by(l, c.key)) << "level " << c.key.level;
  size_t coarser = 0;
  for (const CollapsedCell& c : l.cells) {
    if (collapsed_by(s, c.key)) continue;
    ++coarser;
    // The stricter cut's cells inside c: some hold no hit, or they do not
    // cover c (the rest of c was kept whole, where a finest cell may hold
    // no hit).
    bool unreached_part = false;
    double covered = 0;  // the share of c the stricter cut's cells cover
    for (const CollapsedCell& d : s.cells) {
      if (d.key.level <= c.key.level || (d.key.code >> (3 * (d.key.level - c.key.level))) != c.key.code) continue;
      covered += std::ldexp(1.0, -3 * int(d.key.level - c.key.level));
      unreached_part = unreached_part || d.hits == 0;
    }
    EXPECT_TRUE(unreached_part || covered < 1 || c.hits == 0) << "level " << c.key.level << ", covered " << covered;
  }
  EXPECT_GT(coarser, 0u) << "a larger allowance should let unreached cells collapse further";
  EXPECT_LT(l.cells.size() + l.counters.at("cells_kept_for_normals"), s.cells.size() + s.counters.at("cells_kept_for_normals"));

  // Unreached cells held to 2 x 1 and to 1 x 2 pixel angles alike, measured
  // cells to 1 and to 2: the second cut is the looser, and not the same.
  auto measured_strict = probe(MaterialType::Mirror, 2, 1), measured_loose = probe(MaterialType::Mirror, 1, 2);
  ASSERT_TRUE(measured_strict && measured_loose);
  const Cut &ms = measured_strict->cuts[0], &ml = measured_loose->cuts[0];
  EXPECT_NE(cells_of(ms), cells_of(ml)) << "the measured cells' tolerance should move the cut";
  for (const CollapsedCell& c : ms.cells) EXPECT_TRUE(collapsed_by(ml, c.key)) << "level " << c.key.level;

  auto d1 = probe(MaterialType::Diffuse, 1), d2 = probe(MaterialType::Diffuse, 4);
  ASSERT_TRUE(d1 && d2);
  EXPECT_EQ(cells_of(d1->cuts[0]), cells_of(d2->cuts[0]));

  auto rejected = probe(MaterialType::Mirror, 0);
  ASSERT_FALSE(rejected);
  EXPECT_NE(rejected.status().message().find("allowance"), std::string::npos) << rejected.status().message();
}

// Unreached cells on a curved mirror or glass surface take the tilt c kappa
// f (probe.h), c calibrated on the measured cells, instead of the flat
// mirror's pixel angle alone: the bound only loosens (every cell the flat
// bound collapses stays collapsed, before grading, which may split a cell
// beside a region that now collapses finer than what was kept whole), it is
// what the normal bound then keeps fewer cells for, and with too few
// measured curved cells to calibrate on (three test rays) c is 0 and the
// cut is the flat bound's. The bound rises with c: a higher calibration
// quantile collapses every cell the lower one does, before grading
// (CutSelection.EverySelectionIsSelectCutsExactly: a selection prepared for
// one calibration refuses another).
TEST(ProbeDeviation, UnreachedCurvedGlassCellsTakeACalibratedTilt) {
  const OneObject one(teapot());
  auto probe = [&](bool curved, int rays, CutBalance balance) {
    ProbeConfig c;
    c.rays = rays;
    c.seed = 7;
    c.curved_unreached_tilt = curved;
    c.balance = balance;
    auto r = run_probe(make_scene(MaterialType::Glass, kEye, kLook), one.stores(), one.objects(), c);
    EXPECT_TRUE(r) << r.status().message();
    return r ? r->cuts[0] : Cut{};
  };
  const Cut flat = probe(false, 2000, CutBalance::Off), curved = probe(true, 2000, CutBalance::Off);
  ASSERT_FALSE(flat.cells.empty());
  EXPECT_EQ(flat.counters.count("curvature_factor_ppm"), 0u);
  EXPECT_GT(curved.counters.at("curvature_factor_ppm"), 0u);
  EXPECT_LT(curved.counters.at("cells_kept_for_normals"), flat.counters.at("cells_kept_for_normals"));
  for (const CollapsedCell& c : flat.cells) EXPECT_TRUE(collapsed_by(curved, c.key)) << "level " << c.key.level;
  EXPECT_NE(flat.key, curved.key);  // cached cuts do not mix
  // Graded (the default), the curved bound still keeps fewer cells whole.
  EXPECT_LT(probe(true, 2000, CutBalance::Specular).counters.at("finest_cells_kept"),
            probe(false, 2000, CutBalance::Specular).counters.at("finest_cells_kept"));

  const Cut few_flat = probe(false, 3, CutBalance::Specular), few = probe(true, 3, CutBalance::Specular);
  EXPECT_EQ(few.counters.at("curvature_factor_ppm"), 0u);
  EXPECT_EQ(cells_of(few), cells_of(few_flat));

  // c grows with the quantile it is read at, and the cut with it.
  ProbeConfig c;
  c.rays = 2000;
  c.seed = 7;
  c.balance = CutBalance::Off;
  c.calibration_quantile = 0.2;
  auto higher = run_probe(make_scene(MaterialType::Glass, kEye, kLook), one.stores(), one.objects(), c);
  ASSERT_TRUE(higher) << higher.status().message();
  const Cut& h = higher->cuts[0];
  EXPECT_GT(h.counters.at("curvature_factor_ppm"), curved.counters.at("curvature_factor_ppm"));
  EXPECT_LT(h.counters.at("cells_kept_for_normals"), curved.counters.at("cells_kept_for_normals"));
}

// The cut's pairs of touching cells more than one level apart
// (cut_grading_check.h).
size_t ungraded_pairs(const Cut& cut) {
  std::vector<CellKey> cells;
  int Q = 0;
  for (const CollapsedCell& c : cut.cells) {
    cells.push_back(c.key);
    Q = std::max(Q, int(c.key.level));
  }
  return test::ungraded_pairs(cells, Q);
}

// The cut is graded (no cut cell touches one two or more levels coarser)
// on mirrors and glass by default, where the normal bound applies; the
// grading only splits cells (every cell of the ungraded cut stays
// collapsed); a diffuse object's cut is graded only when asked (`all`);
// and the cut's key tells the modes apart where they differ.
TEST(ProbeDeviation, GlassCutsAreGradedDiffuseOnlyWhenAsked) {
  auto cut_with = [&](MaterialType type, CutBalance balance) {
    auto r = probe_teapot(type, 4, balance);
    EXPECT_TRUE(r) << r.status().message();
    return r ? r->cuts[0] : Cut{};
  };
  const Cut glass_off = cut_with(MaterialType::Glass, CutBalance::Off);
  const Cut glass = cut_with(MaterialType::Glass, CutBalance::Specular);
  ASSERT_FALSE(glass.cells.empty());
  EXPECT_GT(ungraded_pairs(glass_off), 0u) << "the test should start from a cut that is not graded";
  EXPECT_EQ(ungraded_pairs(glass), 0u);
  EXPECT_GT(glass.counters.at("cells_split_to_balance"), 0u);
  EXPECT_GT(glass.cells.size(), glass_off.cells.size());
  for (const CollapsedCell& c : glass.cells) EXPECT_TRUE(collapsed_by(glass_off, c.key)) << "level " << c.key.level;
  EXPECT_NE(glass.key, glass_off.key);

  const Cut diffuse_off = cut_with(MaterialType::Diffuse, CutBalance::Off);
  const Cut diffuse = cut_with(MaterialType::Diffuse, CutBalance::Specular);
  const Cut diffuse_all = cut_with(MaterialType::Diffuse, CutBalance::All);
  EXPECT_EQ(cells_of(diffuse), cells_of(diffuse_off));
  EXPECT_GT(ungraded_pairs(diffuse_off), 0u);
  EXPECT_EQ(ungraded_pairs(diffuse_all), 0u);
}

// Property: every cell the shared cut collapses is collapsed (itself or
// through an ancestor) by each view's own cut, for diffuse and glass (whose
// normal bound uses the tilt allowance too).
TEST(SharedCut, AtLeastAsFineAsEveryViewsOwnCutInEveryCell) {
  const Built& b = teapot();
  for (MaterialType type : {MaterialType::Diffuse, MaterialType::Glass}) {
    const Scene scene = make_scene(type, kEye, kLook);
    const SharedViews v = trace_views(scene, b, 2);
    const std::vector<ProbeView> views = v.views();
    auto shared = select(views, scene, b);
    ASSERT_TRUE(shared.is_ok()) << shared.status().message();
    const Cut& cut = shared->cuts[0];
    ASSERT_FALSE(cut.cells.empty());
    size_t finer_somewhere = 0;
    for (size_t i = 0; i < views.size(); ++i) {
      Scene s = scene;
      s.camera = v.cameras[i];
      auto own = select(std::span<const ProbeView>(&views[i], 1), s, b);
      ASSERT_TRUE(own.is_ok());
      for (const CollapsedCell& c : cut.cells)
        ASSERT_TRUE(collapsed_by(own->cuts[0], c.key)) << "view " << i << ": level " << c.key.level << " code " << c.key.code;
      finer_somewhere += cells_of(own->cuts[0]) != cells_of(cut);
    }
    EXPECT_GT(finer_somewhere, 0u) << "the views should not all need the same cut";
    EXPECT_EQ(cut.rays, 3 * shared_config().rays);
  }
}

TEST(SharedCut, SameForOneAndTwoThreadsAndAnyViewOrder) {
  const Built& b = teapot();
  const Scene scene = make_scene(MaterialType::Glass, kEye, kLook);
  const SharedViews one = trace_views(scene, b, 1), two = trace_views(scene, b, 2);
  const std::vector<ProbeView> v1 = one.views(), v2 = two.views();
  auto a = select(v1, scene, b, 1);
  auto c = select(v2, scene, b, 2);
  ASSERT_TRUE(a.is_ok() && c.is_ok());
  EXPECT_EQ(cells_of(a->cuts[0]), cells_of(c->cuts[0]));
  EXPECT_EQ(a->cuts[0].key, c->cuts[0].key);
  std::vector<ProbeView> reversed(v2.rbegin(), v2.rend());
  auto r = select(reversed, scene, b, 2);
  ASSERT_TRUE(r.is_ok());
  EXPECT_EQ(cells_of(r->cuts[0]), cells_of(a->cuts[0]));
}

// A view sequence's page cache (ProbeConfig::pages): a trace through a cache
// kept from an earlier trace gives the same hits as one with its own cache,
// and reads only the pages the earlier trace did not leave.
TEST(ProbeShares, KeptPageCacheGivesTheSameTraceAndReadsLess) {
  const Built& b = teapot();
  const Scene scene = make_scene(MaterialType::Glass, kEye, kLook);
  const OneObject one(b);
  const std::span<const ProbeStore> stores = one.stores();
  const std::span<const ProbeObject> objects = one.objects();
  ProbeConfig c;
  c.rays = 800;
  c.seed = 5;
  c.cache_bytes = 0;
  auto own = trace_probe(scene, stores, objects, c);
  ASSERT_TRUE(own) << own.status().message();
  ASSERT_GT(own->counters.at("pages_read"), 1u);

  PageCache kept(0);
  // Reading a page leaves the thread's scratch for the next one; a trace
  // frees it when it ends, so none of it outlasts the probe.
  ASSERT_TRUE(kept.get(*b.store, 0).is_ok());
  EXPECT_GT(kept.scratch_bytes(), 0u);
  kept.release_scratch();
  EXPECT_EQ(kept.scratch_bytes(), 0u);
  kept.clear();
  ProbeConfig shared = c;
  shared.pages = &kept;
  auto first = trace_probe(scene, stores, objects, shared);
  EXPECT_EQ(kept.scratch_bytes(), 0u);
  auto second = trace_probe(scene, stores, objects, shared);
  ASSERT_TRUE(first && second);
  EXPECT_EQ(first->counters.at("pages_read"), own->counters.at("pages_read"));
  EXPECT_EQ(second->counters.at("pages_read"), 0u);  // every page was kept
  EXPECT_GT(second->counters.at("cache_hits"), 0u);
  for (const ProbeTrace* t : {&first.value(), &second.value()}) {
    ASSERT_EQ(t->hits.size(), own->hits.size());
    for (size_t i = 0; i < t->hits.size(); ++i)
      ASSERT_TRUE(t->hits[i].corners == own->hits[i].corners && t->hits[i].footprint == own->hits[i].footprint) << i;
  }

  // Shrunk between traces, the cache keeps at most its capacity (and one
  // page), and the next trace reads the rest again.
  kept.set_capacity(1);
  EXPECT_LE(kept.counters().resident_bytes, kept.counters().peak_bytes);
  auto third = trace_probe(scene, stores, objects, shared);
  ASSERT_TRUE(third);
  EXPECT_GE(third->counters.at("pages_read") + 1, own->counters.at("pages_read"));
  kept.clear();
  EXPECT_EQ(kept.resident_bytes(), 0u);
}

// What `mpirun raylod probe` does: the test rays traced in shares (one per
// rank, here uneven and with different page caches) and merged give the
// trace of one process, and a cut file with the same bytes.
TEST(ProbeShares, MergedSharesGiveTheSameTraceAndCutFile) {
  const Built& b = teapot();
  const Scene scene = make_scene(MaterialType::Glass, kEye, kLook);
  const OneObject one(b);
  const std::span<const ProbeStore> stores = one.stores();
  const std::span<const ProbeObject> objects = one.objects();
  ProbeConfig c;
  c.rays = 1500;
  c.seed = 11;
  auto whole = trace_probe(scene, stores, objects, c);
  ASSERT_TRUE(whole) << whole.status().message();
  std::vector<ProbeTrace> shares;
  const std::pair<uint64_t, uint64_t> ranges[] = {{0, 1}, {1, 700}, {700, 700}, {700, 1500}};
  for (const auto& [first, end] : ranges) {
    ProbeConfig share = c;
    share.first_ray = first;
    share.end_ray = end;
    share.cache_bytes = first == 1 ? 1 : c.cache_bytes;  // one share re-reads every page
    auto t = trace_probe(scene, stores, objects, share);
    ASSERT_TRUE(t) << t.status().message();
    shares.push_back(std::move(t.value()));
  }
  EXPECT_EQ(shares[2].hits.size(), 0u);
  const ProbeTrace merged = merge_traces(std::move(shares), c);
  ASSERT_EQ(merged.hits.size(), whole->hits.size());
  size_t secondary = 0;
  for (size_t i = 0; i < merged.hits.size(); ++i) {
    const ProbeHit &x = merged.hits[i], &y = whole->hits[i];
    ASSERT_TRUE(x.object == y.object && x.corners == y.corners && x.footprint == y.footprint && x.ratio == y.ratio &&
                x.tilt == y.tilt && x.parent == y.parent && x.estimated == y.estimated)
        << "hit " << i;
    secondary += merged.hits[i].parent >= 0;
  }
  EXPECT_GT(secondary, 0u);  // parents are renumbered across shares
  EXPECT_EQ(merged.magnification, whole->magnification);
  for (const auto& [name, value] : whole->counters)
    if (!is_page_cache_counter(name)) {
      EXPECT_EQ(merged.counters.at(name), value) << name;
    }

  auto cut_whole = select_cuts(*whole, scene, stores, objects, c);
  auto cut_merged = select_cuts(merged, scene, stores, objects, c);
  ASSERT_TRUE(cut_whole && cut_merged);
  const fs::path a = tmp_dir() / "whole.cut", m = tmp_dir() / "merged.cut";
  ASSERT_TRUE(write_cut(a, cut_whole->cuts[0]));
  ASSERT_TRUE(write_cut(m, cut_merged->cuts[0]));
  auto slurp = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(slurp(a), slurp(m));
  EXPECT_FALSE(cut_whole->cuts[0].counters.count("pages_read"));  // how pages were read is not part of the cut
}

}  // namespace
}  // namespace raylod
