// A mesh 1e7 from zero with 1e-3 detail: a staircase of 1e-3 risers written
// as double PLY (the usual form of georeferenced scans and plant models).
// Floats near 1e7 are 1 apart, so reading it into floats would flatten it.
// Checked against double-precision brute force: the full render's depth at
// every pixel that brute force sees wholly on one face (its corner and
// centre rays hit the same tread or riser) lies within the depths of those
// rays, and pixels whose rays all miss the staircase's box stay empty. Then the whole of
// `raylod run` (build, probe, simplify, render) on the far staircase matches
// the same staircase near zero.
#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "geometry/pinhole_camera.h"
#include "pipeline/image_compare.h"
#include "pipeline/pipeline.h"
#include "probe/bvh.h"
#include "probe/store_tracer.h"
#include "render/renderer.h"
#include "scene/scene.h"
#include "streaming/draco_io.h"
#include "streaming/indexed_ply_writer.h"
#include "streaming/mesh_reader.h"
#include "streaming/octree_store.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// 12 steps along +x, each 4e-3 deep and 1e-3 high, 0.02 wide along z; local
// coordinates (the file holds origin + these, in double).
struct Staircase {
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
};

Staircase make_staircase() {
  Staircase s;
  auto quad = [&](Vec3 a, Vec3 b, Vec3 c, Vec3 d) {  // counter-clockwise seen from the front
    const uint32_t i = uint32_t(s.positions.size());
    s.positions.insert(s.positions.end(), {a, b, c, d});
    s.indices.insert(s.indices.end(), {i, i + 1, i + 2, i, i + 2, i + 3});
  };
  // Each tread in 4 x 16 quads and each riser in 16, so that cells away from
  // the open sides (z = 0 and z = width) can collapse.
  const float run = 4e-3f, rise = 1e-3f, width = 0.02f;
  const int nx = 4, nz = 16;
  for (int k = 0; k < 12; ++k) {
    const float y = rise * float(k);
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < nz; ++j) {
        const float x0 = run * (float(k) + float(i) / nx), x1 = run * (float(k) + float(i + 1) / nx);
        const float z0 = width * float(j) / nz, z1 = width * float(j + 1) / nz;
        quad({x0, y, z1}, {x1, y, z1}, {x1, y, z0}, {x0, y, z0});  // tread, facing +y
      }
    const float x = run * float(k + 1);
    for (int j = 0; j < nz; ++j) {
      const float z0 = width * float(j) / nz, z1 = width * float(j + 1) / nz;
      quad({x, y, z0}, {x, y + rise, z0}, {x, y + rise, z1}, {x, y, z1});  // riser, facing -x
    }
  }
  return s;
}

fs::path write_staircase(const fs::path& path, const Staircase& s, const Vec3d& origin) {
  IndexedPlyLayout layout;
  layout.vertex_count = s.positions.size();
  layout.face_count = s.indices.size() / 3;
  layout.normals = false;
  layout.origin = origin;
  auto w = IndexedPlyWriter::create(path, layout);
  EXPECT_TRUE(w.is_ok()) << w.status().message();
  EXPECT_TRUE((*w)->append_vertices(s.positions, {}).is_ok());
  EXPECT_TRUE((*w)->append_triangles(s.indices).is_ok());
  EXPECT_TRUE((*w)->finish().is_ok());
  return path;
}

Scene staircase_scene(const Vec3d& origin, const fs::path& mesh) {
  Scene s;
  s.camera.eye = origin + Vec3d(-0.025, 0.035, 0.045);
  s.camera.look_at = origin + Vec3d(0.022, 0.006, 0.01);
  s.camera.fov_y_deg = 40;
  s.camera.width = 120;
  s.camera.height = 90;
  Material m;
  m.type = MaterialType::Diffuse;
  m.color = Vec3(0.7f, 0.6f, 0.5f);
  s.materials = {m};
  SceneObject o;
  o.mesh = mesh;
  s.objects = {o};
  Light l;
  l.position = origin + Vec3d(0.1, 0.2, 0.15);
  l.intensity = 0.05f;
  s.lights = {l};
  s.background = Vec3(0.3f, 0.4f, 0.6f);
  s.spp = 1;
  s.seed = 3;
  return s;
}

TEST(FarFromOrigin, FullRenderAgreesWithDoublePrecisionBruteForce) {
  test::ScratchDir scratch("far-from-origin");
  const Vec3d origin(1e7 + 0.375, 1e7 + 0.5, -1e7 + 0.625);
  const Staircase stairs = make_staircase();
  const fs::path mesh = write_staircase(scratch.path / "far.ply", stairs, origin);
  const Scene scene = staircase_scene(origin, mesh);

  RenderOptions ro;
  ro.progress = false;
  ro.aov_depth = true;
  auto r = render(scene, ro);
  ASSERT_TRUE(r.is_ok()) << r.status().message();

  // The triangles as the file holds them, in double.
  std::vector<Vec3d> tri;
  for (uint32_t i : stairs.indices) tri.push_back(origin + Vec3d(stairs.positions[i]));
  const PinholeCamera cam = make_pinhole_camera(scene.camera.eye, scene.camera.look_at, scene.camera.up,
                                                scene.camera.fov_y_deg, scene.camera.width, scene.camera.height);
  // Which face of the staircase a triangle lies on: per step, 128 tread
  // triangles, then 32 riser triangles (make_staircase).
  auto face_of = [](int triangle) { return triangle < 0 ? -1 : 2 * (triangle / 160) + (triangle % 160 >= 128); };
  Bbox box;
  for (const Vec3d& p : tri) box.expand(p);
  auto misses_box = [&](double px, double py) {
    const Ray ray = cam.generate(px, py);
    double tnear;
    return !intersect_box(box, ray_box_precomp(ray.origin, ray.direction), 0.0, std::numeric_limits<double>::infinity(),
                          tnear);
  };
  struct BruteHit { int triangle = -1; double t = 0; };
  auto trace = [&](double px, double py) {
    const Ray ray = cam.generate(px, py);
    BruteHit best;
    double tmax = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < tri.size() / 3; ++k) {
      double t, b1, b2;
      if (intersect_triangle(ray.origin, ray.direction, tri[3 * k], tri[3 * k + 1], tri[3 * k + 2], 0.0, tmax, t, b1, b2)) {
        tmax = t;
        best = {int(k), t};
      }
    }
    return best;
  };
  int inside = 0, empty = 0, wrong = 0;
  std::string first_wrong;
  for (int y = 0; y < scene.camera.height; ++y)
    for (int x = 0; x < scene.camera.width; ++x) {
      const BruteHit h[5] = {trace(x, y), trace(x + 1, y), trace(x, y + 1), trace(x + 1, y + 1), trace(x + 0.5, y + 0.5)};
      const float depth = *r->depth.at(x, y);
      bool same = true;
      double lo = h[0].t, hi = h[0].t;
      for (const BruteHit& b : h) {
        same = same && face_of(b.triangle) == face_of(h[0].triangle) && b.triangle >= 0;
        lo = std::min(lo, b.t);
        hi = std::max(hi, b.t);
      }
      // Every ray through the pixel misses the staircase's box: so do its corners'.
      const bool none = misses_box(x, y) && misses_box(x + 1, y) && misses_box(x, y + 1) && misses_box(x + 1, y + 1);
      bool ok = true;
      if (same) {
        ++inside;
        // 1e-5: a hundredth of the staircase's detail; reading the file into
        // floats would move it by up to 0.5.
        ok = depth >= lo - 1e-5 && depth <= hi + 1e-5;
      } else if (none) {
        ++empty;
        ok = depth == 0.0f;
      }
      if (!ok && wrong++ == 0)
        first_wrong = "pixel (" + std::to_string(x) + ", " + std::to_string(y) + "): depth " + std::to_string(depth) +
                      ", brute force " + std::to_string(lo) + " .. " + std::to_string(hi) + (none ? " (empty)" : "");
    }
  const int pixels = scene.camera.width * scene.camera.height;
  EXPECT_EQ(wrong, 0) << first_wrong;
  // Over a thousand pixels lie wholly on one tread or riser, and the sky
  // fills most of the rest: both checks bite.
  EXPECT_GT(inside, pixels / 20);
  EXPECT_GT(empty, pixels / 10);
}

// stairs.ply in `dir` through a scene file: the camera, the object moved by
// `translate`, one light (its JSON object).
Scene stairs_scene_file(const fs::path& dir, const Vec3d& eye, const Vec3d& look, double fov_y, const Vec3d& translate,
                        const std::string& light) {
  char json[1024];
  std::snprintf(json, sizeof json,
                R"({"camera": {"eye": [%.17g, %.17g, %.17g], "look_at": [%.17g, %.17g, %.17g],
                    "fov_y": %.17g, "width": 120, "height": 90},
                    "materials": {"m": {"type": "diffuse", "color": [0.7, 0.6, 0.5]}},
                    "objects": [{"mesh": "stairs.ply", "material": "m",
                                 "transform": {"translate": [%.17g, %.17g, %.17g]}}],
                    "lights": [%s], "spp": 1, "seed": 3})",
                eye.x, eye.y, eye.z, look.x, look.y, look.z, fov_y, translate.x, translate.y, translate.z,
                light.c_str());
  auto s = parse_scene(json, dir, "stairs.json");
  EXPECT_TRUE(s.is_ok()) << s.status().message();
  return s.is_ok() ? *s : Scene{};
}

// PSNR of scene b's full render against scene a's.
double render_psnr(const Scene& a, const Scene& b) {
  RenderOptions ro;
  ro.progress = false;
  auto ra = render(a, ro);
  auto rb = render(b, ro);
  EXPECT_TRUE(ra.is_ok() && rb.is_ok());
  if (!ra.is_ok() || !rb.is_ok()) return 0;
  auto e = compare_images(rb->color, ra->color);
  EXPECT_TRUE(e.is_ok());
  return e.is_ok() ? e->psnr : 0;
}

// A scene file placing the staircase (0.05 across) 1000 units out, camera
// and light moved with it, renders as it does at zero: the renderer's frame
// is the look-at point rounded at any distance (render_origin_for). With a
// frame only from 4096 units out, Embree's floats near 1000 (6e-5 apart)
// gave jagged treads and self-shadowing.
TEST(FarFromOrigin, ParsedSceneAtAModerateOffsetRendersAsAtZero) {
  test::ScratchDir scratch("far-from-origin");
  write_staircase(scratch.path / "stairs.ply", make_staircase(), Vec3d(0));
  auto scene_at = [&](double d) {
    const Vec3d at(d), light = at + Vec3d(0.1, 0.2, 0.15);
    char point[160];
    std::snprintf(point, sizeof point, R"({"type": "point", "position": [%.17g, %.17g, %.17g], "intensity": 0.05})",
                  light.x, light.y, light.z);
    return stairs_scene_file(scratch.path, at + Vec3d(-0.025, 0.035, 0.045), at + Vec3d(0.022, 0.006, 0.01), 40, at,
                             point);
  };
  EXPECT_GT(render_psnr(scene_at(0), scene_at(1000)), 60.0);
}

// A telephoto view: the eye 2.3e6 staircase sizes away, the field of view
// narrowed to frame it as an eye 2,300 sizes away does. Camera rays start near
// the scene (camera_skip_for): from the eye, Embree's float direction was
// off by more than a tread, and the far view shattered into speckle.
TEST(FarFromOrigin, AFarCameraFramesAsANearOneDoes) {
  test::ScratchDir scratch("far-from-origin");
  write_staircase(scratch.path / "stairs.ply", make_staircase(), Vec3d(0));
  const Vec3d look(0.022, 0.006, 0.01), away = glm::normalize(Vec3d(-0.047, 0.029, 0.035));
  auto scene_at = [&](double distance) {
    const double fov = 2 * glm::degrees(std::atan(std::tan(glm::radians(20.0)) * 0.065 / distance));
    return stairs_scene_file(scratch.path, look + distance * away, look, fov, Vec3d(0),
                             R"({"type": "directional", "direction": [-0.3, -1, -0.5], "intensity": 1})");
  };
  // 39.9 dB; 10.2 dB with rays started at the eye.
  EXPECT_GT(render_psnr(scene_at(1.5e2), scene_at(1.5e5)), 30.0);
}

// A millimetre part a million units out, in a float32 PLY: the file itself
// holds one point. run leaves it out saying so, and names single
// precision's step there (0.0625) rather than only the store's grid.
TEST(FarFromOrigin, AFloatFileFarOutThatHoldsAPointSaysWhy) {
  test::ScratchDir scratch("far-float-point");
  const fs::path mesh = scratch.path / "far_f.ply";
  {
    // Binary float32, as CAD exports write: 1e6 + 0.001 rounds to 1e6.
    std::ofstream f(mesh, std::ios::binary);
    f << "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
         "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n";
    const double corners[4][3] = {{0, 0, 0}, {1e-3, 0, 0}, {0, 1e-3, 0}, {0, 0, 1e-3}};
    for (const auto& c : corners)
      for (double x : c) {
        const float v = float(1e6 + x);
        f.write(reinterpret_cast<const char*>(&v), sizeof v);
      }
    const int faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    for (const auto& t : faces) {
      const unsigned char n = 3;
      f.write(reinterpret_cast<const char*>(&n), 1);
      f.write(reinterpret_cast<const char*>(t), sizeof t);
    }
  }
  Scene scene = staircase_scene(Vec3d(1e6), mesh);
  RunOptions run;
  run.cache_dir = scratch.path / "cache";
  run.use_cache = false;
  run.progress = false;
  run.rays = 500;
  // Without a ground nothing is left to render: the reason is the error
  // (it said "the scene has no triangles").
  auto r = run_pipeline(scene, run, nullptr);
  ASSERT_FALSE(r.is_ok());
  const std::string why = r.status().message();
  EXPECT_NE(why.find("nothing to render: every object is left out: "), std::string::npos) << why;
  EXPECT_NE(why.find("single-precision coordinates this far from the origin are 0.0625 apart"), std::string::npos)
      << why;
  // With a ground, the run renders it and warns.
  scene.ground = Ground{1e6 - 0.01, 1.0, 0};
  auto grounded = run_pipeline(scene, run, nullptr);
  ASSERT_TRUE(grounded.is_ok()) << grounded.status().message();
  EXPECT_EQ(grounded->triangles_out, 0u);
  std::string all;
  for (const std::string& w : grounded->warnings) all += w + "\n";
  EXPECT_NE(all.find("single-precision coordinates this far from the origin are 0.0625 apart"), std::string::npos)
      << all;
}

TEST(FarFromOrigin, RunMatchesTheSameStaircaseNearZero) {
  test::ScratchDir scratch("far-from-origin");
  const Staircase stairs = make_staircase();
  // Each run against the full render of its own staircase.
  struct Ran {
    StatusOr<RunResult> run;
    double psnr = 0;
  };
  auto run_at = [&](const Vec3d& origin, const std::string& name) {
    const fs::path mesh = write_staircase(scratch.path / (name + ".ply"), stairs, origin);
    const Scene scene = staircase_scene(origin, mesh);
    RunOptions run;
    run.export_mesh = scratch.path / (name + ".glb");
    run.cache_dir = scratch.path / "cache";
    run.use_cache = true;  // keeps the .drc (in the scratch cache) to look at
    run.progress = false;
    run.rays = 2000;
    Ran out{run_pipeline(scene, run, nullptr)};
    EXPECT_TRUE(out.run.is_ok()) << out.run.status().message();
    RenderOptions ro;
    ro.progress = false;
    auto full = render(scene, ro);
    EXPECT_TRUE(full.is_ok()) << full.status().message();
    if (out.run.is_ok() && full.is_ok()) {
      auto e = compare_images(out.run->render.color, full->color);
      EXPECT_TRUE(e.is_ok());
      if (e.is_ok()) out.psnr = e->psnr;
    }
    return out;
  };
  // The near mesh is read as floats of its coordinates, the far one relative
  // to its rounded first vertex; the octree cells differ where a vertex lies
  // on a cell face, so the two cuts are alike, not the same.
  const Vec3d far_origin(1e7 + 0.375, 1e7 + 0.5, -1e7 + 0.625);
  Ran near = run_at(Vec3d(0), "near");
  Ran far = run_at(far_origin, "far");
  ASSERT_TRUE(near.run.is_ok() && far.run.is_ok());
  EXPECT_EQ(far.run->triangles_in, stairs.indices.size() / 3);
  // Cells away from the open sides collapse, in both.
  EXPECT_LT(far.run->triangles_out, far.run->triangles_in);
  EXPECT_NEAR(double(far.run->triangles_out), double(near.run->triangles_out), 0.1 * double(near.run->triangles_out));
  // As close to its full render as the near run is to its own.
  EXPECT_GT(far.psnr, 30.0);
  EXPECT_NEAR(far.psnr, near.psnr, 3.0) << "far " << far.run->triangles_out << " triangles, near "
                                        << near.run->triangles_out;

  // The exported .glb places the far staircase where it is (its node
  // carries the mesh origin, and the glTF reader keeps positions relative to
  // the node's translation): the same bounds as the simplified mesh, to the
  // float precision of the staircase's own size.
  auto exported = summarize_mesh(scratch.path / "far.glb");
  ASSERT_TRUE(exported.is_ok()) << exported.status().message();
  EXPECT_NE(exported->header.origin, Vec3d(0));
  const Vec3d centre = far_origin + Vec3d(0.024, 0.006, 0.01);
  EXPECT_LT(glm::length(exported->bounds.center() - centre), 1e-3)
      << "exported at " << exported->bounds.center().x << ", " << exported->bounds.center().y << ", "
      << exported->bounds.center().z;

  // The store and the simplified mesh carry the mesh origin.
  auto store = OctreeStore::open(scratch.path / "far.ply.raylod");
  ASSERT_TRUE(store.is_ok()) << store.status().message();
  const Vec3d mesh_origin = (*store)->header().mesh_origin;
  EXPECT_EQ(mesh_origin, Vec3d(std::round(far_origin.x), std::round(far_origin.y), std::round(far_origin.z)));
  // The cache holds the two simplified meshes: the near one at (0, 0, 0) (it
  // lies near zero), the far one relative to the mesh origin.
  std::vector<Vec3d> origins;
  for (const auto& entry : fs::recursive_directory_iterator(scratch.path / "cache"))
    if (entry.path().extension() == ".drc") {
      auto drc = read_draco(entry.path());
      ASSERT_TRUE(drc.is_ok()) << drc.status().message();
      origins.push_back(drc->origin);
    }
  ASSERT_EQ(origins.size(), 2u);
  EXPECT_TRUE((origins[0] == Vec3d(0) && origins[1] == mesh_origin) || (origins[1] == Vec3d(0) && origins[0] == mesh_origin));
}

}  // namespace
}  // namespace raylod
