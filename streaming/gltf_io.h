// glTF 2.0 (.gltf JSON and .glb binary) meshes: reading through tinygltf
// (Debian's libtinygltf, which also parses the JSON), Draco primitives
// (KHR_draco_mesh_compression) through Draco, and writing Draco-compressed
// .glb files.
//
// Reading. Every primitive with triangles (TRIANGLES, TRIANGLE_STRIP,
// TRIANGLE_FAN; indexed or not) gives triangles; POINTS and LINES
// primitives are skipped and counted (one warning per file on stderr), and a
// selection without any triangle primitive is an error. POSITION and NORMAL
// are read as float or, under KHR_mesh_quantization, as (normalized or not)
// byte and short integers; normalized values are dequantised as the spec
// says (max(c / 127, -1), c / 255, ...), and the node transform applies the
// rest of the dequantisation. Normals are kept only when every triangle
// primitive of the selection has them (otherwise crease-angle normals apply,
// as for a mesh without normals); zero normals are repaired as in the other
// readers. Buffers may be in the .glb, in external files beside the .gltf
// (never looked up elsewhere) or data URIs; external images are never read.
//
// What a path selects:
//   * "FILE.glb": the whole default scene (scene, else scenes[0], else every
//     mesh once), every node instance of a mesh flattened into world space by
//     its node's global transform (matrix or TRS, through the hierarchy);
//     normals by the inverse transpose, and a mirroring transform reverses
//     the winding. This is what `raylod build/info/render --mesh` read.
//   * "FILE.glb#meshes[N]" (gltf_mesh_path): mesh N alone, in its own
//     coordinates. A scene object naming a glTF file expands into one object
//     per node instance of a mesh (scene/scene.h), each with such a path and
//     its node's transform, so a mesh used by several nodes has one store.
//
// Memory: the JSON and all buffers are held in memory while a reader is open
// (like Draco files, glTF buffers are not streamed), plus one decoded Draco
// primitive at a time. The last file loaded is cached (by path, size and
// modification time), so the per-mesh readers of one file parse it once.
//
// Errors name the file and the element: "meshes[2].primitives[0]: accessor 5
// (POSITION) ends at byte 1212, past the end of bufferView 3 (1200 bytes)",
// truncated GLB chunks, buffer views past the end of their buffer, index out
// of range, missing buffers or external files, non-finite coordinates and
// coordinates beyond the float range (after the node transform), sparse
// accessors (not supported), required extensions raylod does not know.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"
#include "streaming/draco_io.h"
#include "streaming/mesh_reader.h"
#include "streaming/source_record.h"

namespace raylod {

// One mesh of a glTF file, as `raylod info` lists it.
struct GltfMeshInfo {
  std::string name;                 // the mesh's name, or "meshes[N]"
  uint64_t triangles = 0;           // declared by the accessors (Draco: the indices accessor)
  uint64_t vertices = 0;            // POSITION elements over its triangle primitives
  uint32_t triangle_primitives = 0;
  uint32_t skipped_primitives = 0;  // points and lines
  bool has_normals = false;         // every triangle primitive has NORMAL
  int material = -1;                // the first triangle primitive's material (-1: none)
  uint32_t instances = 0;           // node instances in the default scene
};

// What raylod takes from a glTF material (pbrMetallicRoughness).
struct GltfMaterialInfo {
  std::string name;
  Vec3 base_color{1.0f};            // baseColorFactor (RGB; alpha is ignored)
  bool has_base_color = false;      // baseColorFactor differs from the default white
  bool mirror = false;              // metallicFactor 1 and roughnessFactor 0
};

// A node that places a mesh: its global transform (node to world).
struct GltfInstance {
  int mesh = -1;
  glm::dmat4 transform{1.0};
  std::string node;                 // "nodes[4]" or its name
};

struct GltfSummary {
  std::vector<GltfMeshInfo> meshes;
  std::vector<GltfMaterialInfo> materials;
  std::vector<GltfInstance> instances;  // the default scene's, in depth-first node order
  bool binary = false;                  // .glb container
};

// Loads and checks the file's structure (not the triangles) and describes it.
StatusOr<GltfSummary> describe_gltf(const std::filesystem::path& file);

// A MeshReader over a glTF file or one of its meshes ("FILE#meshes[N]");
// the content decides between GLB and JSON (used by open_mesh).
StatusOr<std::unique_ptr<MeshReader>> open_gltf_reader(const std::filesystem::path& path, ReaderOptions options = {});

// The files the buffers of a glTF file name (not data URIs, not images),
// beside the file as its reader looks for them, each once in buffer order.
// Reads only the JSON (a .glb's JSON chunk); a file whose JSON does not
// parse gives none (its reader reports why). The store's fingerprint of a
// glTF mesh covers them (octree_store.h, fingerprint_file).
std::vector<std::filesystem::path> gltf_external_buffers(const std::filesystem::path& file);
// `file`'s status with those buffers' folded in (sizes summed, the latest
// modification and change times, devices and inodes mixed into the inode),
// so that writing, replacing or removing a buffer changes it as writing the
// file would. Buffers that are not regular files are left out.
FileStatus with_external_buffers(FileStatus file, std::span<const std::filesystem::path> buffers);

// ---- Writing ----

// A mesh of a .glb: Draco-encoded bytes (encode_draco, or a .drc file's
// content), written as one KHR_draco_mesh_compression primitive.
struct GlbMesh {
  std::string name;
  std::vector<char> draco;                     // the first primitive's Draco bitstream
  std::vector<std::vector<char>> more_parts;  // further primitives of the mesh (a .drc part file's parts)
};
// A node placing a mesh (node to world).
struct GlbNode {
  std::string name;
  size_t mesh = 0;
  glm::dmat4 transform{1.0};
};
// Writes a .glb (atomically: a temporary sibling renamed over `path`): one
// glTF mesh with one primitive per GlbMesh, one root node per GlbNode (its
// matrix omitted when it is the identity). The Draco bytes are stored as
// they are (so the quantisation bounds are those they were encoded with);
// each is decoded once here for the accessors' counts and POSITION min/max.
// KHR_draco_mesh_compression is listed in extensionsUsed and
// extensionsRequired. Returns the bytes written.
StatusOr<uint64_t> write_glb(const std::filesystem::path& path, const std::vector<GlbMesh>& meshes,
                             const std::vector<GlbNode>& nodes);

}  // namespace raylod
