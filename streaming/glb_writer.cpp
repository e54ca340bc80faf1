// Writing a binary glTF (.glb, glTF 2.0 section 4.4) whose primitives are
// Draco bitstreams (KHR_draco_mesh_compression): the accessors carry no
// bufferView, only the counts and types the decoded data has, and POSITION
// its min/max (required by the specification for POSITION).
#include <cstring>
#include <fstream>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#include <nlohmann/json.hpp>

#include "core/system.h"
#include "streaming/gltf_io.h"

namespace raylod {
namespace {

using nlohmann::json;

constexpr int kFloat = 5126, kUnsignedInt = 5125;

struct DecodedFacts {
  uint32_t points = 0, faces = 0;
  int position_id = -1, normal_id = -1;
  Vec3 lo{0}, hi{0};
};

StatusOr<DecodedFacts> decode_facts(const std::vector<char>& draco_bytes, const std::string& where) {
  draco::DecoderBuffer buffer;
  buffer.Init(draco_bytes.data(), draco_bytes.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) return Status::error(where + ": Draco decoding failed: " + decoded.status().error_msg_string());
  std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
  const draco::PointAttribute* pos = dm ? dm->GetNamedAttribute(draco::GeometryAttribute::POSITION) : nullptr;
  if (!pos || pos->num_components() != 3 || dm->num_faces() == 0)
    return Status::error(where + ": the Draco data holds no triangle mesh with 3-component positions");
  DecodedFacts f;
  f.points = dm->num_points();
  f.faces = dm->num_faces();
  f.position_id = int(pos->unique_id());
  if (const draco::PointAttribute* nrm = dm->GetNamedAttribute(draco::GeometryAttribute::NORMAL);
      nrm && nrm->num_components() == 3)
    f.normal_id = int(nrm->unique_id());
  for (uint32_t i = 0; i < f.points; ++i) {
    Vec3 p;
    if (!pos->ConvertValue<float, 3>(pos->mapped_index(draco::PointIndex(i)), &p.x) || !is_finite(p))
      return Status::error(where + ": bad decoded position " + std::to_string(i));
    f.lo = i == 0 ? p : glm::min(f.lo, p);
    f.hi = i == 0 ? p : glm::max(f.hi, p);
  }
  return f;
}

json vec3(const Vec3& v) { return json::array({double(v.x), double(v.y), double(v.z)}); }

void append_padded(std::string& out, const char* data, size_t size, char pad) {
  out.append(data, size);
  out.append((4 - size % 4) % 4, pad);
}

void put32(std::string& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(char((v >> (8 * i)) & 0xff));
}

}  // namespace

StatusOr<uint64_t> write_glb(const std::filesystem::path& path, const std::vector<GlbMesh>& meshes,
                             const std::vector<GlbNode>& nodes) {
  const std::string name = path.string();
  if (meshes.empty() || nodes.empty()) return Status::error(name + ": nothing to write (no meshes or no nodes)");
  json doc;
  doc["asset"] = {{"version", "2.0"}, {"generator", "raylod"}};
  doc["extensionsUsed"] = json::array({"KHR_draco_mesh_compression"});
  doc["extensionsRequired"] = json::array({"KHR_draco_mesh_compression"});
  json accessors = json::array(), views = json::array(), jmeshes = json::array(), jnodes = json::array();
  std::string bin;
  // One primitive per Draco bitstream (a mesh's first, then its further parts).
  auto add_primitive = [&](const std::vector<char>& bytes, const std::string& where) -> StatusOr<json> {
    RAYLOD_ASSIGN_OR_RETURN(DecodedFacts f, decode_facts(bytes, where));
    views.push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}});
    append_padded(bin, bytes.data(), bytes.size(), '\0');
    json attributes, draco_attributes;
    attributes["POSITION"] = accessors.size();
    draco_attributes["POSITION"] = f.position_id;
    accessors.push_back({{"componentType", kFloat}, {"count", f.points}, {"type", "VEC3"}, {"min", vec3(f.lo)}, {"max", vec3(f.hi)}});
    if (f.normal_id >= 0) {
      attributes["NORMAL"] = accessors.size();
      draco_attributes["NORMAL"] = f.normal_id;
      accessors.push_back({{"componentType", kFloat}, {"count", f.points}, {"type", "VEC3"}});
    }
    json primitive = {{"attributes", attributes}, {"indices", accessors.size()}, {"mode", 4}};
    accessors.push_back({{"componentType", kUnsignedInt}, {"count", uint64_t(f.faces) * 3}, {"type", "SCALAR"}});
    primitive["extensions"]["KHR_draco_mesh_compression"] = {{"bufferView", views.size() - 1}, {"attributes", draco_attributes}};
    return primitive;
  };
  for (size_t m = 0; m < meshes.size(); ++m) {
    const std::string where = name + ": mesh " + std::to_string(m);
    json primitives = json::array();
    RAYLOD_ASSIGN_OR_RETURN(json first, add_primitive(meshes[m].draco, where));
    primitives.push_back(std::move(first));
    for (size_t part = 0; part < meshes[m].more_parts.size(); ++part) {
      RAYLOD_ASSIGN_OR_RETURN(json more, add_primitive(meshes[m].more_parts[part], where + " part " + std::to_string(part + 2)));
      primitives.push_back(std::move(more));
    }
    json mesh = {{"primitives", primitives}};
    if (!meshes[m].name.empty()) mesh["name"] = meshes[m].name;
    jmeshes.push_back(mesh);
  }
  json scene_nodes = json::array();
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].mesh >= meshes.size())
      return Status::error(name + ": node " + std::to_string(i) + " names mesh " + std::to_string(nodes[i].mesh) +
                           " of " + std::to_string(meshes.size()));
    json node = {{"mesh", nodes[i].mesh}};
    if (!nodes[i].name.empty()) node["name"] = nodes[i].name;
    if (nodes[i].transform != glm::dmat4(1.0)) {
      json matrix = json::array();
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) matrix.push_back(nodes[i].transform[c][r]);  // column-major, as glTF
      node["matrix"] = matrix;
    }
    jnodes.push_back(node);
    scene_nodes.push_back(i);
  }
  doc["accessors"] = accessors;
  doc["bufferViews"] = views;
  doc["buffers"] = json::array({{{"byteLength", bin.size()}}});
  doc["meshes"] = jmeshes;
  doc["nodes"] = jnodes;
  doc["scenes"] = json::array({{{"nodes", scene_nodes}}});
  doc["scene"] = 0;

  const std::string text = doc.dump();
  std::string json_chunk;
  append_padded(json_chunk, text.data(), text.size(), ' ');  // JSON pads with spaces, BIN with zeros
  const uint64_t total = 12 + 8 + json_chunk.size() + 8 + bin.size();
  if (total > UINT32_MAX) return Status::error(name + ": the .glb would be " + std::to_string(total) + " bytes, over GLB's 4 GiB");
  std::string out;
  out.reserve(size_t(total));
  out.append("glTF", 4);
  put32(out, 2);
  put32(out, uint32_t(total));
  put32(out, uint32_t(json_chunk.size()));
  out.append("JSON", 4);
  out += json_chunk;
  put32(out, uint32_t(bin.size()));
  out.append("BIN\0", 4);
  out += bin;

  AtomicOutput file(path);
  RAYLOD_RETURN_IF_ERROR(write_temporary(file, out));
  RAYLOD_RETURN_IF_ERROR(file.commit());
  return uint64_t(out.size());
}

}  // namespace raylod
