// bench_render: what the renderer costs, per stage and per ray kind.
//
//   bench_render [--width 1280] [--height 960] [--spp 1] [--runs 3] [--bvh-quality auto] [--json FILE] MESH...
//
// For each MESH, renders the default scene (glossy teapot on a diffuse floor,
// a point and a directional light) with MESH as the teapot and reports: mesh
// load time, BVH build time and memory, render time (median of --runs) with
// rays by kind, for
//   full          the default scene (diffuse + glossy highlights + shadows)
//   diffuse-only  every material made diffuse (no highlights; same rays)
//   camera-only   no lights: the integrator traces camera rays only
//   camera-single the same with RenderOptions::camera_packets off (one
//                 rtcIntersect1 per camera ray, as before packets)
// and two minimal loops over the same Embree scene without the integrator:
//   primary-1     rtcIntersect1, one ray per pixel centre (same camera mapping)
//   primary-16    rtcIntersect16, 4x4 pixel packets
// The camera-ray ratio -- camera-only camera rays/s over primary-1 rays/s,
// the renderer against its bare Embree loop on the same mesh and camera --
// is printed and written to the JSON (target >= 0.85). camera-only,
// camera-single, primary-1 and primary-16 run interleaved, run after run, so
// that load from other processes falls on all of them alike. Shadow rays/s
// is derived as shadow rays / (diffuse-only - camera-only render time).
// The BVH is the one `raylod render` builds for one frame of this size
// (--bvh-quality auto; render/embree_scene.h) unless --bvh-quality names one.
// Everything runs on all hardware threads (TBB).
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include "core/progress.h"
#include "core/system.h"
#include "scene/scene_camera.h"
#include "render/renderer.h"

using namespace raylod;

namespace {

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : (v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]));
}

// Primary rays through pixel centres with rtcIntersect1; returns hits.
uint64_t primary_loop_1(const EmbreeScene& geometry, const PinholeCamera& cam) {
  std::atomic<uint64_t> hits{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, cam.height, 4), [&](const tbb::blocked_range<int>& r) {
    uint64_t local = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (int y = r.begin(); y != r.end(); ++y)
      for (int x = 0; x < cam.width; ++x) {
        const Ray ray = cam.generate(x + 0.5, y + 0.5);
        RTCRayHit rh;
        rh.ray.org_x = float(ray.origin.x); rh.ray.org_y = float(ray.origin.y); rh.ray.org_z = float(ray.origin.z);
        rh.ray.dir_x = float(ray.direction.x); rh.ray.dir_y = float(ray.direction.y); rh.ray.dir_z = float(ray.direction.z);
        rh.ray.tnear = 0; rh.ray.tfar = std::numeric_limits<float>::infinity();
        rh.ray.time = 0; rh.ray.mask = 0xffffffffu; rh.ray.id = 0; rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(geometry.handle(), &ctx, &rh);
        local += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    hits += local;
  });
  return hits;
}

// The same rays as 4x4 pixel packets with rtcIntersect16.
uint64_t primary_loop_16(const EmbreeScene& geometry, const PinholeCamera& cam) {
  std::atomic<uint64_t> hits{0};
  const int bx = (cam.width + 3) / 4, by = (cam.height + 3) / 4;
  tbb::parallel_for(tbb::blocked_range<int>(0, by, 1), [&](const tbb::blocked_range<int>& r) {
    uint64_t local = 0;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    for (int py = r.begin(); py != r.end(); ++py)
      for (int px = 0; px < bx; ++px) {
        for (int k = 0; k < 16; ++k) {
          const int x = px * 4 + (k & 3), y = py * 4 + (k >> 2);
          valid[k] = (x < cam.width && y < cam.height) ? -1 : 0;
          const Ray ray = cam.generate(std::min(x, cam.width - 1) + 0.5, std::min(y, cam.height - 1) + 0.5);
          rh.ray.org_x[k] = float(ray.origin.x); rh.ray.org_y[k] = float(ray.origin.y); rh.ray.org_z[k] = float(ray.origin.z);
          rh.ray.dir_x[k] = float(ray.direction.x); rh.ray.dir_y[k] = float(ray.direction.y); rh.ray.dir_z[k] = float(ray.direction.z);
          rh.ray.tnear[k] = 0; rh.ray.tfar[k] = std::numeric_limits<float>::infinity();
          rh.ray.time[k] = 0; rh.ray.mask[k] = 0xffffffffu; rh.ray.id[k] = unsigned(k); rh.ray.flags[k] = 0;
          rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect16(valid, geometry.handle(), &ctx, &rh);
        for (int k = 0; k < 16; ++k) local += valid[k] && rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
      }
    hits += local;
  });
  return hits;
}

struct Variant {
  std::string name;
  RenderStats stats;
  double seconds = 0;  // median render time
};

Variant run_variant(const std::string& name, const EmbreeScene& geometry, const Scene& scene, const RenderOptions& o,
                    int runs) {
  Variant v{name, {}, 0};
  std::vector<double> t;
  for (int i = 0; i < runs; ++i) {
    RenderResult r = render_embree_scene(geometry, scene, o);
    t.push_back(r.stats.render_seconds);
    v.stats = r.stats;
  }
  v.seconds = median(t);
  return v;
}

void print_variant(const Variant& v) {
  const RayCounters& c = v.stats.rays;
  std::printf("  %-13s render %7.3f s  rays: camera %9llu  shadow %9llu  reflection %llu  refraction %llu  "
              "total %6.2f Mrays/s  camera %6.2f Mrays/s\n",
              v.name.c_str(), v.seconds, (unsigned long long)c.camera, (unsigned long long)c.shadow,
              (unsigned long long)c.reflection, (unsigned long long)c.refraction, c.total() / v.seconds * 1e-6,
              c.camera / v.seconds * 1e-6);
}

nlohmann::json variant_json(const Variant& v) {
  const RayCounters& c = v.stats.rays;
  return {{"render_seconds_median", v.seconds},
          {"effects", v.stats.effects.describe()},
          {"rays", {{"camera", c.camera}, {"shadow", c.shadow}, {"reflection", c.reflection}, {"refraction", c.refraction}}},
          {"rays_per_second", c.total() / v.seconds}};
}

}  // namespace

int main(int argc, char** argv) {
  int width = 1280, height = 960, spp = 1, runs = 3;
  std::string bvh_quality = "auto";  // auto: what raylod render builds for one frame of this size
  std::string json_path;
  std::vector<std::string> meshes;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) { std::fprintf(stderr, "bench_render: %s needs a value\n", a.c_str()); std::exit(2); }
      return argv[++i];
    };
    if (a == "--width") width = std::stoi(next());
    else if (a == "--height") height = std::stoi(next());
    else if (a == "--spp") spp = std::stoi(next());
    else if (a == "--runs") runs = std::max(1, std::stoi(next()));
    else if (a == "--json") json_path = next();
    else if (a == "--bvh-quality") {
      bvh_quality = next();
      if (bvh_quality != "auto" && bvh_quality != "low" && bvh_quality != "medium" && bvh_quality != "high") {
        std::fprintf(stderr, "bench_render: --bvh-quality takes auto, low, medium or high, not '%s'\n", bvh_quality.c_str());
        return 2;
      }
    }
    else if (a == "-h" || a == "--help") {
      std::printf("usage: bench_render [--width W] [--height H] [--spp N] [--runs R] [--bvh-quality auto|low|medium|high] [--json FILE] MESH...\n");
      return 0;
    } else meshes.push_back(a);
  }
  if (meshes.empty()) {
    std::fprintf(stderr, "bench_render: give at least one mesh file (e.g. /tmp/raylod-h2/teapot-1M.ply)\n");
    return 2;
  }
  Progress::set_enabled(false);
  nlohmann::json all = nlohmann::json::array();
  for (const std::string& mesh : meshes) {
    auto base = default_scene();
    if (!base) { std::fprintf(stderr, "bench_render: %s\n", base.status().message().c_str()); return 1; }
    Scene scene = *base;
    scene.objects[0].mesh = mesh;
    scene.objects[0].generate.reset();
    scene.camera.width = width;
    scene.camera.height = height;
    scene.spp = spp;
    RenderOptions o;
    o.progress = false;

    RenderStats load_stats;
    const double t0 = now_seconds();
    BvhConfig bvh;  // what `raylod render` builds for one frame of this size
    auto loaded = load_scene_meshes(scene, o, load_stats, &bvh);
    if (!loaded) { std::fprintf(stderr, "bench_render: %s\n", loaded.status().message().c_str()); return 1; }
    const double load_s = now_seconds() - t0;
    const uint64_t rss_after_load = current_rss_bytes();
    if (bvh_quality == "low" || bvh_quality == "medium") {
      bvh.high_quality_below = 0;
      bvh.camera_rays = bvh_quality == "low" ? 1 : 0;  // any rays below the triangle count; 0 = unknown
    } else if (bvh_quality == "high") {
      bvh.high_quality_below = UINT64_MAX;
    }
    auto geometry = EmbreeScene::build(std::move(*loaded), bvh);
    if (!geometry) { std::fprintf(stderr, "bench_render: %s\n", geometry.status().message().c_str()); return 1; }
    const BvhInfo& info = (*geometry)->info();

    std::printf("%s: %llu triangles, %llu vertices, %dx%d, %d spp, %d threads\n", mesh.c_str(),
                (unsigned long long)info.triangles, (unsigned long long)info.vertices, width, height, spp,
                int(tbb::this_task_arena::max_concurrency()));
    std::printf("  load %.3f s (%.2f Mtriangles/s)  mesh arrays %s  RSS after load %s\n", load_s,
                info.triangles / load_s * 1e-6, format_bytes(info.mesh_bytes).c_str(),
                format_bytes(rss_after_load).c_str());
    std::printf("  BVH %.3f s (%s, %.2f Mtriangles/s)  BVH %s (%.1f B/triangle), build peak %s (%.1f B/triangle)\n",
                info.build_seconds, info.quality.c_str(), info.triangles / info.build_seconds * 1e-6,
                format_bytes(info.bvh_bytes).c_str(), double(info.bvh_bytes) / info.triangles,
                format_bytes(info.bvh_peak_bytes).c_str(), double(info.bvh_peak_bytes) / info.triangles);
    std::printf("  estimate_render_memory %s vs measured mesh + build peak %s\n",
                format_bytes(load_stats.estimated_bytes).c_str(),
                format_bytes(info.mesh_bytes + info.bvh_peak_bytes).c_str());

    Scene diffuse = scene;
    for (Material& m : diffuse.materials) { m.type = MaterialType::Diffuse; m.specular = Vec3(0.0f); }
    Scene camera_only = diffuse;
    camera_only.lights.clear();
    const Variant full = run_variant("full", **geometry, scene, o, runs);
    const Variant diff = run_variant("diffuse-only", **geometry, diffuse, o, runs);
    print_variant(full);
    print_variant(diff);

    // Side by side: the renderer's camera rays (packets and single) and the
    // bare loops, interleaved within each run.
    // The geometry is in the render frame (in_render_frame), so is the camera.
    const PinholeCamera pc = make_pinhole_camera(in_render_frame(scene).camera);
    RenderOptions single = o;
    single.camera_packets = false;
    Variant cam{"camera-only", {}, 0}, cam1{"camera-single", {}, 0};
    std::vector<double> tc, tc1, t1, t16;
    uint64_t hits1 = 0, hits16 = 0;
    for (int r = 0; r < runs; ++r) {
      RenderResult rc = render_embree_scene(**geometry, camera_only, o);
      tc.push_back(rc.stats.render_seconds);
      cam.stats = rc.stats;
      RenderResult rc1 = render_embree_scene(**geometry, camera_only, single);
      tc1.push_back(rc1.stats.render_seconds);
      cam1.stats = rc1.stats;
      double s = now_seconds();
      hits1 = primary_loop_1(**geometry, pc);
      t1.push_back(now_seconds() - s);
      s = now_seconds();
      hits16 = primary_loop_16(**geometry, pc);
      t16.push_back(now_seconds() - s);
    }
    cam.seconds = median(tc);
    cam1.seconds = median(tc1);
    print_variant(cam);
    print_variant(cam1);
    const double pixels = double(width) * height;
    const double m1 = median(t1), m16 = median(t16);
    std::printf("  primary-1     %7.3f s  %6.2f Mrays/s (%llu hits)\n", m1, pixels / m1 * 1e-6, (unsigned long long)hits1);
    std::printf("  primary-16    %7.3f s  %6.2f Mrays/s (%llu hits)\n", m16, pixels / m16 * 1e-6, (unsigned long long)hits16);
    const double cam_rate = cam.stats.rays.camera / cam.seconds;
    const double cam1_rate = cam1.stats.rays.camera / cam1.seconds;
    const double ratio = cam_rate / (pixels / m1), ratio16 = cam_rate / (pixels / m16);
    const double shadow_rate = diff.seconds > cam.seconds ? diff.stats.rays.shadow / (diff.seconds - cam.seconds) : 0;
    std::printf("  camera-ray ratio (renderer camera-only / bare rtcIntersect1 loop): %.2fx (%.2f / %.2f Mrays/s; "
                "target >= 0.85x)\n", ratio, cam_rate * 1e-6, pixels / m1 * 1e-6);
    std::printf("  against the bare rtcIntersect16 loop: %.2fx; single-ray renderer path: %.2fx of primary-1\n",
                ratio16, cam1_rate / (pixels / m1));
    std::printf("  shadow rays (derived) %.2f Mrays/s\n", shadow_rate * 1e-6);
    std::printf("  peak RSS %s\n", format_bytes(peak_rss_bytes()).c_str());

    all.push_back({{"mesh", mesh},
                   {"triangles", info.triangles},
                   {"width", width}, {"height", height}, {"spp", spp}, {"runs", runs},
                   {"load_seconds", load_s},
                   {"bvh", {{"seconds", info.build_seconds}, {"quality", info.quality}, {"bytes", info.bvh_bytes},
                            {"build_peak_bytes", info.bvh_peak_bytes}}},
                   {"mesh_bytes", info.mesh_bytes},
                   {"estimated_bytes", load_stats.estimated_bytes},
                   {"full", variant_json(full)},
                   {"diffuse_only", variant_json(diff)},
                   {"camera_only", variant_json(cam)},
                   {"camera_single_rays", variant_json(cam1)},
                   {"camera_ray_ratio_to_primary_1", ratio},
                   {"camera_ray_ratio_to_primary_16", ratio16},
                   {"primary_1", {{"seconds_median", m1}, {"rays_per_second", pixels / m1}}},
                   {"primary_16", {{"seconds_median", m16}, {"rays_per_second", pixels / m16}}},
                   {"shadow_rays_per_second_derived", shadow_rate},
                   {"peak_rss_bytes", peak_rss_bytes()}});
    std::fflush(stdout);
  }
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    f << all.dump(2) << "\n";
  }
  return 0;
}
