// Whitted-style integrator (Whitted 1980): diffuse and Phong glossy shading
// from point and directional lights with shadow rays, perfect mirror
// reflection, and glass with exact dielectric Fresnel reflection and
// refraction (total internal reflection included) and a transmission tint,
// up to the scene's max depth.
//
// Simulate only what the scene calls for: the Effects are derived from the
// materials the geometry actually uses and from the lights, and the
// integrator never spawns a ray kind whose effect is off (no shadow rays
// without lights, no reflection rays without a mirror or glass, no
// refraction rays without glass). Phong highlights are evaluated from the
// lights and cost no rays.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "geometry/optics.h"
#include "geometry/pinhole_camera.h"
#include "render/embree_scene.h"
#include "scene/scene.h"

namespace raylod {

struct Effects {
  int lights = 0;
  bool diffuse = false;     // direct diffuse lighting (lights, and a material with a diffuse colour)
  bool glossy = false;      // Phong highlights (lights, and a material with a specular colour)
  bool shadows = false;     // shadow rays (on whenever direct lighting is)
  bool reflection = false;  // reflection rays (a mirror or glass material, max_depth > 0)
  bool refraction = false;  // refraction rays (a glass material, max_depth > 0)
  // "diffuse, glossy highlights, shadows (2 lights), reflection, refraction" or "ambient only".
  std::string describe() const;
};

// Effects for a scene whose geometry uses the given material indices.
Effects effects_for(const Scene& scene, std::span<const int> used_materials);

// Rays traced, by kind.
struct RayCounters {
  uint64_t camera = 0, shadow = 0, reflection = 0, refraction = 0;
  uint64_t total() const { return camera + shadow + reflection + refraction; }
  RayCounters& operator+=(const RayCounters& o) {
    camera += o.camera; shadow += o.shadow; reflection += o.reflection; refraction += o.refraction;
    return *this;
  }
};

struct IntegratorConfig {
  int max_depth = 5;  // secondary bounces after the camera ray
  // Secondary rays whose throughput (largest channel) is below this are not
  // traced (geometry/optics.h, kMinThroughput).
  float min_throughput = kMinThroughput;
  // Whitted's ambient term k_a I_a: I_a = ambient * background colour,
  // k_a = the diffuse colour. Stands in for sky light, costs no rays.
  float ambient = 0.15f;
  // Darken camera hits within half a pixel footprint of a triangle edge:
  // shows the triangle density (the paper's wireframe figure).
  bool wireframe = false;
  // Secondary rays start this far off the surface (along the face normal),
  // relative to the largest coordinate of the hit point: about 16 float ulps,
  // well past Embree's intersection error and the float rounding of the
  // origin, and small enough not to bend the path through thin glass.
  double offset_scale = 2e-6;
  // ...but never relative to less than this (world units): 1, or the scene's
  // size if it is smaller (render_embree_scene sets it), so that a scene
  // modelled in metres at micrometre scale shades as the same scene in
  // millimetres does (an absolute 2e-6 moved contact shadows there).
  double offset_floor = 1.0;
};

// What a camera sample saw, with its first hit for the AOVs.
struct CameraSample {
  Vec3 color{0};
  bool hit = false;
  double depth = 0;          // distance along the camera ray to the first hit
  Vec3 normal{0};            // shading normal at the first hit, facing the camera
  uint64_t triangle = 0;     // global triangle id of the first hit
};

// The specular continuation at a mirror or glass hit, as the integrator
// computes it: directions (geometry/optics.h, shared with the probe) with
// spawn origins offset to the correct side of the surface, and weights
// (Fresnel, reflectance, tint).
struct SpecularScatter {
  bool reflects = false, refracts = false;
  bool total_internal_reflection = false;
  bool entering = false;  // the ray hit the front face (outside -> inside)
  Ray reflected, refracted;
  Vec3 reflect_weight{0}, refract_weight{0};
};
SpecularScatter scatter_specular(const Material& m, const Vec3d& direction, const SurfacePoint& sp, double offset);

// Spawn offset for a hit point (see IntegratorConfig::offset_scale and offset_floor).
double ray_offset(const Vec3d& p, double offset_scale, double offset_floor = 1.0);

class Integrator {
 public:
  Integrator(const EmbreeScene& geometry, const Scene& scene, const PinholeCamera& camera, const Effects& effects,
             const IntegratorConfig& config);
  // Traces the camera ray through continuous pixel position (px, py).
  CameraSample sample(double px, double py, RayCounters& counters) const;
  // The camera rays through up to EmbreeScene::kPacketSize pixel positions
  // (a pixel block) traced as one coherent packet, in two steps so that a
  // caller can trace the next packet before shading this one: trace starts
  // the fetches of the hits' triangle indices, prefetch_camera_vertices
  // those of their vertices, and shade then finds them in cache. shade_camera_packet traces the shadow rays of the hits as
  // occlusion packets; reflection and refraction rays go one by one. out[i]
  // is what sample(pixels[i].x, pixels[i].y) returns: the same rays, the same
  // hits and the same floating-point operations in the same order.
  struct CameraPacket {
    int size = 0;
    Ray rays[EmbreeScene::kPacketSize];
    Hit hits[EmbreeScene::kPacketSize];
    bool found[EmbreeScene::kPacketSize];
  };
  void trace_camera_packet(std::span<const glm::dvec2> pixels, CameraPacket& packet, RayCounters& counters) const;
  // The second fetch step: the hits' vertex positions and normals, whose
  // indices trace_camera_packet began to fetch. Call it some work after the
  // trace (the renderer: after shading the previous packet), so that the
  // indices have arrived and the vertices arrive before this packet is shaded.
  void prefetch_camera_vertices(const CameraPacket& packet) const;
  void shade_camera_packet(const CameraPacket& packet, CameraSample* out, RayCounters& counters) const;
  // Radiance arriving along ray; depth = bounces so far (0 for camera rays).
  Vec3 radiance(const Ray& ray, int depth, const Vec3& throughput, RayCounters& counters) const;

 private:
  // A shadow ray of direct lighting, and what its light adds if nothing blocks it.
  struct ShadowQuery {
    Ray ray;
    double tfar = 0;
    Vec3 contribution{0};
  };

  Vec3 shade(const Ray& ray, const Hit& hit, const SurfacePoint& sp, int depth, const Vec3& throughput,
             RayCounters& counters) const;
  const Material& material(const Hit& hit) const;
  // Whitted's ambient term (no rays).
  Vec3 ambient(const Material& m) const;
  // True if the material is lit directly (and so spawns shadow rays).
  bool lit(const Material& m) const;
  // Calls emit(ShadowQuery) for each light that can reach the side of the
  // surface the ray came from, in light order.
  template <class Emit>
  void shadow_queries(const Material& m, const Vec3d& dir, const SurfacePoint& sp, double offset, Emit&& emit) const;
  // Adds the mirror and glass continuations to result (single rays).
  void add_specular(Vec3& result, const Material& m, const Vec3d& dir, const SurfacePoint& sp, double offset,
                    int depth, const Vec3& throughput, RayCounters& counters) const;
  // The first-hit fields of a camera sample (everything but the colour).
  void record_camera_hit(const Ray& ray, const Hit& hit, const SurfacePoint& sp, CameraSample& out) const;
  void apply_wireframe(const Hit& hit, const SurfacePoint& sp, CameraSample& out) const;

  const EmbreeScene& geometry_;
  const Scene& scene_;
  PinholeCamera camera_;
  Effects effects_;
  IntegratorConfig config_;
  // How far along its direction a camera ray starts (camera_skip_for): 0
  // unless the eye is far from everything there is to hit.
  double camera_skip_ = 0;
};

// How far camera rays may start along their direction: nothing lies nearer
// the eye than `bounds` (the scene's, ground included), so a ray's first hit
// is at least the eye's distance to it away. Used only when that distance is
// over 8 diagonals of the box, where Embree's float origin and direction,
// taken at the eye, would miss by more than the scene's detail (an eye 1e5
// object sizes away shattered a sphere); 0 otherwise, or if the eye is inside.
double camera_skip_for(const Vec3d& eye, const Bbox& bounds);

// Follows a ray through mirror and glass surfaces the way the integrator
// does, always taking the refracted branch when there is one (the reflected
// one under total internal reflection or at a mirror), until it escapes or
// hits an opaque material. For tests and diagnostics.
struct ChainVertex {
  Vec3d position{0};
  enum class Event { Refract, Reflect, TotalInternalReflection, Opaque, Escape } event = Event::Escape;
  Vec3d direction_out{0};  // direction after the event (the ray's, for Escape)
};
std::vector<ChainVertex> trace_specular_chain(const EmbreeScene& geometry, const Scene& scene, Ray ray, int max_events,
                                              double offset_scale = 2e-6);

}  // namespace raylod
