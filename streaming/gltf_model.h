// Internals of the glTF reader (streaming/gltf_io.h): the loaded model,
// checked accessor views, and the scene graph's node instances.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "core/math.h"
#include "core/status.h"
#include "streaming/gltf_io.h"

namespace raylod::gltf {

// A parsed glTF file with every buffer loaded (gltf_load.cpp).
struct LoadedModel {
  tinygltf::Model model;
  std::string name;        // the file, for messages
  bool binary = false;     // GLB container
  uint64_t file_bytes = 0;
  // The indices accessors of KHR_draco_mesh_compression primitives, by
  // (mesh, primitive): taken out of the JSON before tinygltf parses it.
  std::map<std::pair<int, int>, int64_t> draco_indices;
};

// Loads FILE (GLB by its magic, else JSON): the GLB container is checked
// first (header, chunk lengths against the file), then tinygltf parses it,
// with external files looked up only beside FILE and images never decoded.
// Required extensions other than the ones raylod reads (or that do not
// change geometry: KHR_materials_*, KHR_texture_*, KHR_lights_punctual) are
// an error. The last model loaded is cached by path, size and mtime (kept
// loaded if at most 256 MiB, else only while a reader holds it).
StatusOr<std::shared_ptr<const LoadedModel>> load_model(const std::filesystem::path& file);

// A checked, strided view of an accessor's elements (gltf_accessor.cpp).
struct AccessorView {
  const uint8_t* data = nullptr;  // element 0
  size_t stride = 0;              // bytes between elements
  size_t count = 0;
  int component_type = 0;         // TINYGLTF_COMPONENT_TYPE_*
  int components = 0;             // 1 (SCALAR) or 3 (VEC3)
  bool normalized = false;

  // Component c of element i, dequantised as glTF's `normalized` says
  // (signed: max(v / (2^(n-1) - 1), -1); unsigned: v / (2^n - 1)).
  double component(size_t i, int c) const;
  Vec3d vec3(size_t i) const { return {component(i, 0), component(i, 1), component(i, 2)}; }
  // Element i of an index accessor.
  uint32_t index(size_t i) const;
};

enum class AccessorUse { Position, Normal, Indices };
// Checks accessor `index` for `use` (type and component type, as glTF and
// KHR_mesh_quantization allow) and that it lies inside its buffer view,
// and the view inside its buffer. `where` prefixes every message
// ("meshes[2].primitives[0]").
StatusOr<AccessorView> view_accessor(const tinygltf::Model& model, int index, AccessorUse use, const std::string& where);

// The node instances of meshes in the default scene with their global
// transforms (gltf_nodes.cpp): scene, else scenes[0], else every mesh once at
// identity. Node cycles, bad indices and non-finite transforms are errors.
StatusOr<std::vector<GltfInstance>> mesh_instances(const tinygltf::Model& model);

// True for the triangle modes (TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN).
inline bool is_triangle_mode(int mode) { return mode == 4 || mode == 5 || mode == 6; }

}  // namespace raylod::gltf
