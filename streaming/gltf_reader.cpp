// The glTF MeshReader: triangles from every triangle primitive of the
// selection (streaming/gltf_io.h), streamed corner by corner from the
// accessors (glTF 2.0, section 3.7.2.1 "Topology Types": strips give
// {v_i, v_{i+(1+i%2)}, v_{i+(2-i%2)}}, fans {v_{i+1}, v_{i+2}, v_0}), or
// from the decoded mesh of a KHR_draco_mesh_compression primitive.
#include <cinttypes>
#include <cstdio>
#include <mutex>
#include <set>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>

#include "streaming/draco_io.h"
#include "streaming/gltf_model.h"
#include "streaming/vertex_table.h"

namespace raylod {
namespace gltf {
namespace {

constexpr const char* kDraco = "KHR_draco_mesh_compression";

// One triangle primitive, checked: its views (or its Draco bytes) and how
// many triangles its accessors declare.
struct PrimitivePlan {
  int mesh = -1, primitive = -1;
  std::string where;                 // "meshes[2].primitives[0]"
  int mode = 4;
  bool draco = false;
  AccessorView position, normal, indices;
  bool has_normal = false, has_indices = false;
  const uint8_t* draco_data = nullptr;  // KHR_draco_mesh_compression: the bufferView's bytes
  size_t draco_size = 0;
  int draco_position = -1, draco_normal = -1;  // Draco attribute unique ids
  uint64_t triangles = 0;            // declared
  uint64_t vertices = 0;
};

std::string mesh_where(int mesh) { return "meshes[" + std::to_string(mesh) + "]"; }

StatusOr<int> attribute(const tinygltf::Primitive& p, const char* name) {
  auto it = p.attributes.find(name);
  return it == p.attributes.end() ? -1 : it->second;
}

Status plan_draco(const LoadedModel& loaded, const tinygltf::Primitive& p, PrimitivePlan& plan) {
  const tinygltf::Model& model = loaded.model;
  const tinygltf::Value& ext = p.extensions.at(kDraco);
  const std::string where = plan.where + ".extensions." + kDraco;
  if (!ext.IsObject() || !ext.Has("bufferView") || !ext.Get("bufferView").IsInt())
    return Status::error(where + ": needs an integer bufferView");
  const int view = ext.Get("bufferView").GetNumberAsInt();
  if (view < 0 || size_t(view) >= model.bufferViews.size())
    return Status::error(where + ": bufferView " + std::to_string(view) + " does not exist (the file has " +
                         std::to_string(model.bufferViews.size()) + ")");
  const tinygltf::BufferView& v = model.bufferViews[size_t(view)];
  if (v.buffer < 0 || size_t(v.buffer) >= model.buffers.size())
    return Status::error(where + ": bufferView " + std::to_string(view) + ": buffer " + std::to_string(v.buffer) +
                         " does not exist");
  const tinygltf::Buffer& b = model.buffers[size_t(v.buffer)];
  if (v.byteOffset > b.data.size() || v.byteLength > b.data.size() - v.byteOffset)
    return Status::error(where + ": bufferView " + std::to_string(view) + " (bytes " + std::to_string(v.byteOffset) +
                         " + " + std::to_string(v.byteLength) + ") is past the end of buffer " + std::to_string(v.buffer) +
                         " (" + std::to_string(b.data.size()) + " bytes)");
  plan.draco_data = b.data.data() + v.byteOffset;
  plan.draco_size = v.byteLength;
  if (!ext.Has("attributes") || !ext.Get("attributes").IsObject())
    return Status::error(where + ": needs an attributes object");
  const tinygltf::Value& attrs = ext.Get("attributes");
  if (!attrs.Has("POSITION") || !attrs.Get("POSITION").IsInt())
    return Status::error(where + ".attributes: no POSITION");
  plan.draco_position = attrs.Get("POSITION").GetNumberAsInt();
  if (attrs.Has("NORMAL") && attrs.Get("NORMAL").IsInt()) plan.draco_normal = attrs.Get("NORMAL").GetNumberAsInt();
  plan.has_normal = plan.draco_normal >= 0;
  // The accessors keep their counts (the extension's spec): the declared size.
  const int pos = p.attributes.at("POSITION");
  if (pos >= 0 && size_t(pos) < model.accessors.size()) plan.vertices = model.accessors[size_t(pos)].count;
  if (auto it = loaded.draco_indices.find({plan.mesh, plan.primitive});
      it != loaded.draco_indices.end() && it->second >= 0 && size_t(it->second) < model.accessors.size())
    plan.triangles = model.accessors[size_t(it->second)].count / 3;
  return Status::ok();
}

StatusOr<PrimitivePlan> plan_primitive(const LoadedModel& loaded, int mesh, int primitive) {
  const tinygltf::Model& model = loaded.model;
  const tinygltf::Primitive& p = model.meshes[size_t(mesh)].primitives[size_t(primitive)];
  PrimitivePlan plan;
  plan.mesh = mesh;
  plan.primitive = primitive;
  plan.where = mesh_where(mesh) + ".primitives[" + std::to_string(primitive) + "]";
  plan.mode = p.mode < 0 ? 4 : p.mode;
  RAYLOD_ASSIGN_OR_RETURN(int pos, attribute(p, "POSITION"));
  if (pos < 0) return Status::error(plan.where + ": no POSITION attribute");
  RAYLOD_ASSIGN_OR_RETURN(int nrm, attribute(p, "NORMAL"));
  if (p.extensions.count(kDraco)) {
    plan.draco = true;
    RAYLOD_RETURN_IF_ERROR(plan_draco(loaded, p, plan));
    return plan;
  }
  RAYLOD_ASSIGN_OR_RETURN(plan.position, view_accessor(model, pos, AccessorUse::Position, plan.where));
  plan.vertices = plan.position.count;
  if (nrm >= 0) {
    RAYLOD_ASSIGN_OR_RETURN(plan.normal, view_accessor(model, nrm, AccessorUse::Normal, plan.where));
    if (plan.normal.count != plan.position.count)
      return Status::error(plan.where + ": NORMAL has " + std::to_string(plan.normal.count) + " elements, POSITION " +
                           std::to_string(plan.position.count));
    plan.has_normal = true;
  }
  uint64_t n = plan.position.count;
  if (p.indices >= 0) {
    RAYLOD_ASSIGN_OR_RETURN(plan.indices, view_accessor(model, p.indices, AccessorUse::Indices, plan.where));
    plan.has_indices = true;
    n = plan.indices.count;
  }
  if (plan.mode == 4) {
    if (n % 3 != 0)
      return Status::error(plan.where + ": TRIANGLES with " + std::to_string(n) + (plan.has_indices ? " indices" : " vertices") +
                           ", not a multiple of 3");
    plan.triangles = n / 3;
  } else {
    plan.triangles = n >= 3 ? n - 2 : 0;
  }
  return plan;
}

// The triangle primitives of one mesh, and how many others were skipped.
Status plan_mesh(const LoadedModel& loaded, int mesh, std::vector<PrimitivePlan>& out, uint32_t& skipped) {
  const tinygltf::Model& model = loaded.model;
  const tinygltf::Mesh& m = model.meshes[size_t(mesh)];
  for (size_t i = 0; i < m.primitives.size(); ++i) {
    const int mode = m.primitives[i].mode < 0 ? 4 : m.primitives[i].mode;
    if (mode > 6)
      return Status::error(mesh_where(mesh) + ".primitives[" + std::to_string(i) + "]: mode " + std::to_string(mode) +
                           " is not a glTF primitive mode (0 to 6)");
    if (!is_triangle_mode(mode)) {
      ++skipped;  // POINTS, LINES, LINE_LOOP, LINE_STRIP
      continue;
    }
    RAYLOD_ASSIGN_OR_RETURN(PrimitivePlan plan, plan_primitive(loaded, mesh, int(i)));
    out.push_back(std::move(plan));
  }
  return Status::ok();
}

// A piece of the output: one primitive under one transform.
struct Piece {
  size_t plan = 0;
  glm::dmat4 transform{1.0};
  glm::dmat3 normal_matrix{1.0};
  bool identity = true;
  bool mirror = false;
};

class GltfReader final : public MeshReader {
 public:
  GltfReader(std::shared_ptr<const LoadedModel> model, std::vector<PrimitivePlan> plans, std::vector<Piece> pieces,
             uint32_t skipped, ReaderOptions options)
      : model_(std::move(model)), plans_(std::move(plans)), pieces_(std::move(pieces)), skipped_(skipped), options_(options) {}

  StatusOr<bool> next(TriangleBatch& batch) override {
    batch.clear();
    const size_t limit = std::max<size_t>(1, options_.batch_triangles);
    while (batch.size() < limit && piece_ < pieces_.size()) {
      if (!prepared_) RAYLOD_RETURN_IF_ERROR(prepare());
      const Piece& piece = pieces_[piece_];
      const PrimitivePlan& plan = plans_[piece.plan];
      const uint64_t total = plan.draco ? draco_.triangle_count() : plan.triangles;
      for (; next_triangle_ < total && batch.size() < limit; ++next_triangle_)
        RAYLOD_RETURN_IF_ERROR(emit(piece, plan, next_triangle_, batch));
      if (next_triangle_ == total) {
        ++piece_;
        next_triangle_ = 0;
        prepared_ = false;
        draco_ = IndexedMesh{};
      }
    }
    if (batch.size() > 0) {
      emitted_ += batch.size();
      return true;
    }
    if (emitted_ == 0) return Status::error(path_.string() + ": empty mesh (its triangle primitives have no triangles)");
    warn_repaired_normals();
    warn_skipped();
    return false;
  }

 private:
  // Decodes the current piece's Draco primitive (accessor primitives need nothing).
  Status prepare() {
    prepared_ = true;
    const PrimitivePlan& plan = plans_[pieces_[piece_].plan];
    if (!plan.draco) return Status::ok();
    const std::string where = path_.string() + ": " + plan.where + ".extensions." + kDraco;
    RAYLOD_RETURN_IF_ERROR(
        check_draco_counts(reinterpret_cast<const char*>(plan.draco_data), plan.draco_size, where + ": "));
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(plan.draco_data), plan.draco_size);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok()) return Status::error(where + ": Draco decoding failed: " + decoded.status().error_msg_string());
    std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
    if (!dm) return Status::error(where + ": the Draco data holds no mesh");
    const draco::PointAttribute* pos = dm->GetAttributeByUniqueId(uint32_t(plan.draco_position));
    if (!pos || pos->num_components() != 3)
      return Status::error(where + ": no 3-component Draco attribute with id " + std::to_string(plan.draco_position) +
                           " (POSITION)");
    if (!draco_attribute_holds_numbers(*pos)) return Status::error(where + ": the POSITION attribute does not hold numbers");
    const draco::PointAttribute* nrm = nullptr;
    if (header_.has_normals) {
      nrm = dm->GetAttributeByUniqueId(uint32_t(plan.draco_normal));
      if (!nrm || nrm->num_components() != 3)
        return Status::error(where + ": no 3-component Draco attribute with id " + std::to_string(plan.draco_normal) +
                             " (NORMAL)");
      if (!draco_attribute_holds_numbers(*nrm)) return Status::error(where + ": the NORMAL attribute does not hold numbers");
    }
    const uint32_t n = dm->num_points();
    draco_.positions.resize(n);
    if (nrm) draco_.normals.resize(n);
    for (uint32_t i = 0; i < n; ++i) {
      const draco::PointIndex pi(i);
      if (!pos->ConvertValue<float, 3>(pos->mapped_index(pi), &draco_.positions[i].x))
        return Status::error(where + ": bad position for point " + std::to_string(i));
      if (nrm && !nrm->ConvertValue<float, 3>(nrm->mapped_index(pi), &draco_.normals[i].x))
        return Status::error(where + ": bad normal for point " + std::to_string(i));
    }
    draco_.indices.resize(size_t(dm->num_faces()) * 3);
    for (uint32_t t = 0; t < dm->num_faces(); ++t) {
      const auto& face = dm->face(draco::FaceIndex(t));
      for (int k = 0; k < 3; ++k) {
        if (face[k].value() >= n) return Status::error(where + ": Draco face " + std::to_string(t) + " has an index out of range");
        draco_.indices[3 * size_t(t) + k] = face[k].value();
      }
    }
    return Status::ok();
  }

  // The vertex (into POSITION) of corner k of triangle t.
  StatusOr<uint32_t> corner(const PrimitivePlan& plan, uint64_t t, int k) const {
    uint64_t e;  // element of the index sequence (or of POSITION when not indexed)
    if (plan.mode == 4) e = 3 * t + uint64_t(k);
    else if (plan.mode == 5) e = k == 0 ? t : k == 1 ? t + 1 + t % 2 : t + 2 - t % 2;
    else e = k == 0 ? t + 1 : k == 1 ? t + 2 : 0;
    const uint64_t v = plan.has_indices ? plan.indices.index(size_t(e)) : e;
    if (v >= plan.position.count)
      return Status::error(path_.string() + ": " + plan.where + ": index " + std::to_string(v) + " (indices element " +
                           std::to_string(e) + ") is out of range: POSITION has " + std::to_string(plan.position.count) +
                           " elements");
    return uint32_t(v);
  }

  Status emit(const Piece& piece, const PrimitivePlan& plan, uint64_t t, TriangleBatch& batch) {
    Vec3 p[3], n[3];
    for (int k = 0; k < 3; ++k) {
      Vec3d local, normal(0);
      uint64_t v;
      if (plan.draco) {
        v = draco_.indices[3 * t + uint64_t(k)];
        local = Vec3d(draco_.positions[v]);
        if (header_.has_normals) normal = Vec3d(draco_.normals[v]);
      } else {
        RAYLOD_ASSIGN_OR_RETURN(uint32_t vi, corner(plan, t, k));
        v = vi;
        local = plan.position.vec3(vi);
        if (header_.has_normals) normal = plan.normal.vec3(vi);
      }
      const std::string what = plan.where + (plan.draco ? ": Draco point " : ": POSITION element ") + std::to_string(v);
      if (!std::isfinite(local.x) || !std::isfinite(local.y) || !std::isfinite(local.z))
        return Status::error(path_.string() + ": " + what + " is not finite " + vec_text(local));
      const Vec3d world = piece.identity ? local : Vec3d(piece.transform * glm::dvec4(local, 1.0));
      if (beyond_float_range(world) || !std::isfinite(world.x) || !std::isfinite(world.y) || !std::isfinite(world.z))
        return Status::error(path_.string() + ": " + what + " is beyond the float range (about +-3.4e38) " +
                             (piece.identity ? "" : "after its node transform ") + vec_text(world));
      p[k] = Vec3(world - header_.origin);
      if (header_.has_normals) {
        if (!std::isfinite(normal.x) || !std::isfinite(normal.y) || !std::isfinite(normal.z))
          return Status::error(path_.string() + ": " + plan.where + ": the normal of vertex " + std::to_string(v) +
                               " is not finite " + vec_text(normal));
        Vec3d turned = piece.identity ? normal : piece.normal_matrix * normal;
        const double len = glm::length(turned);
        n[k] = len > 0 && std::isfinite(len) ? Vec3(turned / len) : Vec3(0);
      }
    }
    if (piece.mirror) {
      std::swap(p[1], p[2]);
      std::swap(n[1], n[2]);
    }
    const size_t first = batch.positions.size();
    batch.positions.insert(batch.positions.end(), p, p + 3);
    if (header_.has_normals) {
      batch.normals.insert(batch.normals.end(), n, n + 3);
      repaired_normals_ += uint64_t(repair_zero_normals(&batch.positions[first], &batch.normals[first]));
    }
    return Status::ok();
  }

  void warn_skipped() const {
    if (skipped_ == 0) return;
    static std::mutex mutex;
    static std::set<std::string> warned;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (!warned.insert(path_.string()).second) return;
    }
    std::fprintf(stderr, "raylod: warning: %s: %u point or line primitive%s skipped (only triangles are read)\n",
                 path_.string().c_str(), skipped_, skipped_ == 1 ? "" : "s");
  }

  friend StatusOr<std::unique_ptr<MeshReader>> open_reader(const std::filesystem::path&, ReaderOptions);
  std::shared_ptr<const LoadedModel> model_;  // keeps the buffers the views point into
  std::vector<PrimitivePlan> plans_;
  std::vector<Piece> pieces_;
  uint32_t skipped_ = 0;
  ReaderOptions options_;
  size_t piece_ = 0;
  uint64_t next_triangle_ = 0;
  bool prepared_ = false;
  IndexedMesh draco_;  // the current Draco primitive, decoded
  uint64_t emitted_ = 0;
};

StatusOr<std::unique_ptr<MeshReader>> open_reader(const std::filesystem::path& path, ReaderOptions options) {
  const MeshRef ref = parse_mesh_ref(path);
  RAYLOD_ASSIGN_OR_RETURN(std::shared_ptr<const LoadedModel> loaded, load_model(ref.file));
  const tinygltf::Model& model = loaded->model;
  const std::string name = path.string();
  // Which meshes, under which transforms.
  std::vector<GltfInstance> instances;
  if (ref.gltf_mesh >= 0) {
    if (size_t(ref.gltf_mesh) >= model.meshes.size())
      return Status::error(name + ": the file has " + std::to_string(model.meshes.size()) + " meshes, no meshes[" +
                           std::to_string(ref.gltf_mesh) + "]");
    instances.push_back(GltfInstance{ref.gltf_mesh, glm::dmat4(1.0), ""});
  } else {
    auto found = mesh_instances(model);
    if (!found) return found.status().with_context(name);
    instances = std::move(*found);
  }
  std::vector<PrimitivePlan> plans;
  std::vector<std::pair<size_t, size_t>> mesh_plans(model.meshes.size(), {0, 0});  // first plan, count
  std::vector<bool> planned(model.meshes.size(), false);
  uint32_t skipped = 0;
  std::vector<Piece> pieces;
  for (const GltfInstance& inst : instances) {
    const size_t m = size_t(inst.mesh);
    if (!planned[m]) {
      planned[m] = true;
      const size_t first = plans.size();
      if (Status st = plan_mesh(*loaded, inst.mesh, plans, skipped); !st) return st.with_context(name);
      mesh_plans[m] = {first, plans.size() - first};
    }
    Piece piece;
    piece.transform = inst.transform;
    piece.identity = inst.transform == glm::dmat4(1.0);
    piece.normal_matrix = glm::transpose(glm::inverse(glm::dmat3(inst.transform)));
    piece.mirror = glm::determinant(glm::dmat3(inst.transform)) < 0;
    for (size_t i = 0; i < mesh_plans[m].second; ++i) {
      piece.plan = mesh_plans[m].first + i;
      pieces.push_back(piece);
    }
  }
  if (pieces.empty())
    return Status::error(name + ": no triangles: " +
                         (instances.empty() ? std::string("the scene places no mesh")
                                            : std::to_string(skipped) + " point or line primitive(s) and no triangle primitive"));
  auto reader = std::make_unique<GltfReader>(loaded, std::move(plans), std::move(pieces), skipped, options);
  reader->path_ = path;
  MeshHeader& h = reader->header_;
  h.format = MeshFormat::Gltf;
  h.encoding = loaded->binary ? "glb" : "gltf (JSON)";
  h.has_normals = true;
  for (const Piece& piece : reader->pieces_) {
    const PrimitivePlan& plan = reader->plans_[piece.plan];
    h.vertex_count += plan.vertices;
    h.face_count += plan.triangles;
    h.has_normals = h.has_normals && plan.has_normal;
  }
  h.file_bytes = loaded->file_bytes;
  // A mesh placed far from zero by its node (a simplified far mesh raylod
  // exported, a georeferenced model): positions relative to the first
  // instance's translation, which the node transforms reach in double.
  h.origin = local_origin_for(Vec3d(reader->pieces_.front().transform[3]));
  return std::unique_ptr<MeshReader>(std::move(reader));
}

}  // namespace
}  // namespace gltf

StatusOr<std::unique_ptr<MeshReader>> open_gltf_reader(const std::filesystem::path& path, ReaderOptions options) {
  return gltf::open_reader(path, options);
}

StatusOr<GltfSummary> describe_gltf(const std::filesystem::path& file) {
  RAYLOD_ASSIGN_OR_RETURN(std::shared_ptr<const gltf::LoadedModel> loaded, gltf::load_model(file));
  const tinygltf::Model& model = loaded->model;
  GltfSummary s;
  s.binary = loaded->binary;
  for (size_t m = 0; m < model.meshes.size(); ++m) {
    GltfMeshInfo info;
    info.name = model.meshes[m].name.empty() ? "meshes[" + std::to_string(m) + "]" : model.meshes[m].name;
    std::vector<gltf::PrimitivePlan> plans;
    if (Status st = gltf::plan_mesh(*loaded, int(m), plans, info.skipped_primitives); !st) return st.with_context(file.string());
    info.has_normals = !plans.empty();
    for (const gltf::PrimitivePlan& plan : plans) {
      info.triangles += plan.triangles;
      info.vertices += plan.vertices;
      info.has_normals = info.has_normals && plan.has_normal;
      if (info.material < 0) info.material = model.meshes[m].primitives[size_t(plan.primitive)].material;
    }
    info.triangle_primitives = uint32_t(plans.size());
    s.meshes.push_back(info);
  }
  for (size_t i = 0; i < model.materials.size(); ++i) {
    const tinygltf::Material& mat = model.materials[i];
    GltfMaterialInfo info;
    info.name = mat.name.empty() ? "materials[" + std::to_string(i) + "]" : mat.name;
    const auto& pbr = mat.pbrMetallicRoughness;
    if (pbr.baseColorFactor.size() >= 3) {
      for (int c = 0; c < 3; ++c) info.base_color[c] = float(std::clamp(pbr.baseColorFactor[size_t(c)], 0.0, 1.0));
      info.has_base_color = info.base_color != Vec3(1.0f);
    }
    info.mirror = pbr.metallicFactor == 1.0 && pbr.roughnessFactor == 0.0;
    s.materials.push_back(info);
  }
  auto instances = gltf::mesh_instances(model);
  if (!instances) return instances.status().with_context(file.string());
  s.instances = std::move(*instances);
  for (const GltfInstance& inst : s.instances) ++s.meshes[size_t(inst.mesh)].instances;
  for (const GltfMeshInfo& m : s.meshes)
    if (m.material >= int(s.materials.size()))
      return Status::error(file.string() + ": " + m.name + ": material " + std::to_string(m.material) +
                           " does not exist (the file has " + std::to_string(s.materials.size()) + ")");
  return s;
}

}  // namespace raylod
