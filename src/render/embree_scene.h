// The renderer's geometry: world-space indexed triangle meshes (loaded by
// streaming a mesh file and welding identical corners) in one Embree 3 scene.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <embree3/rtcore.h>

#include "core/math.h"
#include "core/status.h"
#include "geometry/ray.h"
#include "scene/scene.h"

namespace raylod {

// TriangleMesh::name of the ground plane's mesh (make_ground_mesh).
inline constexpr const char* kGroundMeshName = "ground";

// A world-space triangle mesh with shared vertices, as Embree consumes it.
struct TriangleMesh {
  std::vector<Vec3> positions;    // world space
  std::vector<Vec3> normals;      // empty, or one unit vertex normal per position (world space)
  std::vector<uint32_t> indices;  // 3 per triangle; counter-clockwise seen from the front
  int material = 0;               // index into Scene::materials
  std::string name;               // for messages: the file name, or "ground"
  size_t triangle_count() const { return indices.size() / 3; }
  // Bytes held by the arrays (what the renderer keeps resident besides the BVH).
  uint64_t bytes() const;
};

// Welds a triangle soup -- corner k of triangle i is positions[3 i + k] -- into
// shared vertices: corners with bit-identical position (and normal, if
// normals is not empty) become one vertex. Triangle order is kept, so
// triangle ids match the soup's. normals is empty or positions.size().
TriangleMesh weld_triangles(std::span<const Vec3> positions, std::span<const Vec3> normals);

// Gives a welded mesh without normals per-corner crease-angle normals
// (geometry/crease_normals.h): corners whose normals differ are split into
// separate vertices. Triangle order and ids are kept.
void add_crease_normals(TriangleMesh& mesh, double crease_angle_deg);

// Streams a mesh file with open_mesh (PLY, STL, OBJ, Draco), welds it, gives
// it crease-angle normals if the file has none (in object space, as the
// collapse does), and transforms it to world space: positions (relative to
// the reader's MeshHeader::origin, which is composed in first) by
// object_to_world, normals by its inverse transpose; a mirroring transform
// (negative determinant) reverses the winding so that front faces stay front
// faces. on_triangles (optional) is told how many triangles each batch added,
// for progress bars.
StatusOr<TriangleMesh> load_triangle_mesh(const std::filesystem::path& path, const glm::dmat4& object_to_world,
                                          int material, double crease_angle_deg,
                                          const std::function<void(uint64_t)>& on_triangles = {});

// Triangle count a mesh file declares in its header (faces; for polygon
// meshes a lower bound on triangles). Reads the header only.
StatusOr<uint64_t> declared_triangle_count(const std::filesystem::path& path);

// The scene's ground plane: a square of side ground.size at y = ground.height,
// centred under the camera's look-at point, as two triangles facing +y.
TriangleMesh make_ground_mesh(const Ground& ground, const Camera& camera);

// How the BVH is built, by scene size: Embree's high-quality (spatial split)
// builder pays off for small scenes; large ones use the medium builder, and
// very large ones also the compact layout, which stores triangle indices
// instead of vertex copies in the leaves (about half the BVH memory, slower
// traversal).
//
// A large scene that serves fewer camera rays than it has triangles (a
// full-resolution mesh rendered once: 10M triangles, 1280 x 960 at 4 spp) is
// built with Embree's low-quality (Morton code) builder instead: its build is
// then most of the render. Measured (tools/MEASUREMENTS.md, "The BVH builder
// by frame"): on the 10M teapot the build takes 0.8 s instead of 2.4 s and the
// trace 4 to 13% longer; on the 100M glass scene's 9.4M-triangle view 0.9 s
// instead of 2.3 s, the trace 13 to 32% longer (1.24 -> 1.40 to 1.64 s). At
// one camera ray per triangle the glass trace's loss would be about the
// build's gain, hence the threshold. The choice depends on the frame (width x
// height x spp), never on threads or ranks.
struct BvhConfig {
  uint64_t high_quality_below = 2'000'000;  // triangles
  uint64_t compact_from = 20'000'000;       // triangles
  // Camera rays the BVH serves (width x height x spp of every frame traced
  // with it); 0 = unknown, no low-quality build.
  uint64_t camera_rays = 0;
  double low_quality_below_rays_per_triangle = 1.0;
  // Embree's robust mode: watertight-ish traversal, so that rays through
  // shared edges of a closed glass mesh do not leak between triangles.
  bool robust = true;
};

enum class BvhQuality { Low, Medium, High };
// The builder for a scene of `triangles` under `config` (the rules above).
BvhQuality choose_bvh_quality(uint64_t triangles, const BvhConfig& config);

struct BvhInfo {
  uint64_t triangles = 0;
  uint64_t vertices = 0;
  uint64_t mesh_bytes = 0;         // vertex and index arrays (shared with Embree, not copied)
  uint64_t bvh_bytes = 0;          // Embree's allocations after the build (the BVH)
  uint64_t bvh_peak_bytes = 0;     // Embree's peak allocation during the build
  double build_seconds = 0;
  std::string quality;             // "high", "medium", "low", with "+compact"
  Bbox bounds;
  Bbox object_bounds;              // of every mesh but the ground's
};

// A closest hit: distance along the ray, geometry (mesh index) and triangle,
// and Embree's barycentrics: P = (1 - u - v) V0 + u V1 + v V2.
struct Hit {
  double t = 0;
  uint32_t geom = RTC_INVALID_GEOMETRY_ID;
  uint32_t prim = 0;
  float u = 0, v = 0;
};

class EmbreeScene {
 public:
  // Builds one Embree scene holding every mesh (geometry id = index in
  // meshes). The meshes are moved in and shared with Embree, not copied.
  static StatusOr<std::unique_ptr<EmbreeScene>> build(std::vector<TriangleMesh> meshes, const BvhConfig& config = {});
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  RTCScene handle() const { return scene_; }
  const std::vector<TriangleMesh>& meshes() const { return meshes_; }
  const TriangleMesh& mesh(uint32_t geom) const { return meshes_[geom]; }
  // Global triangle id of (geom, prim): triangles numbered mesh after mesh.
  uint64_t triangle_id(uint32_t geom, uint32_t prim) const { return first_triangle_[geom] + prim; }
  const BvhInfo& info() const { return info_; }

  // Closest hit on (tnear, tfar); false if none.
  bool intersect(const Ray& ray, double tnear, double tfar, Hit& hit) const;
  // True if anything lies on the ray within (tnear, tfar).
  bool occluded(const Ray& ray, double tnear, double tfar) const;

  // Up to kPacketSize rays as one Embree packet (rtcIntersect16 /
  // rtcOccluded16), tnear = 0. Lanes past rays.size() are inactive. Embree
  // evaluates the same ray-triangle test per lane as intersect() and
  // occluded(), so the results match the single-ray calls (tested in
  // tests/render/packet_test.cpp). coherent: the rays start near each other
  // with similar directions (camera rays of a pixel block).
  static constexpr int kPacketSize = 16;
  // found[i] = rays[i] hit something on (0, tfar); hits[i] is set only then.
  void intersect_packet(std::span<const Ray> rays, double tfar, bool coherent, Hit* hits, bool* found) const;
  // occluded[i] = something lies on rays[i] within (0, tfar[i]).
  void occluded_packet(std::span<const Ray> rays, const double* tfar, bool* occluded) const;

 private:
  EmbreeScene() = default;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  std::vector<TriangleMesh> meshes_;
  std::vector<uint64_t> first_triangle_;
  BvhInfo info_;
 public:
  struct Monitor;  // Embree error and memory callbacks (implementation detail)
 private:
  std::unique_ptr<Monitor> monitor_;
};

// Surface quantities at a hit, in double.
struct SurfacePoint {
  Vec3d position{0};   // on the triangle, from the barycentrics (not o + t d)
  Vec3d geometric{0};  // unit face normal, right-hand rule over the winding
  Vec3d shading{0};    // unit interpolated vertex normal, or the face normal
  double edge_distance = 0;  // distance to the nearest triangle edge (only if asked for)
};
SurfacePoint surface_point(const EmbreeScene& scene, const Hit& hit, bool with_edge_distance = false);
// The surface points of up to kPacketSize hits at once (lanes with found[i]
// false are skipped; found may be null), each the same as surface_point's.
void surface_points(const EmbreeScene& scene, std::span<const Hit> hits, const bool* found, bool with_edge_distance,
                    SurfacePoint* out);

}  // namespace raylod
