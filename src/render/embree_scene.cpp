// Loading meshes into one Embree 3 scene: streaming read, corner welding,
// world transform, BVH build with a quality chosen by size.
#include "render/embree_scene.h"

#include <atomic>
#include <cassert>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>

#include <tbb/parallel_for.h>
#include <glm/gtc/matrix_transform.hpp>

#include "core/system.h"
#include "geometry/crease_normals.h"
#include "geometry/optics.h"
#include "streaming/draco_io.h"
#include "streaming/mesh_reader.h"

namespace raylod {

uint64_t TriangleMesh::bytes() const {
  return positions.capacity() * sizeof(Vec3) + normals.capacity() * sizeof(Vec3) + indices.capacity() * sizeof(uint32_t);
}

namespace {

// Open-addressing hash set of vertex indices, keyed by the bits of the
// vertex's position (and normal). Readers hand out independent triangles;
// welding them back to shared vertices halves to thirds the resident mesh
// (a closed mesh has about half as many vertices as triangles).
class Welder {
 public:
  Welder(TriangleMesh& mesh, bool with_normals, size_t expected_vertices) : mesh_(mesh), normals_(with_normals) {
    size_t cap = 1024;
    while (cap < expected_vertices * 2) cap <<= 1;
    table_.assign(cap, kEmpty);
    mesh_.positions.reserve(expected_vertices);
    if (normals_) mesh_.normals.reserve(expected_vertices);
  }

  // Returns the vertex index of (p, n), adding the vertex if it is new.
  StatusOr<uint32_t> add(const Vec3& p, const Vec3* n) {
    if ((mesh_.positions.size() + 1) * 2 > table_.size()) grow();
    const size_t mask = table_.size() - 1;
    for (size_t slot = hash(p, n) & mask;; slot = (slot + 1) & mask) {
      uint32_t idx = table_[slot];
      if (idx == kEmpty) {
        if (mesh_.positions.size() >= kEmpty) return Status::error("more than 4 billion vertices");
        idx = uint32_t(mesh_.positions.size());
        mesh_.positions.push_back(p);
        if (normals_) mesh_.normals.push_back(*n);
        table_[slot] = idx;
        return idx;
      }
      if (same(mesh_.positions[idx], p) && (!normals_ || same(mesh_.normals[idx], *n))) return idx;
    }
  }

 private:
  static constexpr uint32_t kEmpty = std::numeric_limits<uint32_t>::max();
  static bool same(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof(Vec3)) == 0; }
  static uint64_t mix(uint64_t h) {  // splitmix64 finaliser
    h ^= h >> 30; h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27; h *= 0x94d049bb133111ebull;
    return h ^ (h >> 31);
  }
  static uint64_t bits(const Vec3& v) {
    return (uint64_t(std::bit_cast<uint32_t>(v.x)) * 0x9e3779b97f4a7c15ull) ^
           (uint64_t(std::bit_cast<uint32_t>(v.y)) * 0xc2b2ae3d27d4eb4full) ^
           (uint64_t(std::bit_cast<uint32_t>(v.z)) * 0x165667b19e3779f9ull);
  }
  uint64_t hash(const Vec3& p, const Vec3* n) const {
    uint64_t h = bits(p);
    if (normals_) h ^= mix(bits(*n));
    return mix(h);
  }
  void grow() {
    std::vector<uint32_t> bigger(table_.size() * 2, kEmpty);
    const size_t mask = bigger.size() - 1;
    for (uint32_t idx = 0; idx < mesh_.positions.size(); ++idx) {
      size_t slot = hash(mesh_.positions[idx], normals_ ? &mesh_.normals[idx] : nullptr) & mask;
      while (bigger[slot] != kEmpty) slot = (slot + 1) & mask;
      bigger[slot] = idx;
    }
    table_.swap(bigger);
  }

  TriangleMesh& mesh_;
  bool normals_;
  std::vector<uint32_t> table_;
};

void transform_mesh(TriangleMesh& mesh, const glm::dmat4& m) {
  if (m == glm::dmat4(1.0)) return;
  const glm::dmat3 normal_matrix = glm::transpose(glm::inverse(glm::dmat3(m)));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.positions.size(), 1 << 14), [&](const auto& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      mesh.positions[i] = Vec3(Vec3d(m * glm::dvec4(Vec3d(mesh.positions[i]), 1.0)));
      if (!mesh.normals.empty()) mesh.normals[i] = Vec3(glm::normalize(normal_matrix * Vec3d(mesh.normals[i])));
    }
  });
  if (glm::determinant(glm::dmat3(m)) < 0)
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3) std::swap(mesh.indices[t + 1], mesh.indices[t + 2]);
}

}  // namespace

TriangleMesh weld_triangles(std::span<const Vec3> positions, std::span<const Vec3> normals) {
  TriangleMesh mesh;
  const bool with_normals = !normals.empty();
  Welder welder(mesh, with_normals, positions.size() / 2);
  mesh.indices.reserve(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    auto idx = welder.add(positions[i], with_normals ? &normals[i] : nullptr);
    mesh.indices.push_back(idx.value());  // in-memory soups are far below 2^32 vertices
  }
  return mesh;
}

StatusOr<uint64_t> declared_triangle_count(const std::filesystem::path& path) {
  // open_mesh decodes a whole .drc; its header carries the count.
  if (auto format = mesh_format_from_extension(path); format.is_ok() && *format == MeshFormat::Draco)
    return draco_triangle_count(path);
  RAYLOD_ASSIGN_OR_RETURN(auto reader, open_mesh(path));
  return reader->header().face_count;
}

void add_crease_normals(TriangleMesh& mesh, double crease_angle_deg) {
  if (!mesh.normals.empty()) return;
  std::vector<Vec3> corner_normals = crease_corner_normals(mesh.positions, mesh.indices, crease_angle_deg);
  std::vector<Vec3> soup(mesh.indices.size());
  for (size_t i = 0; i < mesh.indices.size(); ++i) soup[i] = mesh.positions[mesh.indices[i]];
  TriangleMesh split = weld_triangles(soup, corner_normals);
  mesh.positions = std::move(split.positions);
  mesh.normals = std::move(split.normals);
  mesh.indices = std::move(split.indices);
}

namespace {

// A .drc is indexed already: with normals its points are taken as they are
// (the welder would only find Draco's points again, at the cost of a soup of
// corners).
StatusOr<bool> load_draco_indexed(const std::filesystem::path& path, TriangleMesh& mesh, Vec3d& origin,
                                  const std::function<void(uint64_t)>& on_triangles) {
  auto format = mesh_format_from_extension(path);
  if (!format.is_ok() || *format != MeshFormat::Draco) return false;
  RAYLOD_RETURN_IF_ERROR(check_regular_file(path));  // as open_mesh: a FIFO or device fails at once
  RAYLOD_ASSIGN_OR_RETURN(IndexedMesh decoded, read_draco(path));
  origin = decoded.origin;
  if (decoded.normals.empty()) {
    // Crease normals smooth across shared positions: weld Draco's points by
    // position first (it may keep points that share one apart).
    std::vector<Vec3> soup(decoded.indices.size());
    for (size_t i = 0; i < soup.size(); ++i) soup[i] = decoded.positions[decoded.indices[i]];
    TriangleMesh welded = weld_triangles(soup, {});
    mesh.positions = std::move(welded.positions);
    mesh.indices = std::move(welded.indices);
  } else {
    mesh.positions = std::move(decoded.positions);
    mesh.normals = std::move(decoded.normals);
    mesh.indices = std::move(decoded.indices);
  }
  if (on_triangles) on_triangles(mesh.triangle_count());
  return true;
}

// Crease normals where the file has none, then into the world: positions are
// relative to the reader's local origin (a mesh far from zero).
Status place_mesh(TriangleMesh& mesh, const std::filesystem::path& path, const Vec3d& origin,
                  const glm::dmat4& object_to_world, double crease_angle_deg) {
  if (mesh.normals.empty()) add_crease_normals(mesh, crease_angle_deg);
  transform_mesh(mesh, origin == Vec3d(0) ? object_to_world : object_to_world * glm::translate(glm::dmat4(1.0), origin));
  for (const Vec3& p : mesh.positions)
    if (!is_finite(p)) return Status::error(path.string() + ": the object's transform puts its vertices beyond the float range (Inf or NaN)");
  return {};
}

}  // namespace

StatusOr<TriangleMesh> load_triangle_mesh(const std::filesystem::path& path, const glm::dmat4& object_to_world,
                                          int material, double crease_angle_deg,
                                          const std::function<void(uint64_t)>& on_triangles) {
  TriangleMesh mesh;
  mesh.material = material;
  mesh.name = path.filename().string();
  Vec3d draco_origin(0);
  RAYLOD_ASSIGN_OR_RETURN(bool indexed, load_draco_indexed(path, mesh, draco_origin, on_triangles));
  if (indexed) {
    RAYLOD_RETURN_IF_ERROR(place_mesh(mesh, path, draco_origin, object_to_world, crease_angle_deg));
    return mesh;
  }
  RAYLOD_ASSIGN_OR_RETURN(auto reader, open_mesh(path));
  const uint64_t faces = reader->header().face_count;
  mesh.indices.reserve(size_t(faces) * 3);
  std::unique_ptr<Welder> welder;
  bool with_normals = false;
  TriangleBatch batch;
  while (true) {
    RAYLOD_ASSIGN_OR_RETURN(bool more, reader->next(batch));
    if (!more) break;
    if (!welder) {
      with_normals = !batch.normals.empty();
      welder = std::make_unique<Welder>(mesh, with_normals, size_t(faces / 2 + 16));
    } else if (with_normals != !batch.normals.empty()) {
      return Status::error(path.string() + ": reader returned batches with and without normals");
    }
    for (size_t i = 0; i < batch.positions.size(); ++i) {
      auto idx = welder->add(batch.positions[i], with_normals ? &batch.normals[i] : nullptr);
      if (!idx) return idx.status().with_context(path.string());
      mesh.indices.push_back(*idx);
    }
    if (on_triangles) on_triangles(batch.size());
  }
  if (mesh.indices.empty()) return Status::error(path.string() + ": empty mesh (no triangles)");
  welder.reset();
  RAYLOD_RETURN_IF_ERROR(place_mesh(mesh, path, reader->header().origin, object_to_world, crease_angle_deg));
  return mesh;
}

TriangleMesh make_ground_mesh(const Ground& ground, const Camera& camera) {
  TriangleMesh m;
  const double h = ground.size * 0.5;
  const double cx = camera.look_at.x, cz = camera.look_at.z, y = ground.height;
  // a=(x0,z0) b=(x0,z1) c=(x1,z1) d=(x1,z0): (b-a) x (c-a) points to +y.
  m.positions = {Vec3(Vec3d(cx - h, y, cz - h)), Vec3(Vec3d(cx - h, y, cz + h)), Vec3(Vec3d(cx + h, y, cz + h)),
                 Vec3(Vec3d(cx + h, y, cz - h))};
  m.indices = {0, 1, 2, 0, 2, 3};
  m.material = ground.material;
  m.name = kGroundMeshName;
  return m;
}

struct EmbreeScene::Monitor {
  std::atomic<int64_t> current{0}, peak{0};
  std::mutex mutex;
  std::string error;
};

namespace {

void on_embree_error(void* user, RTCError code, const char* message) {
  auto* mon = static_cast<EmbreeScene::Monitor*>(user);
  std::lock_guard<std::mutex> lock(mon->mutex);
  if (mon->error.empty()) mon->error = std::string("Embree error ") + std::to_string(int(code)) + ": " + (message ? message : "");
}

bool on_embree_memory(void* user, ssize_t bytes, bool /*post*/) {
  auto* mon = static_cast<EmbreeScene::Monitor*>(user);
  const int64_t now = mon->current.fetch_add(bytes) + bytes;
  int64_t peak = mon->peak.load();
  while (now > peak && !mon->peak.compare_exchange_weak(peak, now)) {}
  return true;
}

}  // namespace

BvhQuality choose_bvh_quality(uint64_t triangles, const BvhConfig& config) {
  if (triangles < config.high_quality_below) return BvhQuality::High;
  if (config.camera_rays > 0 &&
      double(config.camera_rays) < config.low_quality_below_rays_per_triangle * double(triangles))
    return BvhQuality::Low;
  return BvhQuality::Medium;
}

StatusOr<std::unique_ptr<EmbreeScene>> EmbreeScene::build(std::vector<TriangleMesh> meshes, const BvhConfig& config) {
  std::unique_ptr<EmbreeScene> s(new EmbreeScene());
  s->meshes_ = std::move(meshes);
  s->monitor_ = std::make_unique<Monitor>();
  BvhInfo& info = s->info_;
  for (size_t g = 0; g < s->meshes_.size(); ++g) {
    TriangleMesh& m = s->meshes_[g];
    if (m.indices.size() % 3 != 0) return Status::error(m.name + ": index count is not a multiple of 3");
    if (!m.normals.empty() && m.normals.size() != m.positions.size())
      return Status::error(m.name + ": normal count differs from vertex count");
    for (uint32_t idx : m.indices)
      if (idx >= m.positions.size()) return Status::error(m.name + ": vertex index out of range");
    if (m.name != kGroundMeshName)
      for (const Vec3& p : m.positions) info.object_bounds.expand(Vec3d(p));
    s->first_triangle_.push_back(info.triangles);
    info.triangles += m.triangle_count();
    info.vertices += m.positions.size();
    // Embree reads vertex buffers with 16-byte loads: the last 12-byte vertex
    // needs 4 readable bytes after it.
    if (m.positions.capacity() < m.positions.size() + 1) m.positions.reserve(m.positions.size() + 1);
    info.mesh_bytes += m.bytes();
  }
  if (info.triangles == 0) return Status::error("the scene has no triangles");

  s->device_ = rtcNewDevice(nullptr);
  if (!s->device_) return Status::error("cannot create an Embree device (error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(s->device_, on_embree_error, s->monitor_.get());
  rtcSetDeviceMemoryMonitorFunction(s->device_, on_embree_memory, s->monitor_.get());

  const BvhQuality chosen = choose_bvh_quality(info.triangles, config);
  const RTCBuildQuality quality = chosen == BvhQuality::High     ? RTC_BUILD_QUALITY_HIGH
                                  : chosen == BvhQuality::Medium ? RTC_BUILD_QUALITY_MEDIUM
                                                                 : RTC_BUILD_QUALITY_LOW;
  const bool compact = info.triangles >= config.compact_from;
  info.quality = std::string(chosen == BvhQuality::High ? "high" : chosen == BvhQuality::Medium ? "medium" : "low") +
                 (compact ? "+compact" : "");
  int flags = RTC_SCENE_FLAG_NONE;
  if (compact) flags |= RTC_SCENE_FLAG_COMPACT;
  if (config.robust) flags |= RTC_SCENE_FLAG_ROBUST;

  const auto start = std::chrono::steady_clock::now();
  s->scene_ = rtcNewScene(s->device_);
  rtcSetSceneFlags(s->scene_, RTCSceneFlags(flags));
  rtcSetSceneBuildQuality(s->scene_, quality);
  for (size_t g = 0; g < s->meshes_.size(); ++g) {
    TriangleMesh& m = s->meshes_[g];
    if (m.triangle_count() == 0) continue;
    RTCGeometry geom = rtcNewGeometry(s->device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, m.positions.data(), 0, sizeof(Vec3),
                               m.positions.size());
    rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m.indices.data(), 0,
                               3 * sizeof(uint32_t), m.triangle_count());
    rtcSetGeometryBuildQuality(geom, quality);
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(s->scene_, geom, unsigned(g));
    rtcReleaseGeometry(geom);
  }
  {
    const ScopedSmallPages small_pages;  // core/system.h: the build's blocks are touched sparsely
    rtcCommitScene(s->scene_);
  }
  info.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (rtcGetDeviceError(s->device_) != RTC_ERROR_NONE || !s->monitor_->error.empty()) {
    std::string msg = s->monitor_->error.empty() ? "Embree failed to build the BVH" : s->monitor_->error;
    return Status::error(msg + " (" + std::to_string(info.triangles) + " triangles)");
  }
  info.bvh_bytes = uint64_t(std::max<int64_t>(0, s->monitor_->current.load()));
  info.bvh_peak_bytes = uint64_t(std::max<int64_t>(0, s->monitor_->peak.load()));
  RTCBounds b;
  rtcGetSceneBounds(s->scene_, &b);
  info.bounds.expand(Vec3d(b.lower_x, b.lower_y, b.lower_z));
  info.bounds.expand(Vec3d(b.upper_x, b.upper_y, b.upper_z));
  return s;
}

EmbreeScene::~EmbreeScene() {
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
}

bool EmbreeScene::intersect(const Ray& ray, double tnear, double tfar, Hit& hit) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = float(ray.origin.x);
  rh.ray.org_y = float(ray.origin.y);
  rh.ray.org_z = float(ray.origin.z);
  rh.ray.dir_x = float(ray.direction.x);
  rh.ray.dir_y = float(ray.direction.y);
  rh.ray.dir_z = float(ray.direction.z);
  rh.ray.tnear = float(tnear);
  rh.ray.tfar = float(tfar);
  rh.ray.time = 0;
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene_, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  hit.t = rh.ray.tfar;
  hit.geom = rh.hit.geomID;
  hit.prim = rh.hit.primID;
  hit.u = rh.hit.u;
  hit.v = rh.hit.v;
  return true;
}

bool EmbreeScene::occluded(const Ray& ray, double tnear, double tfar) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  r.org_x = float(ray.origin.x);
  r.org_y = float(ray.origin.y);
  r.org_z = float(ray.origin.z);
  r.dir_x = float(ray.direction.x);
  r.dir_y = float(ray.direction.y);
  r.dir_z = float(ray.direction.z);
  r.tnear = float(tnear);
  r.tfar = float(tfar);
  r.time = 0;
  r.mask = 0xffffffffu;
  r.id = 0;
  r.flags = 0;
  rtcOccluded1(scene_, &ctx, &r);
  return r.tfar < 0;  // Embree sets tfar to -inf on a hit
}

namespace {
// Ray i of an Embree SoA packet (RTCRay16 or the ray part of RTCRayHit16).
void set_packet_ray(RTCRay16& r, int i, const Ray& ray, double tfar) {
  r.org_x[i] = float(ray.origin.x);
  r.org_y[i] = float(ray.origin.y);
  r.org_z[i] = float(ray.origin.z);
  r.dir_x[i] = float(ray.direction.x);
  r.dir_y[i] = float(ray.direction.y);
  r.dir_z[i] = float(ray.direction.z);
  r.tnear[i] = 0.0f;
  r.tfar[i] = float(tfar);
  r.time[i] = 0;
  r.mask[i] = 0xffffffffu;
  r.id[i] = unsigned(i);
  r.flags[i] = 0;
}
}  // namespace

void EmbreeScene::intersect_packet(std::span<const Ray> rays, double tfar, bool coherent, Hit* hits,
                                   bool* found) const {
  assert(rays.size() <= size_t(kPacketSize));
  if (rays.empty()) return;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(64) RTCRayHit16 rh;
  alignas(64) int valid[kPacketSize];
  for (int i = 0; i < kPacketSize; ++i) {
    const bool active = size_t(i) < rays.size();
    valid[i] = active ? -1 : 0;
    // Inactive lanes repeat ray 0 so that their fields are finite.
    set_packet_ray(rh.ray, i, rays[active ? size_t(i) : 0], tfar);
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect16(valid, scene_, &ctx, &rh);
  for (size_t i = 0; i < rays.size(); ++i) {
    found[i] = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID;
    if (!found[i]) continue;
    hits[i].t = rh.ray.tfar[i];
    hits[i].geom = rh.hit.geomID[i];
    hits[i].prim = rh.hit.primID[i];
    hits[i].u = rh.hit.u[i];
    hits[i].v = rh.hit.v[i];
  }
}

void EmbreeScene::occluded_packet(std::span<const Ray> rays, const double* tfar, bool* occluded) const {
  assert(rays.size() <= size_t(kPacketSize));
  if (rays.empty()) return;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  alignas(64) RTCRay16 r;
  alignas(64) int valid[kPacketSize];
  for (int i = 0; i < kPacketSize; ++i) {
    const bool active = size_t(i) < rays.size();
    valid[i] = active ? -1 : 0;
    set_packet_ray(r, i, rays[active ? size_t(i) : 0], tfar[active ? i : 0]);
  }
  rtcOccluded16(valid, scene_, &ctx, &r);
  for (size_t i = 0; i < rays.size(); ++i) occluded[i] = r.tfar[i] < 0;  // -inf on a hit
}

void surface_points(const EmbreeScene& scene, std::span<const Hit> hits, const bool* found, bool with_edge_distance,
                    SurfacePoint* out) {
  // In three passes over the lanes -- fetch and cross products, square roots,
  // divisions -- so that the lanes' sqrt and division chains overlap instead
  // of each lane waiting out its own (their latency, not the fetches, is most
  // of a camera hit's shading). Per lane, the arithmetic is that of one point.
  constexpr int kMax = EmbreeScene::kPacketSize;
  assert(hits.size() <= size_t(kMax));
  const int n = int(hits.size());
  Vec3d cr[kMax], ns[kMax];
  double area2[kMax], normal2[kMax], w[kMax], edge2[kMax][3];
  bool has_normals[kMax];
  for (int i = 0; i < n; ++i) {
    if (found && !found[i]) continue;
    const Hit& hit = hits[size_t(i)];
    const TriangleMesh& m = scene.mesh(hit.geom);
    const uint32_t* tri = &m.indices[size_t(hit.prim) * 3];
    const Vec3d a(m.positions[tri[0]]), b(m.positions[tri[1]]), c(m.positions[tri[2]]);
    const double u = hit.u, v = hit.v;
    w[i] = 1.0 - u - v;
    SurfacePoint& sp = out[i];
    sp.position = a + u * (b - a) + v * (c - a);
    cr[i] = glm::cross(b - a, c - a);
    area2[i] = glm::dot(cr[i], cr[i]);
    has_normals[i] = !m.normals.empty();
    if (has_normals[i]) {
      ns[i] = w[i] * Vec3d(m.normals[tri[0]]) + u * Vec3d(m.normals[tri[1]]) + v * Vec3d(m.normals[tri[2]]);
      normal2[i] = glm::dot(ns[i], ns[i]);
    } else {
      ns[i] = Vec3d(0);
      normal2[i] = 0;
    }
    if (with_edge_distance) {
      // Opposite corners a, b, c: |c - b|, |c - a|, |b - a|, squared.
      edge2[i][0] = glm::dot(c - b, c - b);
      edge2[i][1] = glm::dot(c - a, c - a);
      edge2[i][2] = glm::dot(b - a, b - a);
    }
  }
  double twice_area[kMax], normal_length[kMax], edge[kMax][3];
  for (int i = 0; i < n; ++i) {
    if (found && !found[i]) continue;
    twice_area[i] = std::sqrt(area2[i]);
    normal_length[i] = has_normals[i] ? std::sqrt(normal2[i]) : 0.0;
    if (with_edge_distance)
      for (int k = 0; k < 3; ++k) edge[i][k] = std::sqrt(edge2[i][k]);
  }
  for (int i = 0; i < n; ++i) {
    if (found && !found[i]) continue;
    SurfacePoint& sp = out[i];
    sp.geometric = twice_area[i] > 0 ? cr[i] / twice_area[i] : Vec3d(0, 0, 1);
    sp.shading = sp.geometric;
    if (has_normals[i]) {
      if (normal_length[i] > kMinShadingNormalLength) sp.shading = ns[i] / normal_length[i];
      // The vertex normals say which side is outside; the winding may disagree
      // (CAD exports, and the reverse-wound twins a collapse keeps), so orient
      // the face normal by them, as the probe does: inside/outside for glass
      // then follows the normals, not whichever twin Embree reports.
      if (glm::dot(sp.geometric, sp.shading) < 0) sp.geometric = -sp.geometric;
    }
  }
  if (!with_edge_distance) return;
  for (int i = 0; i < n; ++i) {
    if (found && !found[i]) continue;
    // Distance to edge k = barycentric_k * height over that edge = b_k * 2A / |edge_k|.
    const double barycentric[3] = {w[i], double(hits[size_t(i)].u), double(hits[size_t(i)].v)};
    double d = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k)
      if (edge[i][k] > 0) d = std::min(d, barycentric[k] * twice_area[i] / edge[i][k]);
    out[i].edge_distance = std::isfinite(d) ? d : 0.0;
  }
}

SurfacePoint surface_point(const EmbreeScene& scene, const Hit& hit, bool with_edge_distance) {
  SurfacePoint sp;
  surface_points(scene, {&hit, 1}, nullptr, with_edge_distance, &sp);
  return sp;
}

}  // namespace raylod
