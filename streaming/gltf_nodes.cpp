// The node hierarchy of a glTF scene flattened into mesh instances (glTF 2.0,
// section 3.5 "Nodes and Hierarchy"): a node's global transform is its
// parent's times its local one, the local one being `matrix` (column-major)
// or T * R * S from translation, rotation (unit quaternion x, y, z, w) and
// scale.
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "streaming/gltf_model.h"

namespace raylod::gltf {
namespace {

StatusOr<glm::dmat4> local_transform(const tinygltf::Node& n, const std::string& where) {
  glm::dmat4 m(1.0);
  if (!n.matrix.empty()) {
    if (n.matrix.size() != 16) return Status::error(where + ".matrix: expected 16 numbers");
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r) m[c][r] = n.matrix[size_t(c * 4 + r)];
  } else {
    glm::dvec3 t(0), s(1);
    glm::dquat q(1, 0, 0, 0);
    if (!n.translation.empty()) {
      if (n.translation.size() != 3) return Status::error(where + ".translation: expected 3 numbers");
      t = {n.translation[0], n.translation[1], n.translation[2]};
    }
    if (!n.scale.empty()) {
      if (n.scale.size() != 3) return Status::error(where + ".scale: expected 3 numbers");
      s = {n.scale[0], n.scale[1], n.scale[2]};
    }
    if (!n.rotation.empty()) {
      if (n.rotation.size() != 4) return Status::error(where + ".rotation: expected 4 numbers (x, y, z, w)");
      q = glm::dquat(n.rotation[3], n.rotation[0], n.rotation[1], n.rotation[2]);  // glm: w first
      const double len = glm::length(q);
      if (!(len > 0) || !std::isfinite(len)) return Status::error(where + ".rotation: not a unit quaternion");
      q /= len;  // exporters round: renormalise rather than shear
    }
    m = glm::translate(glm::dmat4(1.0), t) * glm::mat4_cast(q) * glm::scale(glm::dmat4(1.0), s);
  }
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return Status::error(where + ": the transform is not finite");
  return m;
}

Status visit(const tinygltf::Model& model, int node, const glm::dmat4& parent, std::vector<bool>& on_path,
             std::vector<GltfInstance>& out, int depth) {
  const std::string where = "nodes[" + std::to_string(node) + "]";
  if (node < 0 || size_t(node) >= model.nodes.size())
    return Status::error("node " + std::to_string(node) + " does not exist (the file has " +
                         std::to_string(model.nodes.size()) + " nodes)");
  if (on_path[size_t(node)] || depth > 1000) return Status::error(where + ": the node hierarchy has a cycle");
  const tinygltf::Node& n = model.nodes[size_t(node)];
  RAYLOD_ASSIGN_OR_RETURN(glm::dmat4 local, local_transform(n, where));
  const glm::dmat4 global = parent * local;
  if (n.mesh >= 0) {
    if (size_t(n.mesh) >= model.meshes.size())
      return Status::error(where + ".mesh: mesh " + std::to_string(n.mesh) + " does not exist (the file has " +
                           std::to_string(model.meshes.size()) + " meshes)");
    out.push_back(GltfInstance{n.mesh, global, n.name.empty() ? where : where + " '" + n.name + "'"});
  }
  on_path[size_t(node)] = true;
  for (int child : n.children) RAYLOD_RETURN_IF_ERROR(visit(model, child, global, on_path, out, depth + 1));
  on_path[size_t(node)] = false;
  return Status::ok();
}

}  // namespace

StatusOr<std::vector<GltfInstance>> mesh_instances(const tinygltf::Model& model) {
  std::vector<GltfInstance> out;
  if (model.scenes.empty()) {
    // No scene to show: every mesh once, in its own coordinates.
    for (size_t m = 0; m < model.meshes.size(); ++m) out.push_back(GltfInstance{int(m), glm::dmat4(1.0), "(no scene)"});
    return out;
  }
  const int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
  if (size_t(scene) >= model.scenes.size())
    return Status::error("scene " + std::to_string(scene) + " does not exist (the file has " +
                         std::to_string(model.scenes.size()) + " scenes)");
  std::vector<bool> on_path(model.nodes.size(), false);
  for (int root : model.scenes[size_t(scene)].nodes) {
    Status st = visit(model, root, glm::dmat4(1.0), on_path, out, 0);
    if (!st) return st.with_context("scenes[" + std::to_string(scene) + "]");
  }
  return out;
}

}  // namespace raylod::gltf
