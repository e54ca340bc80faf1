// The probe (Miyashita, Kanai & Kishinami, steps A2-A4) with Igehy ray
// differentials; the policy for unreached cells is documented in probe.h.
#include "probe/probe.h"

#include "probe/cell_visibility.h"
#include "probe/cut_balance.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <numbers>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/gtc/matrix_transform.hpp>

#include "core/random.h"
#include "core/progress.h"
#include "core/system.h"
#include "geometry/collapse_deviation.h"
#include "geometry/optics.h"
#include "probe/store_tracer.h"
#include "scene/scene_camera.h"

namespace raylod {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kNoObject = -1;
constexpr int kGround = -2;
// How many levels below a cell the deviation test looks (descendant_deviation):
// one level below holds 8 nodes at most, four 4,096.
constexpr int kDescendantLevels = 4;
// The far-end normal bound (CutSelection::select, probe.h): triangles seen
// more than kFarReach cell diagonals from a corner in the cell, on cells
// whose far_normal, times the corner's weight at the hit, exceeds
// kFarNormalFloor radians (below it the cell counts as flat).
constexpr double kFarReach = 2.0;
constexpr double kFarNormalFloor = 1e-3;
// Unreached curved mirror and glass cells (probe.h): the fewest measured
// curved cells a view calibrates the factor c from.
constexpr size_t kMinCurvatureSamples = 50;

// Largest singular value of a 3x3 matrix (power iteration on L^T L).
double max_singular_value(const Mat3d& l) {
  const Mat3d m = glm::transpose(l) * l;
  Vec3d v(0.5773502691896258);
  double lambda = 0;
  for (int i = 0; i < 64; ++i) {
    Vec3d w = m * v;
    const double len = glm::length(w);
    if (!(len > 0)) return 0;
    lambda = len;
    v = w / len;
  }
  return std::sqrt(lambda);
}

struct ObjectXf {
  glm::dmat4 m, minv;
  Mat3d linv, normal;  // inverse linear part; inverse transpose for normals
  double sigma = 1;    // largest stretch of the transform (world length per store length)
  size_t store = 0;
  int material = 0;
};

// Store coordinates to world: the object's transform after the store's mesh
// origin (StoreHeader::mesh_origin).
ObjectXf make_object_xf(const ProbeObject& o, std::span<const ProbeStore> stores) {
  ObjectXf x;
  x.m = o.transform * glm::translate(glm::dmat4(1.0), stores[o.store].store->header().mesh_origin);
  x.minv = glm::inverse(x.m);
  const Mat3d l(o.transform);
  x.linv = glm::inverse(l);
  x.normal = glm::transpose(x.linv);
  x.sigma = max_singular_value(l);
  x.store = o.store;
  x.material = o.material;
  return x;
}

enum Kind { kPrimary, kReflection, kRefraction };

using HitRecord = ProbeHit;

struct ProbeRayCounters {
  static constexpr int kCount = 12;
  uint64_t v[kCount] = {};
  enum {
    primary, reflection, refraction, tir, hits, hits_ground, misses, dropped, page_visits, triangle_tests, pruned,
    ground_shadow
  };
};
const char* const kCounterNames[ProbeRayCounters::kCount] = {
    "rays_primary", "rays_reflection", "rays_refraction", "total_internal_reflections", "hits", "hits_ground",
    "misses", "differentials_dropped", "page_visits", "triangle_tests", "rays_pruned", "rays_ground_shadow"};

struct RayOutcome {
  std::vector<HitRecord> hits;
  std::vector<GroundHit> ground;  // where the ray's path met the ground
  ProbeRayCounters counters;
  Status status;
};

struct PathRay {
  RayDifferential rd;
  int depth = 0;
  Kind kind = kPrimary;
  double path_length = 0;
  Vec3 throughput{1.0f};  // the renderer's throughput of the path (integrator.cpp, add_specular)
  int skip_object = kNoObject;
  TriangleRef skip_ref;
  int32_t parent = -1;  // the mesh hit (index into the ray's hits) this ray leaves, or -1
  int branch = 0;       // which of the parent's rays it is (its slot in Leaving below)
};

// A ray leaving a mirror or glass hit, the throughput the renderer gives it,
// and how far it turns per radian the normal tilts (2 for a reflection;
// Refraction::tilt_gain for a transmitted ray).
struct Leaving {
  RayDifferential rd;
  Kind kind = kReflection;
  Vec3 throughput{0.0f};
  double gain = 2;
};

struct WorldHit {
  double t = kInf;
  int object = kNoObject;
  TriangleHit tri;
};

class ProbeTracer {
 public:
  ProbeTracer(const Scene& scene, std::span<const ProbeStore> stores, std::span<const ProbeObject> objects,
              const ProbeConfig& config, PageCache& cache)
      : scene_(scene), config_(config), camera_(make_pinhole_camera(scene.camera)) {
    for (const ProbeStore& s : stores) tracers_.emplace_back(*s.store, cache);
    Bbox world;
    for (const ProbeObject& o : objects) {
      const ObjectXf x = make_object_xf(o, stores);
      xf_.push_back(x);
      const Bbox b = tracers_[o.store].bounds();
      if (!b.empty())
        for (int c = 0; c < 8; ++c)
          world.expand(Vec3d(x.m * glm::dvec4(c & 1 ? b.hi.x : b.lo.x, c & 2 ? b.hi.y : b.lo.y,
                                              c & 4 ? b.hi.z : b.lo.z, 1.0)));
    }
    // Secondary rays start this far along: far below any feature of the
    // meshes, far above double rounding at their coordinates.
    tmin_scale_ = world.empty() ? 0 : 1e-9 * glm::length(world.extent());
    tmin_abs_ = world.empty() ? 0 : 1e-14 * std::max(glm::length(world.lo), glm::length(world.hi));
  }

  const PinholeCamera& camera() const { return camera_; }
  const std::vector<ObjectXf>& transforms() const { return xf_; }

  // Test ray `index`: a random position inside a random pixel, from the
  // ray's own seed (so it does not depend on which thread traces it).
  Vec2 pixel_of(uint64_t index, double& px, double& py) const {
    uint64_t state = config_.seed * 0x2545f4914f6cdd1dull ^ (index + 1) * 0x9e3779b97f4a7c15ull;
    splitmix64(state);
    const PinholeCamera& cam = camera_;
    const double ix = std::floor(uniform01(state) * cam.width), iy = std::floor(uniform01(state) * cam.height);
    px = std::min(ix, double(cam.width - 1)) + uniform01(state);
    py = std::min(iy, double(cam.height - 1)) + uniform01(state);
    return Vec2(float(ix), float(iy));
  }

  RayOutcome trace_test_ray(uint64_t index) const {
    RayOutcome out;
    const PinholeCamera& cam = camera_;
    double px, py;
    pixel_of(index, px, py);
    PathRay first;
    first.rd = camera_ray_differential(cam, px, py);
    // The ray's own pixel angle: its beam widens by this per unit of path.
    const double beam = std::min(glm::length(first.rd.dd_dx), glm::length(first.rd.dd_dy));
    std::vector<PathRay> stack{first};
    // Per mesh hit: its rendered leaving rays' smallest spread along their
    // paths and their gains (0: no such ray), and which of its parent's
    // rays led to it.
    struct Branches {
      std::array<double, 2> spread{kInf, kInf}, gain{0, 0};
      int from = 0;
    };
    std::vector<Branches> branches;
    while (!stack.empty()) {
      PathRay pr = std::move(stack.back());
      stack.pop_back();
      ++out.counters.v[pr.kind == kPrimary ? ProbeRayCounters::primary
                       : pr.kind == kReflection ? ProbeRayCounters::reflection : ProbeRayCounters::refraction];
      WorldHit wh;
      const double tmin = pr.depth == 0 ? 0 : tmin_scale_ + tmin_abs_;
      out.status = intersect(pr.rd.ray.origin, pr.rd.ray.direction, tmin, pr.skip_object, pr.skip_ref, wh, out.counters);
      if (!out.status) return out;
      if (wh.object == kNoObject) { ++out.counters.v[ProbeRayCounters::misses]; continue; }

      HitSurface sp;
      int material;
      if (wh.object == kGround) {
        sp.point = pr.rd.ray.at(wh.t);
        sp.geometric_normal = sp.normal = Vec3d(0, 1, 0);
        material = scene_.ground->material;
      } else {
        const ObjectXf& x = xf_[size_t(wh.object)];
        std::array<Vec3d, 3> p, n;
        for (int k = 0; k < 3; ++k) {
          p[k] = Vec3d(x.m * glm::dvec4(wh.tri.p[k], 1.0));
          if (wh.tri.has_normals) {
            const Vec3d nk = x.normal * wh.tri.n[k];
            const double len = glm::length(nk);
            n[k] = len > 0 ? nk / len : Vec3d(0);
          }
        }
        sp = triangle_surface_point(p[0], p[1], p[2], wh.tri.has_normals ? n.data() : nullptr, wh.tri.b1, wh.tri.b2,
                                    config_.limits);
        material = x.material;
      }
      RayDifferential r = pr.rd;
      transfer(r, wh.t, sp.geometric_normal, config_.limits);
      const double path = pr.path_length + wh.t;

      if (wh.object == kGround) {
        ++out.counters.v[ProbeRayCounters::hits_ground];
        GroundHit& g = out.ground.emplace_back();
        g.point = sp.point;
        out.status = light_ground(g, out.counters);
        if (!out.status) return out;
      } else {
        ++out.counters.v[ProbeRayCounters::hits];
        const ObjectXf& x = xf_[size_t(wh.object)];
        HitRecord h;
        h.object = uint32_t(wh.object);
        h.corners = wh.tri.p;
        h.b1 = wh.tri.b1;
        h.b2 = wh.tri.b2;
        if (r.has_differentials) {
          // The footprint in store units: the differentials mapped back by the inverse transform.
          h.footprint = std::max(glm::length(x.linv * r.dp_dx), glm::length(x.linv * r.dp_dy));
          const Vec3d& d = r.ray.direction;
          auto across = [&](const Vec3d& dp) { return glm::length(x.linv * (dp - glm::dot(dp, d) * d)); };
          h.width = std::max(across(r.dp_dx), across(r.dp_dy));
          // A surface moved along its normal moves in the image by that
          // times the sine of the incidence angle (ProbeHit::shift_footprint).
          const double sine = glm::length(glm::cross(sp.geometric_normal, d));
          h.shift_footprint = sine * h.footprint > h.width ? h.width / sine : h.footprint;
          if (pr.kind != kPrimary && beam > 0 && path > 0) h.ratio = footprint(r) / (beam * path);
        } else {
          h.estimated = true;
          h.footprint = h.width = h.shift_footprint = beam * path / x.sigma;
          ++out.counters.v[ProbeRayCounters::dropped];
        }
        h.parent = pr.parent;
        h.back_facing = glm::dot(sp.geometric_normal, r.ray.direction) > 0;
        out.hits.push_back(h);
        branches.emplace_back().from = pr.branch;
      }

      // The rays leaving a mirror or glass surface, with the renderer's
      // weights (render/integrator.cpp, scatter_specular): it traces those
      // whose throughput reaches kMinThroughput, and none beyond max_depth.
      if (pr.depth >= scene_.max_depth) continue;
      const Material& mat = scene_.materials[size_t(material)];
      std::array<Leaving, 2> leaving;
      int n_leaving = 0;
      bool tir = false;
      if (mat.refracts()) {
        const Refraction rf = refract(r, sp, mat.ior, config_.limits);
        if (rf.total_internal_reflection) {
          tir = true;
          leaving[n_leaving++] = {rf.ray, kReflection, pr.throughput, 2.0};
        } else {
          const Vec3 transmitted = float(1.0 - rf.fresnel) * (rf.entering ? mat.tint : Vec3(1.0f));
          leaving[n_leaving++] = {rf.ray, kRefraction, pr.throughput * transmitted, rf.tilt_gain};
          leaving[n_leaving++] = {reflect(r, sp, config_.limits), kReflection, pr.throughput * Vec3(float(rf.fresnel)),
                                  2.0};
        }
      } else if (mat.reflects()) {
        leaving[n_leaving++] = {reflect(r, sp, config_.limits), kReflection, pr.throughput * Vec3(mat.reflectance), 2.0};
      }
      const int32_t at = wh.object != kGround ? int32_t(out.hits.size() - 1) : pr.parent;
      const int at_branch = wh.object != kGround ? -1 : pr.branch;
      for (int b = 0; b < n_leaving; ++b) {
        const Leaving& l = leaving[size_t(b)];
        if (!(max_channel(l.throughput) >= kMinThroughput)) {  // not rendered
          ++out.counters.v[ProbeRayCounters::pruned];
          continue;
        }
        if (tir) ++out.counters.v[ProbeRayCounters::tir];
        // The ray's angular spread ||dD||: a turn of its direction shows in
        // the image as that turn over the spread, in pixels. A mirror ground
        // passes its rays on to the mesh hit before it.
        if (at >= 0) {
          const double spread =
              l.rd.has_differentials ? std::max(glm::length(l.rd.dd_dx), glm::length(l.rd.dd_dy)) : beam;
          Branches& br = branches[size_t(at)];
          const size_t slot = size_t(at_branch >= 0 ? at_branch : b);
          br.spread[slot] = std::min(br.spread[slot], spread);
          if (at_branch < 0) br.gain[slot] = l.gain;
        }
        PathRay s;
        s.rd = l.rd;
        s.depth = pr.depth + 1;
        s.kind = l.kind;
        s.path_length = path;
        s.throughput = l.throughput;
        s.skip_object = wh.object;
        s.skip_ref = wh.tri.ref;
        s.parent = at;
        s.branch = at_branch >= 0 ? at_branch : b;
        stack.push_back(std::move(s));
      }
    }
    // A normal tilt t at a hit turns each ray leaving it by gain * t; the
    // turn stays as it is along the rest of the path while a later surface
    // may focus the beam (the two walls of a thin glass shell nearly cancel
    // each other's spread), so the hit tolerates t up to the smallest
    // spread / gain over its rays b, the spread of b taken as the smallest
    // ||dD|| over b and every ray after it. Hits come after the hit their
    // ray left, so one backward pass carries each subtree's spread to its
    // parent.
    for (size_t i = out.hits.size(); i-- > 0;) {
      const Branches& br = branches[i];
      double tilt = kInf, spread = kInf;
      for (size_t b = 0; b < 2; ++b) {
        if (br.gain[b] == 0) continue;  // no such ray, or not rendered
        spread = std::min(spread, br.spread[b]);
        tilt = std::min(tilt, std::isinf(br.gain[b]) ? 0.0 : br.spread[b] / br.gain[b]);
      }
      ProbeHit& h = out.hits[i];
      h.tilt = tilt;
      if (h.parent >= 0) {
        double& p = branches[size_t(h.parent)].spread[size_t(br.from)];
        p = std::min(p, spread);
      }
    }
    return out;
  }

 private:
  Status intersect(const Vec3d& o, const Vec3d& d, double tmin, int skip_object, TriangleRef skip_ref, WorldHit& out,
                   ProbeRayCounters& counters) const {
    TraceCounters tc;
    for (size_t i = 0; i < xf_.size(); ++i) {
      const ObjectXf& x = xf_[i];
      const Vec3d oo(x.minv * glm::dvec4(o, 1.0));
      const Vec3d od = x.linv * d;  // not normalised: t stays the world distance
      TriangleHit h;
      RAYLOD_RETURN_IF_ERROR(tracers_[x.store].intersect(oo, od, tmin, out.t,
                                                         int(i) == skip_object ? skip_ref : TriangleRef{}, h, &tc));
      if (h.found()) {
        out.t = h.t;
        out.object = int(i);
        out.tri = h;
      }
    }
    if (scene_.ground && skip_object != kGround && d.y != 0) {
      // The ground: a square of side size at y = height, centred under look_at.
      const double t = (scene_.ground->height - o.y) / d.y;
      if (t > tmin && t < out.t) {
        const Vec3d p = o + t * d;
        const double half = 0.5 * scene_.ground->size;
        if (std::abs(p.x - scene_.camera.look_at.x) <= half && std::abs(p.z - scene_.camera.look_at.z) <= half) {
          out.t = t;
          out.object = kGround;
          out.tri = TriangleHit{};
        }
      }
    }
    counters.v[ProbeRayCounters::page_visits] += tc.page_visits;
    counters.v[ProbeRayCounters::triangle_tests] += tc.triangle_tests;
    return {};
  }

  const Scene& scene_;
  const ProbeConfig& config_;
  PinholeCamera camera_;
  std::vector<StoreTracer> tracers_;
  std::vector<ObjectXf> xf_;
  double tmin_scale_ = 0, tmin_abs_ = 0;

  // Which lights reach a ground point past the meshes (GroundHit::lit): a
  // shadow ray to each light, as the renderer's (a light below the ground
  // reaches none of it). Only where the ground shows shadows and the cut
  // looks (ProbeConfig::unseen_cells).
  Status light_ground(GroundHit& g, ProbeRayCounters& counters) const {
    if (!config_.unseen_cells || !scene_.ground_shows_shadows())
      return {};
    const size_t n = std::min<size_t>(scene_.lights.size(), 32);
    for (size_t l = 0; l < n; ++l) {
      const Light& light = scene_.lights[l];
      Vec3d d = light.type == LightType::Directional ? -light.direction : light.position - g.point;
      const double len = glm::length(d);
      bool reaches = d.y > 0 && len > 0;
      if (reaches) {
        d /= len;
        WorldHit wh;
        wh.t = light.type == LightType::Directional ? kInf : len;
        ++counters.v[ProbeRayCounters::ground_shadow];
        RAYLOD_RETURN_IF_ERROR(intersect(g.point, d, tmin_scale_ + tmin_abs_, kGround, TriangleRef{}, wh, counters));
        reaches = wh.object == kNoObject;
      }
      if (!reaches) g.lit &= ~(uint32_t(1) << l);
    }
    return {};
  }
};

// x rounded down to a float, so that tests against it stay at least as strict.
float float_at_most(double x) {
  const float y = float(x);
  return double(y) > x ? std::nextafter(y, 0.0f) : y;
}

// The mean resultant length R of a node's normals from their spread
// (collapse_deviation.h: normal_spread_angle = 2 sqrt(1 - R)).
double resultant_from_spread(double spread) { return 1.0 - 0.25 * spread * spread; }

double distance_to_box(const Vec3d& p, const Bbox& b) {
  const Vec3d q = glm::max(b.lo - p, glm::max(Vec3d(0), p - b.hi));
  return glm::length(q);
}

}  // namespace

SelectionCache::Store SelectionCache::make_entry(const OctreeStore& store) {
  const int Q = store.header().quadric_depth;
  Store e;
  e.codes.resize(size_t(Q) + 1);
  e.slot.resize(size_t(Q) + 1);
  size_t nodes_total = 0;
  for (int L = 0; L <= Q; ++L) {
    const auto nodes = store.level(L);
    e.codes[size_t(L)].resize(nodes.size());
    for (size_t i = 0; i < nodes.size(); ++i) e.codes[size_t(L)][i] = nodes[i].code;
    e.slot[size_t(L)].assign(nodes.size(), 0);
    nodes_total += nodes.size();
  }
  const auto finest = store.level(Q);
  e.finest_cones.resize(finest.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, finest.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      Store::NormalCone& c = e.finest_cones[i];
      const double spread = normal_spread_angle(finest[i]);
      c.reach = spread >= 0.5 * std::numbers::pi ? 1.0f : float(std::sin(spread));
      const double len = glm::length(finest[i].normal_sum);
      if (len > 0)
        for (int k = 0; k < 3; ++k) c.mean[k] = float(finest[i].normal_sum[k] / len);
    }
  });
  e.max_computed = size_t(most_computed(nodes_total));
  return e;
}

SelectionCache::Store& SelectionCache::of(const OctreeStore& store) {
  std::vector<uint64_t> counts;
  for (int L = 0; L <= store.header().quadric_depth; ++L) counts.push_back(store.level(L).size());
  const auto key = std::make_pair(store_fingerprint(store), counts);
  auto it = by_store_.find(key);
  if (it == by_store_.end()) it = by_store_.emplace(key, make_entry(store)).first;
  return it->second;
}

uint64_t SelectionCache::bytes_for(std::span<const OctreeStore* const> stores) {
  uint64_t b = 0;
  for (const OctreeStore* st : stores) {
    uint64_t nodes = 0;
    for (int L = 0; L <= st->header().quadric_depth; ++L) nodes += st->level(L).size();
    b += nodes * (sizeof(uint64_t) + sizeof(uint32_t)) +
         st->level(st->header().quadric_depth).size() * sizeof(Store::NormalCone) +
         most_computed(nodes) * sizeof(CollapseDeviation);
  }
  return b;
}

uint64_t store_fingerprint(const OctreeStore& store) {
  const StoreHeader& h = store.header();
  uint64_t fp = fnv1a64(h.source_path.data(), h.source_path.size());
  auto mix = [&](const auto& v) { fp = fnv1a64(&v, sizeof(v), fp); };
  mix(h.version);
  mix(h.source_bytes);
  mix(h.source_mtime_ns);
  mix(h.source_hash);
  mix(h.triangle_count);
  mix(h.quadric_depth);
  mix(h.page_level);
  mix(h.root_lo);
  mix(h.root_size);
  mix(store.pages().size());
  return fp;
}

const char* to_string(CutCriterion c) { return c == CutCriterion::Diagonal ? "diagonal" : "deviation"; }

double default_tolerance_scale(int spp) { return spp > 4 ? std::pow(4.0 / double(spp), 0.75) : 1.0; }

const char* to_string(CutBalance b) {
  return b == CutBalance::Specular ? "specular" : b == CutBalance::All ? "all" : "off";
}

StatusOr<CutBalance> parse_cut_balance(const std::string& name) {
  for (CutBalance b : {CutBalance::Specular, CutBalance::All, CutBalance::Off})
    if (name == to_string(b)) return b;
  return Status::error("--balance: unknown value '" + name + "' (specular, all or off)");
}

StatusOr<CutCriterion> parse_cut_criterion(const std::string& name) {
  if (name == "deviation") return CutCriterion::Deviation;
  if (name == "diagonal") return CutCriterion::Diagonal;
  return Status::error("unknown cut criterion '" + name + "' (use deviation or diagonal)");
}

std::string probe_key(const Scene& scene, const OctreeStore& store, std::span<const ProbeObject> objects,
                      size_t store_index, const ProbeConfig& config) {
  uint64_t k = store_fingerprint(store);
  auto mix = [&](const auto& v) { k = fnv1a64(&v, sizeof(v), k); };
  mix(kCutRulesVersion);
  const Camera& c = scene.camera;
  mix(c.eye);
  mix(c.look_at);
  mix(c.up);
  mix(c.fov_y_deg);
  mix(c.width);
  mix(c.height);
  mix(scene.max_depth);
  mix(store_index);
  for (const ProbeObject& o : objects) {
    mix(o.transform);
    mix(o.store);
    const Material& m = scene.materials[size_t(o.material)];
    mix(m.type);
    mix(m.ior);
    mix(m.reflectance);  // which rays the renderer traces (kMinThroughput)
    mix(m.tint);
  }
  const bool ground = scene.ground.has_value();
  mix(ground);
  if (ground) {
    mix(scene.ground->height);
    mix(scene.ground->size);
    mix(scene.materials[size_t(scene.ground->material)].type);
  }
  const bool lights = !scene.lights.empty();
  mix(lights);
  for (const Light& l : scene.lights) {  // where shadows fall on the ground (the shadow bound)
    mix(l.type);
    mix(l.type == LightType::Directional ? l.direction : l.position);
  }
  mix(config.rays);
  mix(config.seed);
  mix(config.footprint_scale);
  mix(config.criterion);
  mix(config.tolerance_px);
  mix(config.angle_tolerance_px);
  mix(config.outline_tolerance);
  mix(config.unseen_cells);
  mix(config.shadow_receivers);
  mix(config.balance);
  mix(config.calibration_quantile);
  mix(config.curved_unreached_tilt);
  mix(config.unreached_angle_allowance);
  mix(config.shadow_factor);
  mix(config.limits.min_cos);
  mix(config.limits.max_turn);
  mix(config.limits.max_ratio);
  mix(config.limits.min_normal_length);
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(k));
  return buf;
}

namespace {

Status check_probe_inputs(const Scene& scene, std::span<const ProbeStore> stores, std::span<const ProbeObject> objects,
                          const ProbeConfig& config) {
  for (const ProbeObject& o : objects) {
    if (o.store >= stores.size() || !stores[o.store].store)
      return Status::error("probe: object refers to store " + std::to_string(o.store) + ", which is not given");
    if (o.material < 0 || size_t(o.material) >= scene.materials.size())
      return Status::error("probe: object material index out of range");
  }
  if (!(config.footprint_scale > 0)) return Status::error("probe: footprint scale must be > 0");
  if (!(config.tolerance_px > 0)) return Status::error("probe: tolerance must be > 0 pixels");
  if (!(config.angle_tolerance_px > 0)) return Status::error("probe: angle tolerance must be > 0 pixels");
  if (!(config.outline_tolerance > 0 && config.outline_tolerance <= 1))
    return Status::error("probe: the outline tolerance must be a fraction of the tolerance, in (0, 1]");
  if (!(config.unreached_angle_allowance > 0))
    return Status::error("probe: the unreached cells' angle allowance must be > 0");
  if (!(config.calibration_quantile >= 0 && config.calibration_quantile <= 1))
    return Status::error("probe: the calibration quantile must be between 0 and 1");
  return {};
}

}  // namespace

namespace {

// The value at quantile q (0 to 1) of non-empty `values` (reordered): the
// calibrations of m and of unreached curved cells' c (probe.h).
double low_quantile(std::vector<double>& values, double q) {
  const size_t at = size_t(std::floor(q * double(values.size() - 1)));
  std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(at), values.end());
  return values[at];
}

// The policy's magnification m: a low quantile of measured secondary hits.
void set_magnification(ProbeTrace& trace, const ProbeConfig& config) {
  std::vector<double> ratios;
  for (const HitRecord& h : trace.hits)
    if (h.ratio >= 0) ratios.push_back(h.ratio);
  double m = 1;
  if (!ratios.empty()) m = std::min(1.0, low_quantile(ratios, config.calibration_quantile));
  trace.magnification = m;
  trace.counters["magnification_ppm"] = uint64_t(std::llround(m * 1e6));
}

}  // namespace

StatusOr<ProbeTrace> trace_probe(const Scene& scene, std::span<const ProbeStore> stores,
                                 std::span<const ProbeObject> objects, const ProbeConfig& config) {
  RAYLOD_RETURN_IF_ERROR(check_probe_inputs(scene, stores, objects, config));
  const auto t_start = std::chrono::steady_clock::now();
  std::optional<PageCache> own_cache;
  if (config.pages) config.pages->set_capacity(config.cache_bytes);
  else own_cache.emplace(config.cache_bytes);
  PageCache& cache = config.pages ? *config.pages : *own_cache;
  const PageCacheCounters before = cache.counters();
  ProbeTracer tracer(scene, stores, objects, config, cache);

  // A2/A3: trace the test rays. Each ray has its own seed and its own result
  // slot, so the outcome does not depend on the number of threads.
  const uint64_t first = std::min(config.first_ray, config.rays);
  const uint64_t end = config.end_ray == 0 ? config.rays : std::clamp(config.end_ray, first, config.rays);
  const uint64_t n = end - first;
  std::vector<RayOutcome> outcomes(n);
  // Trace in the Morton order of the rays' pixels, so that neighbouring rays
  // (which mostly need the same pages) run close together in time and the
  // page cache serves them; results stay in their own slots, by ray index.
  std::vector<std::pair<uint64_t, uint64_t>> order(n);
  for (uint64_t i = 0; i < n; ++i) {
    double px, py;
    const Vec2 pixel = tracer.pixel_of(first + i, px, py);
    order[i] = {morton_encode(uint32_t(pixel.x), uint32_t(pixel.y), 0), i};
  }
  std::sort(order.begin(), order.end());
  {
    std::optional<Progress> progress;
    if (config.progress) progress.emplace("probe", n, "rays");
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 16), [&](const tbb::blocked_range<uint64_t>& r) {
      for (uint64_t i = r.begin(); i != r.end(); ++i)
        outcomes[order[i].second] = tracer.trace_test_ray(first + order[i].second);
      if (progress) progress->advance(r.size());
    });
    if (progress) progress->finish();
  }
  cache.release_scratch();  // the trace is over: what its threads kept for building pages goes
  ProbeTrace result;
  ProbeRayCounters total;
  for (const RayOutcome& o : outcomes) {
    if (!o.status) return o.status;
    for (int k = 0; k < ProbeRayCounters::kCount; ++k) total.v[k] += o.counters.v[k];
  }
  for (int k = 0; k < ProbeRayCounters::kCount; ++k) result.counters[kCounterNames[k]] = total.v[k];
  const PageCacheCounters cc = cache.counters();
  result.counters["pages_read"] = cc.pages_read - before.pages_read;
  result.counters["bytes_read"] = cc.bytes_read - before.bytes_read;
  result.counters["cache_hits"] = cc.hits - before.hits;
  result.counters["cache_misses"] = cc.misses - before.misses;
  result.counters["cache_evictions"] = cc.evictions - before.evictions;
  result.counters["cache_peak_bytes"] = cc.peak_bytes;  // since the cache was made
  size_t hits = 0;
  for (const RayOutcome& o : outcomes) hits += o.hits.size();
  result.hits.reserve(hits);
  for (const RayOutcome& o : outcomes) {
    const int32_t offset = int32_t(result.hits.size());
    for (ProbeHit h : o.hits) {
      if (h.parent >= 0) h.parent += offset;
      result.hits.push_back(h);
    }
    result.ground_hits.insert(result.ground_hits.end(), o.ground.begin(), o.ground.end());
  }
  result.rays = config.rays;
  result.seed = config.seed;
  set_magnification(result, config);
  result.trace_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

ProbeTrace merge_traces(std::vector<ProbeTrace> shares, const ProbeConfig& config) {
  ProbeTrace result;
  size_t hits = 0;
  for (const ProbeTrace& t : shares) hits += t.hits.size();
  result.hits.reserve(hits);
  for (ProbeTrace& t : shares) {
    const int32_t offset = int32_t(result.hits.size());
    for (ProbeHit h : t.hits) {
      if (h.parent >= 0) h.parent += offset;
      result.hits.push_back(h);
    }
    t.hits = {};
    result.ground_hits.insert(result.ground_hits.end(), t.ground_hits.begin(), t.ground_hits.end());
    for (const auto& [name, value] : t.counters)
      if (name != "magnification_ppm") result.counters[name] += value;
    result.trace_seconds = std::max(result.trace_seconds, t.trace_seconds);
  }
  result.rays = config.rays;
  result.seed = config.seed;
  set_magnification(result, config);
  return result;
}

bool is_page_cache_counter(const std::string& name) {
  return name == "pages_read" || name == "bytes_read" || name.rfind("cache_", 0) == 0;
}

namespace {

// One view: probe_key of its camera; several: a hash of their keys in order.
std::string shared_probe_key(std::span<const ProbeView> views, const Scene& scene, const OctreeStore& store,
                             std::span<const ProbeObject> objects, size_t store_index, const ProbeConfig& config) {
  Scene view_scene = scene;
  std::string keys;
  for (const ProbeView& v : views) {
    view_scene.camera = v.camera;
    keys += probe_key(view_scene, store, objects, store_index, config);
  }
  if (views.size() == 1) return keys;
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(fnv1a64(keys.data(), keys.size())));
  return buf;
}

}  // namespace

StatusOr<ProbeResult> select_cuts(const ProbeTrace& trace, const Scene& scene, std::span<const ProbeStore> stores,
                                  std::span<const ProbeObject> objects, const ProbeConfig& config) {
  const ProbeView view{&trace, scene.camera};
  return select_shared_cuts(std::span<const ProbeView>(&view, 1), scene, stores, objects, config);
}

namespace {

// Where a view's test rays met the ground (those a light reaches, for one
// light): a grid over the (x, z) box of those points (about one point a
// cell, at most 128 x 128), a cell marked if a point lies in it or next to
// it, with its summed-area table to count marked cells in a box at once.
class GroundSeen {
 public:
  // `light`: only the points that light reaches (GroundHit::lit) are marked,
  // on the grid all the points give (so the cells marked are a subset of
  // those marked for all); -1: all.
  explicit GroundSeen(std::span<const GroundHit> hits, int light = -1) {
    if (hits.empty()) return;
    for (const GroundHit& g : hits) {
      lo_ = glm::min(lo_, Vec2d(g.point.x, g.point.z));
      hi_ = glm::max(hi_, Vec2d(g.point.x, g.point.z));
    }
    // About one point a cell where they cover the box evenly: finer, and
    // the gaps between a few thousand points would read as unseen ground.
    side_ = std::clamp(int(std::sqrt(double(hits.size()))), 4, 128);
    const int side = side_;
    cell_ = glm::max((hi_ - lo_) / double(side), Vec2d(1e-12 * (1 + glm::length(hi_) + glm::length(lo_))));
    std::vector<uint8_t> hit(size_t(side) * side, 0), marked(hit.size(), 0);
    for (const GroundHit& g : hits) {
      if (light >= 0 && light < 32 && !(g.lit >> light & 1u)) continue;
      const auto [i, j] = index(g.point.x, g.point.z);
      hit[size_t(j) * side + size_t(i)] = 1;
    }
    for (int j = 0; j < side; ++j)
      for (int i = 0; i < side; ++i) {
        if (!hit[size_t(j) * side + size_t(i)]) continue;
        for (int dj = -1; dj <= 1; ++dj)
          for (int di = -1; di <= 1; ++di) {
            const int x = i + di, y = j + dj;
            if (x >= 0 && y >= 0 && x < side && y < side) marked[size_t(y) * side + size_t(x)] = 1;
          }
      }
    sum_.assign(size_t(side + 1) * (side + 1), 0);
    for (int j = 0; j < side; ++j)
      for (int i = 0; i < side; ++i)
        at(i + 1, j + 1) = marked[size_t(j) * side + size_t(i)] + at(i, j + 1) + at(i + 1, j) - at(i, j);
  }
  // Whether a test ray met the ground in or next to the (x, z) box of `b`
  // (its cells, one cell of margin: the grid is coarse).
  bool empty() const { return sum_.empty(); }
  bool seen(const Bbox& b) const {
    if (sum_.empty()) return false;
    if (b.hi.x < lo_.x - cell_.x || b.lo.x > hi_.x + cell_.x || b.hi.z < lo_.y - cell_.y || b.lo.z > hi_.y + cell_.y)
      return false;
    const auto [i0, j0] = index(b.lo.x - cell_.x, b.lo.z - cell_.y);
    const auto [i1, j1] = index(b.hi.x + cell_.x, b.hi.z + cell_.y);
    return at(i1 + 1, j1 + 1) - at(i0, j1 + 1) - at(i1 + 1, j0) + at(i0, j0) > 0;
  }

 private:
  using Vec2d = glm::dvec2;
  std::pair<int, int> index(double x, double z) const {
    const double last = double(side_ - 1);
    const auto clamp_cell = [last](double v) { return int(std::clamp(std::floor(v), 0.0, last)); };
    return {clamp_cell((x - lo_.x) / cell_.x), clamp_cell((z - lo_.y) / cell_.y)};
  }
  uint32_t& at(int i, int j) { return sum_[size_t(j) * size_t(side_ + 1) + size_t(i)]; }
  uint32_t at(int i, int j) const { return sum_[size_t(j) * size_t(side_ + 1) + size_t(i)]; }
  int side_ = 1;  // cells per side
  Vec2d lo_{kInf}, hi_{-kInf}, cell_{1};
  std::vector<uint32_t> sum_;
};

// What the unreached-cell policy needs of one view (probe.h).
struct ViewFacts {
  const ProbeTrace* trace = nullptr;
  PinholeCamera cam;
  Frustum frustum;
  double a_min = kInf;  // smallest angle between neighbouring pixels' rays (at the image corners)
  double m = 1;         // the trace's magnification
  GroundSeen ground{{}};  // where its test rays met the ground
  std::vector<GroundSeen> lit_ground;  // per light, where they met ground it reaches
  std::vector<ShadowReceivers> receivers;  // per light, where its shadows can be seen
};

ViewFacts make_view_facts(const ProbeView& v, size_t lights) {
  ViewFacts f;
  f.trace = v.trace;
  f.cam = make_pinhole_camera(v.camera);
  f.frustum = make_frustum(f.cam);
  for (double px : {0.0, 0.5 * f.cam.width, double(f.cam.width)})
    for (double py : {0.0, 0.5 * f.cam.height, double(f.cam.height)}) {
      const RayDerivatives d = f.cam.derivatives(px, py);
      f.a_min = std::min({f.a_min, glm::length(d.dd_dx), glm::length(d.dd_dy)});
    }
  f.m = v.trace->magnification;
  f.ground = GroundSeen(v.trace->ground_hits);
  for (size_t l = 0; l < lights; ++l) f.lit_ground.emplace_back(v.trace->ground_hits, int(l));
  return f;
}

// Per light, where its shadows can be seen in the view (probe.h, "Unseen
// cells"): every hit of its test rays, on a mesh or the ground, standing
// for the surface out to twice the rays' mean spacing in the image.
std::vector<ShadowReceivers> shadow_receivers_of(const ViewFacts& f, std::span<const ObjectXf> xf, const Scene& scene) {
  const double pixels = double(f.cam.width) * double(f.cam.height);
  const double spacing = 2.0 * std::sqrt(pixels / double(std::max<uint64_t>(1, f.trace->rays)));
  std::vector<ShadowReceiver> receivers;
  receivers.reserve(f.trace->hits.size() + f.trace->ground_hits.size());
  for (const ProbeHit& h : f.trace->hits) {
    const ObjectXf& x = xf[h.object];
    const Vec3d local = (1 - h.b1 - h.b2) * h.corners[0] + h.b1 * h.corners[1] + h.b2 * h.corners[2];
    const double footprint = h.footprint * x.sigma * (h.estimated ? f.m : 1.0);  // world units, per pixel
    receivers.push_back({Vec3d(x.m * glm::dvec4(local, 1.0)), spacing * footprint});
  }
  for (const GroundHit& g : f.trace->ground_hits)
    receivers.push_back({g.point, spacing * f.a_min * glm::length(g.point - f.cam.eye)});
  std::vector<ShadowReceivers> out;
  for (const Light& l : scene.lights) out.push_back(ShadowReceivers::make(l, receivers));
  return out;
}

// The smallest angle between neighbouring pixels' rays over the pixels a
// world box covers (pinhole_camera.h, over its bounding ball); a_min if the
// ball reaches the eye's plane.
double pixel_angle_over(const ViewFacts& view, const Bbox& b) {
  const double a = smallest_pixel_angle_over_ball(view.cam, 0.5 * (b.lo + b.hi), 0.5 * glm::length(b.hi - b.lo));
  return a > 0 ? std::max(a, view.a_min) : view.a_min;
}

}  // namespace

namespace {

struct StoreNeeds {
  bool specular = false;  // a mirror or glass object uses the store: its cells also bound the normal
  // Per view, the factor c of unreached curved cells' tilt c kappa f (probe.h); 0: none.
  std::vector<double> curvature_factor;
  // need() and the tilt allowance per level, node by node (probe.h); and
  // need() from the hits' shift footprints (ProbeHit::shift_footprint),
  // which the deviation criterion's tests take (float: 4 bytes a node more).
  std::vector<std::vector<double>> need, tilt;
  std::vector<std::vector<float>> shift_need;
  // The same over the finest cells an outline may run through in a view
  // (their normals reach across the direction from the eye; probe.h,
  // "Outlines"); +inf where none does.
  std::vector<std::vector<float>> contour_need;
  // The nodes' codes and collapse deviations (SelectionCache): a shared
  // cache's entry, or own.
  SelectionCache::Store* kept = nullptr;
  SelectionCache::Store own;
  // The store's hits, for the footprints of the marked cells: each hit's
  // footprint (the estimate's factor m applied) and its corners' finest cells.
  struct Hit {
    float footprint = 0;
    std::array<uint64_t, 3> codes{};
  };
  std::vector<Hit> hits;
  float min_footprint = 0;
  // Every corner of a hit triangle, sorted by its finest cell's code, with
  // its distance to the hit (store units) and its weight there: a cell whose
  // corner is far from where a ray saw its triangle bounds the normal at the
  // triangle's far end (CollapseDeviation::far_normal).
  struct Reach {
    uint64_t code = 0;
    float distance = 0;
    float weight = 0;  // the corner's barycentric weight at the hit
  };
  std::vector<Reach> reach;
  // Finest cells no test ray reached that faced away from the eye in every
  // view, and that no view could see nor, with lights, see the shadow of
  // (probe.h, "Unseen cells"); counted per store.
  uint64_t back_facing_cells = 0, unseen_cells = 0;
  // The largest weight of a corner in `cell` (level L) at a hit more than
  // `distance` from it; 0 if none.
  double far_weight(int L, int Q, uint64_t cell, double distance) const;
};

double StoreNeeds::far_weight(int L, int Q, uint64_t cell, double distance) const {
  const int shift = 3 * (Q - L);
  auto it = std::lower_bound(reach.begin(), reach.end(), cell << shift,
                             [](const Reach& r, uint64_t code) { return r.code < code; });
  double w = 0;
  for (; it != reach.end() && (it->code >> shift) == cell; ++it)
    if (it->distance > distance) w = std::max(w, double(it->weight));
  return w;
}

}  // namespace

struct CutSelection::State {
  std::vector<ProbeView> views;
  const Scene* scene = nullptr;
  std::span<const ProbeStore> stores;
  std::span<const ProbeObject> objects;
  double shadow_factor = 0;
  bool unseen_cells = true;
  bool shadow_receivers = true;
  // What the unreached curved cells' calibration (make()) read of the config.
  bool curved_unreached_tilt = true;
  double calibration_quantile = 0;
  double unreached_angle_allowance = 0;
  std::vector<StoreNeeds> needs;
  double prepare_seconds = 0;
};

CutSelection::CutSelection() = default;
CutSelection::~CutSelection() = default;
CutSelection::CutSelection(CutSelection&&) noexcept = default;
CutSelection& CutSelection::operator=(CutSelection&&) noexcept = default;

StatusOr<CutSelection> CutSelection::make(std::span<const ProbeView> views, const Scene& scene,
                                          std::span<const ProbeStore> stores, std::span<const ProbeObject> objects,
                                          const ProbeConfig& config) {
  RAYLOD_RETURN_IF_ERROR(check_probe_inputs(scene, stores, objects, config));
  if (views.empty()) return Status::error("probe: no views to select a cut for");
  for (const ProbeView& v : views)
    if (!v.trace) return Status::error("probe: a view has no trace");
  const auto t_start = std::chrono::steady_clock::now();
  CutSelection sel;
  sel.state_ = std::make_unique<State>();
  State& state = *sel.state_;
  state.views.assign(views.begin(), views.end());
  state.scene = &scene;
  state.stores = stores;
  state.objects = objects;
  state.shadow_factor = config.shadow_factor;
  state.unseen_cells = config.unseen_cells;
  state.shadow_receivers = config.shadow_receivers;
  state.curved_unreached_tilt = config.curved_unreached_tilt;
  state.calibration_quantile = config.calibration_quantile;
  state.unreached_angle_allowance = config.unreached_angle_allowance;
  state.needs.resize(stores.size());
  std::vector<ViewFacts> facts;
  for (const ProbeView& v : views) facts.push_back(make_view_facts(v, config.unseen_cells ? scene.lights.size() : 0));
  std::vector<ObjectXf> xf;
  for (const ProbeObject& o : objects) xf.push_back(make_object_xf(o, stores));

  bool specular = false;
  for (const ProbeObject& o : objects) specular |= scene.traces_specular(scene.materials[size_t(o.material)]);
  if (scene.ground) specular |= scene.traces_specular(scene.materials[size_t(scene.ground->material)]);
  const bool lights = !scene.lights.empty();
  // Unseen cells are a rule of scenes without mirrors and glass (estimate below).
  if (config.unseen_cells && config.shadow_receivers && lights && !specular)
    for (ViewFacts& f : facts) f.receivers = shadow_receivers_of(f, xf, scene);

  for (size_t s = 0; s < stores.size(); ++s) {
    const OctreeStore& st = *stores[s].store;
    const int Q = st.header().quadric_depth;
    StoreNeeds& n = state.needs[s];
    if (config.selection_cache) {
      n.kept = &config.selection_cache->of(st);
    } else {
      n.own = SelectionCache::make_entry(st);
      n.kept = &n.own;
    }
    const std::vector<std::vector<uint64_t>>& codes_at = n.kept->codes;
    // Measured footprints at the finest level, attached to the hit triangles'
    // corner cells, per view.
    struct Measured { double f = kInf; double shift = kInf; double tilt = kInf; uint32_t hits = 0; };
    std::vector<std::unordered_map<uint64_t, Measured>> measured(views.size());
    double min_fp = kInf;
    // Per view: camera rays that met the store, and whether any met a back
    // face (probe.h, "Unseen cells").
    std::vector<uint64_t> camera_hits(views.size(), 0);
    std::vector<bool> saw_back(views.size(), false);
    for (size_t v = 0; v < views.size(); ++v)
      for (const HitRecord& h : views[v].trace->hits) {
        if (xf[h.object].store != s) continue;
        if (h.parent < 0) {
          ++camera_hits[v];
          if (h.back_facing) saw_back[v] = true;
        }
        const double f = h.estimated ? h.footprint * facts[v].m : h.footprint;
        min_fp = std::min(min_fp, h.estimated ? f : h.width);
        StoreNeeds::Hit& hit = n.hits.emplace_back();
        hit.footprint = float(f);
        std::array<uint64_t, 3>& codes = hit.codes;
        const std::array<double, 3> b = {1.0 - h.b1 - h.b2, h.b1, h.b2};
        const Vec3d at = b[0] * h.corners[0] + b[1] * h.corners[1] + b[2] * h.corners[2];
        for (int k = 0; k < 3; ++k) {
          codes[k] = st.cell_of(h.corners[k], Q).code;
          n.reach.push_back({codes[k], float(glm::length(at - h.corners[k])), float(b[size_t(k)])});
          if ((k > 0 && codes[k] == codes[0]) || (k > 1 && codes[k] == codes[1])) continue;
          Measured& e = measured[v][codes[k]];
          e.f = std::min(e.f, f);
          e.shift = std::min(e.shift, h.estimated ? f : h.shift_footprint);
          e.tilt = std::min(e.tilt, h.tilt);
          ++e.hits;
        }
      }
    n.min_footprint = std::isfinite(min_fp) ? float(min_fp) : 0.0f;
    std::sort(n.reach.begin(), n.reach.end(),
              [](const StoreNeeds::Reach& a, const StoreNeeds::Reach& b) { return a.code < b.code; });

    // The policy's estimate for a cell no ray of view `view` reached (probe.h).
    std::vector<const ObjectXf*> on_store;
    for (const ObjectXf& x : xf)
      if (x.store == s) on_store.push_back(&x);
    const bool spec = specular, lit = lights;
    const double shadow_factor = config.shadow_factor;
    const bool unseen_cells = config.unseen_cells;
    // `back`: the cell faces away from the eye (probe.h, "Unseen cells").
    // `unseen` (if given) is set where an object's placement of the cell
    // took the unseen cells' bound.
    auto estimate = [&](const ViewFacts& view, const Bbox& b, bool back, bool* unseen = nullptr) {
      const PinholeCamera& cam = view.cam;
      const double m = view.m;
      double need = kInf;
      for (const ObjectXf* xp : on_store) {
        const std::array<Vec3d, 8> c = world_corners(xp->m, b);
        Bbox wb;
        for (const Vec3d& q : c) wb.expand(q);
        const double d = distance_to_box(cam.eye, wb) / xp->sigma;
        double e = view.a_min * d;
        if (spec) e *= m;
        // Seen directly only: the pixels it covers bound it.
        else if (!back && !view.frustum.outside(c)) e = pixel_angle_over(view, wb) * d * m;
        else {
          // Unseen: only its shadows on what the camera sees.
          if (unseen) *unseen = true;
          bool casts = false;
          for (size_t li = 0; li < scene.lights.size() && !casts; ++li)
            casts = !unseen_cells || (!view.frustum.shadow_outside(c, scene.lights[li]) &&
                                      (view.receivers.empty() || view.receivers[li].may_shadow(c, wb)));
          if (lit && casts)
            e *= shadow_factor;
          else
            e = kInf;
        }
        need = std::min(need, e);
      }
      return need;
    };
    // Per view: whether its back-facing cells are unseen, a closed mesh
    // whose normals point outwards as far as its camera rays tell.
    std::vector<bool> backs_unseen(views.size(), false);
    for (size_t v = 0; v < views.size(); ++v)
      backs_unseen[v] = unseen_cells && !spec && st.boundary_leaves() == 0 && camera_hits[v] > 0 && !saw_back[v];
    std::atomic<uint64_t> back_facing_cells{0}, unseen_cells_count{0};
    // Shadows on the ground (probe.h): for each light, the cell's shadow
    // on the ground plane (its corners moved along the light onto y =
    // height; corners at or below it stay). If that lands in the view, the
    // cell's deviation moves the shadow's edge there by up to deviation /
    // sin(alpha) (alpha: the light's elevation over the ground), times
    // s_r / s_o for a point light (the shadow's distance from the light
    // over the cell's), against a footprint of at least m a d at the
    // shadow's distance d from the eye. Infinite if no shadow reaches the
    // visible ground, or the ground is a mirror or glass (it shows no
    // shadows).
    const bool ground_shadows = scene.ground_shows_shadows();
    // Per light, what does not depend on the cell: a directional light's
    // slope (the shadow of (x, y, z) is (x - (y - h) dx/dy, h, z - (y - h)
    // dz/dy)) and its sin(alpha).
    struct ShadowLight {
      bool directional;
      Vec3d at;             // point light: its position
      double kx = 0, kz = 0, sin_alpha = 0;
      bool casts = true;    // a directional light pointing down
    };
    std::vector<ShadowLight> shadow_lights;
    for (const Light& l : scene.lights) {
      ShadowLight sl{l.type == LightType::Directional, l.position};
      if (sl.directional) {
        const Vec3d d = glm::normalize(l.direction);
        sl.casts = d.y < 0;
        if (sl.casts) {
          sl.kx = d.x / d.y;
          sl.kz = d.z / d.y;
          sl.sin_alpha = -d.y;
        }
      }
      shadow_lights.push_back(sl);
    }
    // `need`: what binds the cell so far (a shadow that needs no less is not
    // looked at closely).
    auto shadow_estimate = [&](const ViewFacts& view, const Bbox& b, double need) {
      if (!ground_shadows || view.ground.empty()) return need;
      const double h = scene.ground->height;
      for (const ObjectXf* xp : on_store) {
        const std::array<Vec3d, 8> c = world_corners(xp->m, b);
        for (size_t li = 0; li < shadow_lights.size(); ++li) {
          const ShadowLight& l = shadow_lights[li];
          if (!l.casts) continue;
          Bbox pb;  // the shadow's box on the ground
          double sin_alpha = l.directional ? l.sin_alpha : 1.0, ratio = 1;
          bool lands = true;
          for (int i = 0; i < 8 && lands; ++i) {
            const double above = std::max(0.0, c[i].y - h);  // corners at or below the ground stay
            if (l.directional) {
              pb.expand(Vec3d(c[i].x - above * l.kx, h, c[i].z - above * l.kz));
              continue;
            }
            const Vec3d d = c[i] - l.at;
            const double len = glm::length(d);
            if (!(d.y < 0) || !(len > 0)) { lands = false; break; }  // no shadow falls down from here
            sin_alpha = std::min(sin_alpha, -d.y / len);
            const double t = above / -d.y;
            pb.expand(Vec3d(c[i].x + t * d.x, h, c[i].z + t * d.z));
            ratio = std::min(ratio, 1.0 / (1.0 + t));
          }
          // Ground the view's test rays met, directly or through mirrors and
          // glass; elsewhere (outside the view, hidden behind the object) no
          // shadow shows. Nor where all the ground around lies in the
          // shadow of other parts (probe.h, "Shadows on the ground").
          const GroundSeen& where = unseen_cells ? view.lit_ground[li] : view.ground;
          if (!lands || !where.seen(pb)) continue;
          // Seen directly only (no mirror or glass): the pixels it covers,
          // whose angle is at least a_min (so only when that could bind).
          const double base = view.m * distance_to_box(view.cam.eye, pb) * sin_alpha * ratio / xp->sigma;
          if (!(view.a_min * base < need)) continue;
          need = std::min(need, (spec ? view.a_min : pixel_angle_over(view, pb)) * base);
        }
      }
      return need;
    };
    // Each view's measured cells in code order, walked alongside the nodes.
    struct MeasuredCell {
      uint64_t code;
      Measured m;
    };
    std::vector<std::vector<MeasuredCell>> sorted_measured(views.size());
    for (size_t v = 0; v < views.size(); ++v) {
      for (const auto& [code, m] : measured[v]) sorted_measured[v].push_back({code, m});
      std::sort(sorted_measured[v].begin(), sorted_measured[v].end(),
                [](const MeasuredCell& a, const MeasuredCell& b) { return a.code < b.code; });
    }

    // Mirror or glass objects on this store: their cells also bound the normal.
    for (const ObjectXf& x : xf)
      if (x.store == s) n.specular |= scene.traces_specular(scene.materials[size_t(x.material)]);

    // Unreached mirror and glass cells on a curved surface (probe.h): the
    // tilt they take grows with their curvature times the beam's width. Per
    // view, the factor c is the calibration quantile of tilt / (kappa f)
    // over the measured finest cells with curvature, as m is calibrated
    // from the measured footprints; 0 (the flat mirror's bound alone) with
    // fewer than kMinCurvatureSamples of them.
    const auto nodes_q = st.level(Q);
    const double side_q = st.cell_diagonal(Q) / std::sqrt(3.0);
    std::vector<double> curvature_factor(views.size(), 0.0);
    if (n.specular && config.curved_unreached_tilt)
      for (size_t v = 0; v < views.size(); ++v) {
        std::vector<double> ratios;
        for (const MeasuredCell& mc : sorted_measured[v]) {
          const auto it = std::lower_bound(codes_at[size_t(Q)].begin(), codes_at[size_t(Q)].end(), mc.code);
          if (it == codes_at[size_t(Q)].end() || *it != mc.code || !std::isfinite(mc.m.tilt)) continue;
          const double kappa = normal_spread_angle(nodes_q[size_t(it - codes_at[size_t(Q)].begin())]) / side_q;
          if (kappa > 0 && mc.m.f > 0) ratios.push_back(mc.m.tilt / (kappa * mc.m.f));
        }
        if (ratios.size() >= kMinCurvatureSamples)
          curvature_factor[v] = low_quantile(ratios, config.calibration_quantile);
      }
    n.curvature_factor = curvature_factor;

    // need() and the tilt allowance bottom-up: at level Q the finest over the
    // views of each view's measured or estimated need, min over children above.
    std::vector<std::vector<double>>& need = n.need;
    std::vector<std::vector<float>>& shift_need = n.shift_need;
    std::vector<std::vector<float>>& contour_need = n.contour_need;
    std::vector<std::vector<double>>& tilt = n.tilt;
    need.resize(size_t(Q) + 1);
    shift_need.resize(size_t(Q) + 1);
    contour_need.resize(size_t(Q) + 1);
    tilt.resize(size_t(Q) + 1);
    // The outline and facing tests in the store's frame where an object's
    // transform keeps angles (a rotation, uniform scale, translation: the
    // common case; a reflection keeps which side faces the eye too): there
    // mean . d and the ratio of |mean . d| to |mean| |d| are
    // those of the world, and each view's eye is moved into the store's
    // frame once. Per view, per object on the store: that eye, or NaN
    // where the transform shears or scales unevenly (tested in the world).
    std::vector<bool> conformal;
    for (const ObjectXf* xp : on_store) {
      const Mat3d l(xp->m);
      const double s2 = glm::dot(l[0], l[0]);
      bool c = s2 > 0;
      for (int a = 0; a < 3 && c; ++a)
        for (int b = 0; b < 3 && c; ++b) c = std::abs(glm::dot(l[a], l[b]) - (a == b ? s2 : 0.0)) <= 1e-12 * s2;
      conformal.push_back(c);
    }
    std::vector<std::vector<Vec3d>> eye_in_store(views.size());
    for (size_t v = 0; v < views.size(); ++v)
      for (size_t o = 0; o < on_store.size(); ++o)
        eye_in_store[v].push_back(conformal[o] ? Vec3d(on_store[o]->minv * glm::dvec4(facts[v].cam.eye, 1.0))
                                               : Vec3d(std::numeric_limits<double>::quiet_NaN()));
    // Whether a cell (its box, the unit mean of its normals and their mean
    // resultant length R) faces away from view v's eye for every object on
    // the store (cell_visibility.h).
    auto faces_away_all = [&](size_t v, const Bbox& box, const Vec3d& mean, double R) {
      for (const Vec3d& eye : eye_in_store[v])
        if (std::isnan(eye.x) || !faces_away(eye, box, mean, R, kUnseenFrontShare)) return false;
      return true;
    };
    // Per level, per node: whether some finest cell in it took the unseen
    // cells' bound in some view (then the node's own box is checked too).
    std::vector<std::vector<uint8_t>> unseen_below;
    {
      const std::vector<uint64_t>& nodes = codes_at[size_t(Q)];
      need[size_t(Q)].assign(nodes.size(), kInf);
      shift_need[size_t(Q)].assign(nodes.size(), std::numeric_limits<float>::infinity());
      contour_need[size_t(Q)].assign(nodes.size(), std::numeric_limits<float>::infinity());
      if (n.specular) tilt[size_t(Q)].assign(nodes.size(), kInf);
      const bool store_specular = n.specular;
      const double unreached_allowance = config.unreached_angle_allowance;
      unseen_below.assign(size_t(Q) + 1, {});
      unseen_below[size_t(Q)].assign(nodes.size(), 0);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, nodes.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        // Per view, the first measured cell at or after the range's first node.
        std::vector<size_t> at(views.size());
        for (size_t v = 0; v < views.size(); ++v)
          at[v] = size_t(std::lower_bound(sorted_measured[v].begin(), sorted_measured[v].end(), nodes[r.begin()],
                                          [](const MeasuredCell& c, uint64_t code) { return c.code < code; }) -
                         sorted_measured[v].begin());
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const uint64_t code = nodes[i];
          double f = kInf, fs = kInf, a = kInf, cs = kInf;
          std::optional<Bbox> box;
          const double kappa = store_specular ? normal_spread_angle(nodes_q[i]) / side_q : 0.0;
          // An outline may run through the cell where its normals, a cap of
          // half-angle `spread` around their mean, reach across the
          // direction from the eye: |mean . d| <= sin(spread) (the cone as
          // the selection cache keeps it).
          const SelectionCache::Store::NormalCone& cone = n.kept->finest_cones[i];
          const Vec3d cone_mean(cone.mean[0], cone.mean[1], cone.mean[2]);
          auto outline = [&](size_t v) {
            const Vec3d centre = 0.5 * (box->lo + box->hi);
            const double reach2 = double(cone.reach) * double(cone.reach);
            for (size_t o = 0; o < on_store.size(); ++o) {
              Vec3d mean = cone_mean, d;
              if (const Vec3d& eye = eye_in_store[v][o]; !std::isnan(eye.x)) {
                d = centre - eye;
              } else {
                const ObjectXf* xp = on_store[o];
                d = Vec3d(xp->m * glm::dvec4(centre, 1.0)) - facts[v].cam.eye;
                mean = xp->normal * cone_mean;
              }
              const double md = glm::dot(mean, d), m2 = glm::dot(mean, mean), d2 = glm::dot(d, d);
              if (!(m2 > 0) || !(d2 > 0) || md * md <= reach2 * m2 * d2) return true;
            }
            return false;
          };
          bool all_back = true, all_unseen = true;  // in every view (the counters)
          bool any_unseen = false;  // in some view (the check of coarser cells)
          for (size_t v = 0; v < views.size(); ++v) {
            const std::vector<MeasuredCell>& sm = sorted_measured[v];
            while (at[v] < sm.size() && sm[at[v]].code < code) ++at[v];
            const Measured* hit = at[v] < sm.size() && sm[at[v]].code == code ? &sm[at[v]].m : nullptr;
            if (!box) box = st.cell_bounds(CellKey{uint32_t(Q), code});
            // Unreached and facing away from the eye from all of its box
            // (probe.h, "Unseen cells"), for every object on the store.
            const bool back = !hit && backs_unseen[v] && cone.reach < 1 &&
                              faces_away_all(v, *box, cone_mean, resultant_from_spread(std::asin(double(cone.reach))));
            bool unseen = false;
            const double seen = hit ? hit->f : estimate(facts[v], *box, back, &unseen);
            any_unseen = any_unseen || (unseen && unseen_cells);
            all_back = all_back && back;
            all_unseen = all_unseen && !hit && lit && std::isinf(seen);
            f = std::min(f, seen);
            f = shadow_estimate(facts[v], *box, f);
            // The estimate bounds the beam's width, so the shift footprint
            // too; a hit's shift footprint is at most its footprint, so f
            // adds only the shadows' bound.
            fs = std::min({fs, hit ? hit->shift : seen, f});
            if (outline(v)) cs = std::min(cs, hit ? hit->shift : seen);
            // Unreached mirror or glass cells: the pixel angle, as magnified
            // as the most magnified measured paths, over a mirror's gain of
            // 2; on a curved surface at least c kappa f (above).
            if (store_specular) {
              double unreached = 0.5 * facts[v].a_min * facts[v].m;
              if (!hit && curvature_factor[v] > 0) {
                const double curved = curvature_factor[v] * kappa * seen;
                if (std::isfinite(curved)) unreached = std::max(unreached, curved);
              }
              a = std::min(a, hit ? hit->tilt : unreached_allowance * unreached);
            }
          }
          unseen_below[size_t(Q)][i] = any_unseen;
          if (all_back) back_facing_cells.fetch_add(1, std::memory_order_relaxed);
          if (all_unseen) unseen_cells_count.fetch_add(1, std::memory_order_relaxed);
          need[size_t(Q)][i] = f;
          shift_need[size_t(Q)][i] = float_at_most(fs);
          contour_need[size_t(Q)][i] = float_at_most(cs);
          if (store_specular) tilt[size_t(Q)][i] = a;
        }
      });
      n.back_facing_cells = back_facing_cells.load();
      n.unseen_cells = unseen_cells_count.load();
    }
    for (int L = Q - 1; L >= 0; --L) {
      const std::vector<uint64_t>&parents = codes_at[size_t(L)], &children = codes_at[size_t(L) + 1];
      need[size_t(L)].assign(parents.size(), kInf);
      unseen_below[size_t(L)].assign(parents.size(), 0);
      shift_need[size_t(L)].assign(parents.size(), std::numeric_limits<float>::infinity());
      contour_need[size_t(L)].assign(parents.size(), std::numeric_limits<float>::infinity());
      if (n.specular) tilt[size_t(L)].assign(parents.size(), kInf);
      size_t j = 0;
      for (size_t i = 0; i < parents.size(); ++i) {
        while (j < children.size() && (children[j] >> 3) < parents[i]) ++j;
        bool unseen = false;
        for (; j < children.size() && (children[j] >> 3) == parents[i]; ++j) {
          need[size_t(L)][i] = std::min(need[size_t(L)][i], need[size_t(L) + 1][j]);
          shift_need[size_t(L)][i] = std::min(shift_need[size_t(L)][i], shift_need[size_t(L) + 1][j]);
          contour_need[size_t(L)][i] = std::min(contour_need[size_t(L)][i], contour_need[size_t(L) + 1][j]);
          if (n.specular) tilt[size_t(L)][i] = std::min(tilt[size_t(L)][i], tilt[size_t(L) + 1][j]);
          unseen = unseen || unseen_below[size_t(L) + 1][j];
        }
        unseen_below[size_t(L)][i] = unseen;
        if (!unseen) continue;
        // Some of it took the unseen cells' bound: its collapse puts a
        // vertex anywhere in its own box, which may be in view, facing the
        // eye or casting a shadow into view where its parts did not. So the
        // cell's own box takes the policy too.
        const Bbox box = st.cell_bounds(CellKey{uint32_t(L), parents[i]});
        const NodeRecord& node = st.level(L)[i];
        const double len = glm::length(node.normal_sum);
        const Vec3d mean = len > 0 ? node.normal_sum / len : Vec3d(0);
        const double spread = normal_spread_angle(node);
        double f = kInf;
        for (size_t v = 0; v < views.size(); ++v) {
          const bool back = backs_unseen[v] && len > 0 && spread < 0.5 * std::numbers::pi &&
                            faces_away_all(v, box, mean, resultant_from_spread(spread));
          f = shadow_estimate(facts[v], box, std::min(f, estimate(facts[v], box, back)));
        }
        need[size_t(L)][i] = std::min(need[size_t(L)][i], f);
        shift_need[size_t(L)][i] = std::min(shift_need[size_t(L)][i], float_at_most(f));
      }
    }
  }
  state.prepare_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return sel;
}

StatusOr<ProbeResult> CutSelection::select(const ProbeConfig& config) {
  if (!state_) return Status::error("probe: a cut selection that was not made");
  State& state = *state_;
  const Scene& scene = *state.scene;
  const std::span<const ProbeStore> stores = state.stores;
  const std::span<const ProbeObject> objects = state.objects;
  const std::span<const ProbeView> views = state.views;
  RAYLOD_RETURN_IF_ERROR(check_probe_inputs(scene, stores, objects, config));
  if (config.curved_unreached_tilt != state.curved_unreached_tilt ||
      config.calibration_quantile != state.calibration_quantile ||
      config.unreached_angle_allowance != state.unreached_angle_allowance)
    return Status::error("probe: a cut selection was prepared for another bound on unreached mirror and glass cells");
  if (config.shadow_factor != state.shadow_factor || config.unseen_cells != state.unseen_cells ||
      config.shadow_receivers != state.shadow_receivers)
    return Status::error("probe: a cut selection was prepared for another shadow factor or rule for unseen cells");
  const auto t_select = std::chrono::steady_clock::now();
  ProbeResult result;
  // Counters add up over the views; the magnification is the smallest.
  result.magnification = kInf;
  for (const ProbeView& v : views) {
    for (const auto& [name, value] : v.trace->counters)
      if (name != "magnification_ppm") result.counters[name] += value;
    result.magnification = std::min(result.magnification, v.trace->magnification);
    result.trace_seconds += v.trace->trace_seconds;
  }
  result.counters["magnification_ppm"] = uint64_t(std::llround(result.magnification * 1e6));
  uint64_t total_rays = 0;
  for (const ProbeView& v : views) total_rays += v.trace->rays;
  const double K = config.footprint_scale;
  const bool deviation = config.criterion == CutCriterion::Deviation;

  // A4: one cut per store.
  for (size_t s = 0; s < stores.size(); ++s) {
    const OctreeStore& st = *stores[s].store;
    const int Q = st.header().quadric_depth;
    StoreNeeds& n = state.needs[s];
    const bool bound_normals = deviation && n.specular;
    Cut cut;
    cut.store_hash = store_fingerprint(st);
    cut.store_path = stores[s].path.string();
    cut.key = shared_probe_key(views, scene, st, objects, s, config);
    cut.rays = total_rays;
    cut.seed = views[0].trace->seed;
    cut.footprint_scale = K;
    for (const auto& [name, value] : result.counters)
      if (!is_page_cache_counter(name)) cut.counters[name] = value;
    cut.min_footprint = n.min_footprint;
    cut.counters["store_hits"] = n.hits.size();
    cut.counters["finest_cells_back_facing"] = n.back_facing_cells;
    cut.counters["finest_cells_unseen"] = n.unseen_cells;
    // c of the view that calibrated the least (0 if any view had too few
    // measured curved cells), where it bounds anything.
    if (bound_normals && config.curved_unreached_tilt)
      cut.counters["curvature_factor_ppm"] = uint64_t(std::llround(
          1e6 * *std::min_element(n.curvature_factor.begin(), n.curvature_factor.end())));

    // The cut: top-down, the largest cells the criterion accepts (a cell
    // inside an accepted one is collapsed with it).
    const QemSolveConfig qem;
    const Vec3d origin = st.header().origin;
    const NodeNormals node_normals = node_normals_of(st.header());
    uint64_t rejected_deviation = 0, rejected_normal = 0, rejected_boundary = 0, rejected_fold = 0, rejected_crease = 0,
             rejected_far = 0;
    // The finest cells left uncollapsed (their input triangles are kept as
    // they are), by the test that kept them: K, deviation, normal, boundary,
    // fold.
    std::array<uint64_t, 8> finest_kept{};
    std::vector<std::vector<char>> collapsed(size_t(Q) + 1);
    SelectionCache::Store& kept = *n.kept;
    // Deviations kept beyond the cache's bound are let go (recomputed when
    // needed), and a slot must fit 32 bits.
    size_t node_count = 0;
    for (const std::vector<uint32_t>& slot : kept.slot) node_count += slot.size();
    if (kept.computed.size() > kept.max_computed ||
        kept.computed.size() + node_count >= std::numeric_limits<uint32_t>::max()) {
      kept.computed.clear();
      for (std::vector<uint32_t>& slot : kept.slot) std::fill(slot.begin(), slot.end(), 0);
    }
    const std::vector<std::vector<uint64_t>>& codes_at = kept.codes;
    for (int L = 0; L <= Q; ++L) {
      const auto nodes = st.level(L);
      const std::vector<uint64_t>& codes = codes_at[size_t(L)];
      collapsed[size_t(L)].assign(nodes.size(), 0);
      const double diag = st.cell_diagonal(L);
      // 1 = inside a collapsed parent, 0 = to decide.
      const std::vector<char> inside = L > 0 ? flagged_parents(codes, codes_at[size_t(L) - 1], collapsed[size_t(L) - 1])
                                             : std::vector<char>(nodes.size(), 0);
      // 0 = keep, 1 = collapse, 2 = kept for its deviation, 3 = for its
      // normal, 4 = for an open boundary in it, 5 = for a fold in it, 6 =
      // for a crease in it (mirrors and glass), 7 = for the far end of a
      // triangle seen beyond it.
      // The deviations of the nodes this level tests that no selection
      // computed before (SelectionCache): given slots, then computed.
      if (deviation) {
        std::vector<uint32_t>& slot = kept.slot[size_t(L)];
        std::vector<size_t> todo;
        for (size_t i = 0; i < nodes.size(); ++i)
          if (!inside[i] && diag < K * n.need[size_t(L)][i] && slot[i] == 0) {
            todo.push_back(i);
            slot[i] = uint32_t(kept.computed.size() + todo.size());
          }
        kept.computed.resize(kept.computed.size() + todo.size());
        tbb::parallel_for(tbb::blocked_range<size_t>(0, todo.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
          for (size_t t = r.begin(); t != r.end(); ++t) {
            const size_t i = todo[t];
            CollapseDeviation& dev = kept.computed[slot[i] - 1];
            const Bbox cell = st.cell_bounds(CellKey{uint32_t(L), codes[i]});
            dev = collapse_deviation(nodes[i], Bbox{cell.lo - origin, cell.hi - origin}, node_normals, qem);
            // What the cell's area weighting hides, from its subtree
            // (collapse_deviation.h, descendant_deviation): the nodes up to
            // kDescendantLevels below it.
            for (int M = L + 1; M <= std::min(Q, L + kDescendantLevels); ++M) {
              const std::vector<uint64_t>& below = codes_at[size_t(M)];
              const int shift = 3 * (M - L);
              const auto first = std::lower_bound(below.begin(), below.end(), codes[i] << shift);
              const auto last = std::lower_bound(first, below.end(), (codes[i] + 1) << shift);
              const std::span<const NodeRecord> sub =
                  st.level(M).subspan(size_t(first - below.begin()), size_t(last - first));
              dev.position = std::max(dev.position, descendant_deviation(sub, dev.representative));
            }
          }
        });
      }
      std::vector<char> verdict(nodes.size(), 0);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, nodes.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          if (inside[i]) continue;
          const double f = n.need[size_t(L)][i];
          if (!(diag < K * f)) continue;
          if (!deviation) { verdict[i] = 1; continue; }
          // The deviation tests compare what moves the surface in the image
          // with the shift footprint (ProbeHit::shift_footprint).
          // Where an outline may run, a fraction of the tolerance
          // (ProbeConfig::outline_tolerance).
          const double fs = std::min(double(n.shift_need[size_t(L)][i]),
                                     config.outline_tolerance * double(n.contour_need[size_t(L)][i]));
          const CollapseDeviation& dev = kept.deviation(L, i);
          if (dev.position > config.tolerance_px * fs) { verdict[i] = 2; continue; }
          // What a quadric cannot bound (rims, folds, creases on mirrors
          // and glass, below) collapses only while the whole cell is within
          // the tolerance.
          const bool whole_cell_within = diag <= config.tolerance_px * fs;
          // The quadric does not see a rim (collapse_deviation.h), which the
          // representative may pull anywhere in the cell: a cell with an
          // open boundary.
          if (!whole_cell_within && st.touches_boundary(CellKey{uint32_t(L), codes[i]})) {
            verdict[i] = 4;
            continue;
          }
          // Nor a fold (a knife edge, a plate thinner than the cell), whose
          // edge the representative may pull as far in: the same rule.
          if (!whole_cell_within && dev.folded) {
            verdict[i] = 5;
            continue;
          }
          // Nor the normal at the far end of a triangle a ray saw beyond
          // the cell (CollapseDeviation::far_normal): the long strips of a
          // CAD tessellation end in cells off the view, whose mean normal
          // then shades the whole visible strip. The rim's rule, the cell
          // shrunk by the corner's weight at the hit, on curved cells (a
          // flat one's normal is exact).
          if (!whole_cell_within && dev.far_normal > kFarNormalFloor) {
            const double b = n.far_weight(L, Q, codes[i], kFarReach * diag);
            if (b * diag > config.tolerance_px * fs && b * dev.far_normal > kFarNormalFloor) {
              verdict[i] = 7;
              continue;
            }
          }
          if (bound_normals && dev.normal > config.angle_tolerance_px * n.tilt[size_t(L)][i]) { verdict[i] = 3; continue; }
          // On mirrors and glass, a crease or corner the cell holds exactly
          // (its representative on the edge, no deviation) is still cut
          // across by the triangles that join it to the cells beside it
          // wherever the crease does not follow the cells' faces: chamfers
          // and folded flaps that reflection and refraction show (a
          // rotated glass cube: 23.78 dB against a 36.02 dB floor). The
          // rim's rule.
          if (bound_normals && dev.crease && !whole_cell_within) { verdict[i] = 6; continue; }
          verdict[i] = 1;
        }
      });
      for (size_t i = 0; i < nodes.size(); ++i) {
        if (inside[i]) { collapsed[size_t(L)][i] = 1; continue; }
        if (L == Q && verdict[i] != 1) ++finest_kept[size_t(verdict[i])];
        rejected_deviation += verdict[i] == 2;
        rejected_normal += verdict[i] == 3;
        rejected_boundary += verdict[i] == 4;
        rejected_fold += verdict[i] == 5;
        rejected_crease += verdict[i] == 6;
        rejected_far += verdict[i] == 7;
        if (verdict[i] == 1) collapsed[size_t(L)][i] = 1;
      }
    }
    // Graded where the deviation criterion bounds normals (mirrors and
    // glass), or as asked: a triangle joining a fine cell to a much coarser
    // one spans the coarse cell, beyond the fine cell's bound.
    if (config.balance == CutBalance::All || (config.balance == CutBalance::Specular && bound_normals))
      cut.counters["cells_split_to_balance"] = balance_cut(codes_at, collapsed);
    for (const CellKey& k : cut_cells(codes_at, collapsed)) cut.cells.push_back({k, 0.0f, 0});
    cut.counters["cells_kept_for_deviation"] = rejected_deviation;
    cut.counters["cells_kept_for_normals"] = rejected_normal;
    cut.counters["cells_kept_for_boundary"] = rejected_boundary;
    cut.counters["cells_kept_for_fold"] = rejected_fold;
    cut.counters["cells_kept_for_crease"] = rejected_crease;
    cut.counters["cells_kept_for_far_normal"] = rejected_far;
    cut.counters["finest_cells_kept"] =
        finest_kept[0] + finest_kept[2] + finest_kept[3] + finest_kept[4] + finest_kept[5] + finest_kept[6] +
        finest_kept[7];
    cut.counters["finest_cells_kept_for_k"] = finest_kept[0];
    cut.counters["finest_cells_kept_for_deviation"] = finest_kept[2];
    cut.counters["finest_cells_kept_for_normals"] = finest_kept[3];
    cut.counters["finest_cells_kept_for_boundary"] = finest_kept[4];
    cut.counters["finest_cells_kept_for_fold"] = finest_kept[5];
    cut.counters["finest_cells_kept_for_crease"] = finest_kept[6];
    cut.counters["finest_cells_kept_for_far_normal"] = finest_kept[7];
    std::sort(cut.cells.begin(), cut.cells.end(), [](const CollapsedCell& a, const CollapsedCell& b) { return a.key < b.key; });
    // Footprints and hit counts of the marked cells (each hit counted once per cell).
    std::unordered_map<uint64_t, size_t> cell_index;  // pack(level, code) -> index
    // A marker bit above the code: codes at level L have 3L bits (L <= 21).
    auto pack = [](uint32_t level, uint64_t code) { return (uint64_t(1) << (3 * level)) | code; };
    for (size_t i = 0; i < cut.cells.size(); ++i) cell_index[pack(cut.cells[i].key.level, cut.cells[i].key.code)] = i;
    uint64_t hit_cells = 0;
    for (const StoreNeeds::Hit& h : n.hits) {
      size_t found[3];
      int nfound = 0;
      for (const uint64_t code : h.codes)
        for (int L = Q; L >= 0; --L) {
          auto it = cell_index.find(pack(uint32_t(L), code >> (3 * (Q - L))));
          if (it == cell_index.end()) continue;
          if (std::find(found, found + nfound, it->second) == found + nfound) found[nfound++] = it->second;
          break;
        }
      for (int k = 0; k < nfound; ++k) {
        CollapsedCell& c = cut.cells[found[k]];
        c.min_footprint = c.hits == 0 ? h.footprint : std::min(c.min_footprint, h.footprint);
        ++c.hits;
      }
    }
    for (const CollapsedCell& c : cut.cells) hit_cells += c.hits > 0;
    cut.counters["cells_marked"] = cut.cells.size();
    cut.counters["cells_marked_with_hits"] = hit_cells;
    cut.counters["quadric_depth"] = uint64_t(Q);
    result.cuts.push_back(std::move(cut));
  }
  result.cut_seconds = state.prepare_seconds + std::chrono::duration<double>(std::chrono::steady_clock::now() - t_select).count();
  state.prepare_seconds = 0;  // counted once, in the first selection
  return result;
}

StatusOr<ProbeResult> select_shared_cuts(std::span<const ProbeView> views, const Scene& scene,
                                         std::span<const ProbeStore> stores, std::span<const ProbeObject> objects,
                                         const ProbeConfig& config) {
  RAYLOD_ASSIGN_OR_RETURN(CutSelection selection, CutSelection::make(views, scene, stores, objects, config));
  return selection.select(config);
}

StatusOr<ProbeResult> run_probe(const Scene& scene, std::span<const ProbeStore> stores,
                                std::span<const ProbeObject> objects, const ProbeConfig& config) {
  RAYLOD_ASSIGN_OR_RETURN(ProbeTrace trace, trace_probe(scene, stores, objects, config));
  return select_cuts(trace, scene, stores, objects, config);
}

}  // namespace raylod
