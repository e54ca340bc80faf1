// Whitted-style integrator (Whitted 1980) with exact dielectric Fresnel
// terms; see integrator.h for which effects exist and when they switch on.
#include "render/integrator.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace raylod {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
bool nonzero(const Vec3& c) { return c.x > 0 || c.y > 0 || c.z > 0; }

// Starts the shading fetches of a packet's hits at once -- index rows, then
// the corners' positions and normals -- so that their cache misses overlap
// instead of stalling surface_point() lane after lane (on large meshes these
// fetches, not the traversal, are most of the cost of a camera ray).
void prefetch_indices(const EmbreeScene& geometry, const Hit* hits, const bool* found, int n) {
  for (int i = 0; i < n; ++i)
    if (found[i]) __builtin_prefetch(&geometry.mesh(hits[i].geom).indices[size_t(hits[i].prim) * 3]);
}

void prefetch_vertices(const EmbreeScene& geometry, const Hit* hits, const bool* found, int n) {
  for (int i = 0; i < n; ++i) {
    if (!found[i]) continue;
    const TriangleMesh& m = geometry.mesh(hits[i].geom);
    const uint32_t* tri = &m.indices[size_t(hits[i].prim) * 3];
    for (int k = 0; k < 3; ++k) {
      __builtin_prefetch(&m.positions[tri[k]]);
      if (!m.normals.empty()) __builtin_prefetch(&m.normals[tri[k]]);
    }
  }
}
}  // namespace

std::string Effects::describe() const {
  std::string s;
  auto add = [&](const std::string& e) { s += (s.empty() ? "" : ", ") + e; };
  if (diffuse) add("diffuse");
  if (glossy) add("glossy highlights");
  if (shadows) add("shadows (" + std::to_string(lights) + (lights == 1 ? " light)" : " lights)"));
  if (reflection) add("reflection");
  if (refraction) add("refraction");
  return s.empty() ? "ambient only" : s;
}

Effects effects_for(const Scene& scene, std::span<const int> used_materials) {
  Effects e;
  e.lights = int(scene.lights.size());
  const bool lit = !scene.lights.empty();
  const bool bounces = scene.max_depth > 0;
  for (int idx : used_materials) {
    const Material& m = scene.materials.at(size_t(idx));
    if (lit && nonzero(m.color)) e.diffuse = true;
    if (lit && nonzero(m.specular)) e.glossy = true;
    if (bounces && m.type == MaterialType::Mirror && m.reflectance > 0) e.reflection = true;
    // Glass of ior 1 reflects nothing (Fresnel's term is 0, no total
    // internal reflection); glass of tint 0 passes no light through.
    if (bounces && m.type == MaterialType::Glass) {
      if (m.ior != 1.0f) e.reflection = true;
      if (nonzero(m.tint)) e.refraction = true;
    }
  }
  e.shadows = e.diffuse || e.glossy;
  return e;
}

double ray_offset(const Vec3d& p, double offset_scale, double offset_floor) {
  return offset_scale * std::max({offset_floor, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
}

SpecularScatter scatter_specular(const Material& m, const Vec3d& dir, const SurfacePoint& sp, double offset) {
  SpecularScatter s;
  const FacingNormals f = facing_normals(dir, sp.geometric, sp.shading);
  s.entering = f.entering;
  const Vec3d above = sp.position + offset * f.geometric, below = sp.position - offset * f.geometric;
  s.reflected = Ray{above, specular_reflection(dir, f).direction};

  if (m.type == MaterialType::Mirror) {
    s.reflects = m.reflectance > 0;
    s.reflect_weight = Vec3(m.reflectance);
    return s;
  }
  if (m.type != MaterialType::Glass) return s;

  const double eta = dielectric_eta(s.entering, m.ior);
  const SpecularRefraction t = specular_refraction(dir, f, eta);
  s.reflects = true;
  if (!t.ok) {
    s.total_internal_reflection = true;
    s.reflect_weight = Vec3(1.0f);
    return s;
  }
  const double fr = fresnel_dielectric(-glm::dot(dir, t.normal), eta);
  s.reflect_weight = Vec3(float(fr));
  s.refracts = true;
  s.refracted = Ray{below, t.direction};
  // The tint is applied once per pass through the glass, on the way in.
  s.refract_weight = float(1.0 - fr) * (s.entering ? m.tint : Vec3(1.0f));
  return s;
}

Integrator::Integrator(const EmbreeScene& geometry, const Scene& scene, const PinholeCamera& camera,
                       const Effects& effects, const IntegratorConfig& config)
    : geometry_(geometry), scene_(scene), camera_(camera), effects_(effects), config_(config),
      camera_skip_(camera_skip_for(camera.eye, geometry.info().bounds)) {}

double camera_skip_for(const Vec3d& eye, const Bbox& bounds) {
  if (bounds.empty() || !is_finite(eye)) return 0;
  const Vec3d nearest = glm::clamp(eye, bounds.lo, bounds.hi);
  const double distance = glm::length(eye - nearest), diagonal = glm::length(bounds.hi - bounds.lo);
  if (!(distance > 8 * diagonal)) return 0;
  return distance - diagonal;  // a diagonal short of the box: well clear of rounding
}

template <class Emit>
void Integrator::shadow_queries(const Material& m, const Vec3d& dir, const SurfacePoint& sp, double offset,
                                Emit&& emit) const {
  // Opaque shading is two-sided: light the side the ray came from.
  const Vec3d ng = glm::dot(dir, sp.geometric) < 0 ? sp.geometric : -sp.geometric;
  const Vec3d ns = glm::dot(dir, sp.shading) < 0 ? sp.shading : -sp.shading;
  const Vec3d& p = sp.position;
  const bool diffuse = effects_.diffuse && nonzero(m.color);
  const bool glossy = effects_.glossy && nonzero(m.specular);
  for (const Light& light : scene_.lights) {
    Vec3d l;
    double dist;
    Vec3 e = light.color * light.intensity;
    if (light.type == LightType::Point) {
      l = light.position - p;
      dist = glm::length(l);
      if (!(dist > 0)) continue;
      l /= dist;
      e /= float(dist * dist);
    } else {
      l = -light.direction;
      dist = kInf;
    }
    // A light behind the surface contributes nothing: no shadow ray for it.
    if (glm::dot(l, ng) <= 0) continue;
    // Light below the shading normal's horizon: neither term (Phong included).
    const double cos_theta = glm::dot(ns, l);
    if (cos_theta <= 0) continue;
    double spec = 0;
    if (glossy) spec = std::pow(std::max(0.0, glm::dot(reflect(-l, ns), -dir)), double(m.shininess));
    Vec3 c(0.0f);
    if (diffuse) c += m.color * float(cos_theta);
    if (spec > 0) c += m.specular * float(spec);
    emit(ShadowQuery{Ray{p + offset * ng, l}, std::isfinite(dist) ? dist - 2 * offset : kInf, c * e});
  }
}

CameraSample Integrator::sample(double px, double py, RayCounters& counters) const {
  CameraSample out;
  const Ray ray = camera_.generate(px, py);
  ++counters.camera;
  Hit hit;
  Ray start = ray;
  start.origin += camera_skip_ * ray.direction;
  if (!geometry_.intersect(start, 0.0, kInf, hit)) {
    out.color = scene_.background;
    return out;
  }
  hit.t += camera_skip_;
  const SurfacePoint sp = surface_point(geometry_, hit, config_.wireframe);
  record_camera_hit(ray, hit, sp, out);
  out.color = shade(ray, hit, sp, 0, Vec3(1.0f), counters);
  apply_wireframe(hit, sp, out);
  return out;
}

void Integrator::trace_camera_packet(std::span<const glm::dvec2> pixels, CameraPacket& packet,
                                     RayCounters& counters) const {
  assert(pixels.size() <= size_t(EmbreeScene::kPacketSize));
  const int n = packet.size = int(pixels.size());
  for (int i = 0; i < n; ++i) packet.rays[i] = camera_.generate(pixels[size_t(i)].x, pixels[size_t(i)].y);
  counters.camera += uint64_t(n);
  if (camera_skip_ > 0) {
    Ray start[EmbreeScene::kPacketSize];
    for (int i = 0; i < n; ++i) {
      start[i] = packet.rays[i];
      start[i].origin += camera_skip_ * start[i].direction;
    }
    geometry_.intersect_packet({start, size_t(n)}, kInf, true, packet.hits, packet.found);
    for (int i = 0; i < n; ++i)
      if (packet.found[i]) packet.hits[i].t += camera_skip_;
  } else {
    geometry_.intersect_packet({packet.rays, size_t(n)}, kInf, true, packet.hits, packet.found);
  }
  prefetch_indices(geometry_, packet.hits, packet.found, n);
}

void Integrator::prefetch_camera_vertices(const CameraPacket& packet) const {
  prefetch_vertices(geometry_, packet.hits, packet.found, packet.size);
}

void Integrator::shade_camera_packet(const CameraPacket& packet, CameraSample* out, RayCounters& counters) const {
  constexpr int kMax = EmbreeScene::kPacketSize;
  const int n = packet.size;
  const Ray* rays = packet.rays;
  const Hit* hits = packet.hits;
  const bool* found = packet.found;

  // Surface terms per lane; the shadow rays of all lanes, lane by lane and in
  // light order, so that each lane sums its lights in the order shade() does.
  SurfacePoint sp[kMax];
  double offset[kMax];
  // Kept by the thread from packet to packet: grown once, not per packet.
  thread_local std::vector<ShadowQuery> queries;
  thread_local std::vector<int> query_lane;
  queries.clear();
  query_lane.clear();
  surface_points(geometry_, {hits, size_t(n)}, found, config_.wireframe, sp);
  for (int i = 0; i < n; ++i) {
    out[i] = CameraSample{};
    if (!found[i]) {
      out[i].color = scene_.background;
      continue;
    }
    record_camera_hit(rays[i], hits[i], sp[i], out[i]);
    const Material& m = material(hits[i]);
    offset[i] = ray_offset(sp[i].position, config_.offset_scale, config_.offset_floor);
    out[i].color = ambient(m);
    if (!lit(m)) continue;
    shadow_queries(m, rays[i].direction, sp[i], offset[i], [&](const ShadowQuery& q) {
      queries.push_back(q);
      query_lane.push_back(i);
    });
  }
  Vec3 direct[kMax];
  std::fill(direct, direct + kMax, Vec3(0.0f));
  counters.shadow += queries.size();
  for (size_t first = 0; first < queries.size(); first += kMax) {
    const size_t count = std::min(queries.size() - first, size_t(kMax));
    Ray shadow[kMax];
    double tfar[kMax];
    bool occluded[kMax];
    for (size_t k = 0; k < count; ++k) {
      shadow[k] = queries[first + k].ray;
      tfar[k] = queries[first + k].tfar;
    }
    geometry_.occluded_packet({shadow, count}, tfar, occluded);
    for (size_t k = 0; k < count; ++k)
      if (!occluded[k]) direct[query_lane[first + k]] += queries[first + k].contribution;
  }
  for (int i = 0; i < n; ++i) {
    if (!found[i]) continue;
    const Material& m = material(hits[i]);
    if (lit(m)) out[i].color += direct[i];
    add_specular(out[i].color, m, rays[i].direction, sp[i], offset[i], 0, Vec3(1.0f), counters);
    apply_wireframe(hits[i], sp[i], out[i]);
  }
}

void Integrator::record_camera_hit(const Ray& ray, const Hit& hit, const SurfacePoint& sp, CameraSample& out) const {
  out.hit = true;
  out.depth = hit.t;
  out.triangle = geometry_.triangle_id(hit.geom, hit.prim);
  const Vec3d n = glm::dot(sp.shading, ray.direction) < 0 ? sp.shading : -sp.shading;
  out.normal = Vec3(n);
}

void Integrator::apply_wireframe(const Hit& hit, const SurfacePoint& sp, CameraSample& out) const {
  if (config_.wireframe && sp.edge_distance < 0.5 * hit.t * camera_.pixel_angle()) out.color *= 0.12f;
}

Vec3 Integrator::radiance(const Ray& ray, int depth, const Vec3& throughput, RayCounters& counters) const {
  Hit hit;
  if (!geometry_.intersect(ray, 0.0, kInf, hit)) return scene_.background;
  return shade(ray, hit, surface_point(geometry_, hit), depth, throughput, counters);
}

const Material& Integrator::material(const Hit& hit) const {
  return scene_.materials[size_t(geometry_.mesh(hit.geom).material)];
}

Vec3 Integrator::ambient(const Material& m) const {
  Vec3 result(0.0f);
  if (nonzero(m.color)) result += config_.ambient * scene_.background * m.color;
  return result;
}

bool Integrator::lit(const Material& m) const {
  return (effects_.diffuse && nonzero(m.color)) || (effects_.glossy && nonzero(m.specular));
}

Vec3 Integrator::shade(const Ray& ray, const Hit& hit, const SurfacePoint& sp, int depth, const Vec3& throughput,
                       RayCounters& counters) const {
  const Material& m = material(hit);
  const double offset = ray_offset(sp.position, config_.offset_scale, config_.offset_floor);
  Vec3 result = ambient(m);
  if (lit(m)) {
    Vec3 direct(0.0f);
    shadow_queries(m, ray.direction, sp, offset, [&](const ShadowQuery& q) {
      ++counters.shadow;
      if (!geometry_.occluded(q.ray, 0.0, q.tfar)) direct += q.contribution;
    });
    result += direct;
  }
  add_specular(result, m, ray.direction, sp, offset, depth, throughput, counters);
  return result;
}

void Integrator::add_specular(Vec3& result, const Material& m, const Vec3d& dir, const SurfacePoint& sp,
                              double offset, int depth, const Vec3& throughput, RayCounters& counters) const {
  if (depth >= config_.max_depth || !m.reflects()) return;
  const SpecularScatter s = scatter_specular(m, dir, sp, offset);
  if (s.reflects && effects_.reflection) {
    const Vec3 t = throughput * s.reflect_weight;
    if (max_channel(t) >= config_.min_throughput) {
      ++counters.reflection;
      result += s.reflect_weight * radiance(s.reflected, depth + 1, t, counters);
    }
  }
  if (s.refracts && effects_.refraction) {
    const Vec3 t = throughput * s.refract_weight;
    if (max_channel(t) >= config_.min_throughput) {
      ++counters.refraction;
      result += s.refract_weight * radiance(s.refracted, depth + 1, t, counters);
    }
  }
}

std::vector<ChainVertex> trace_specular_chain(const EmbreeScene& geometry, const Scene& scene, Ray ray, int max_events,
                                              double offset_scale) {
  std::vector<ChainVertex> chain;
  for (int i = 0; i < max_events; ++i) {
    Hit hit;
    if (!geometry.intersect(ray, 0.0, kInf, hit)) {
      chain.push_back({ray.origin, ChainVertex::Event::Escape, ray.direction});
      break;
    }
    const SurfacePoint sp = surface_point(geometry, hit);
    const Material& m = scene.materials[size_t(geometry.mesh(hit.geom).material)];
    if (!m.reflects()) {
      chain.push_back({sp.position, ChainVertex::Event::Opaque, ray.direction});
      break;
    }
    const SpecularScatter s = scatter_specular(m, ray.direction, sp, ray_offset(sp.position, offset_scale));
    if (s.refracts) {
      chain.push_back({sp.position, ChainVertex::Event::Refract, s.refracted.direction});
      ray = s.refracted;
    } else {
      chain.push_back({sp.position,
                       s.total_internal_reflection ? ChainVertex::Event::TotalInternalReflection : ChainVertex::Event::Reflect,
                       s.reflected.direction});
      ray = s.reflected;
    }
  }
  return chain;
}

}  // namespace raylod
