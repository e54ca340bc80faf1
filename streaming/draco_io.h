// Draco (.drc) mesh files: the compressed simplified meshes raylod writes.
#pragma once

#include <filesystem>
#include <memory>

#include "core/status.h"
#include "streaming/mesh_reader.h"

namespace raylod {

struct IndexedMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;      // empty or one per position
  std::vector<uint32_t> indices;  // 3 per triangle
  size_t triangle_count() const { return indices.size() / 3; }
};

struct DracoOptions {
  int position_bits = 0;  // 0 = choose from the data and max_position_error
  int normal_bits = 10;
  double max_position_error = 0;  // world units; used when position_bits == 0
  int speed = 5;                   // Draco encoder speed 0 (best) .. 10 (fastest)
};

struct DracoWriteReport {
  int position_bits = 0, normal_bits = 0;
  double max_position_error = 0;  // bound implied by the quantisation
  uint64_t bytes = 0;
};

// Encodes the mesh (degenerate triangles must be removed by the caller) and
// writes it atomically.
StatusOr<DracoWriteReport> write_draco(const std::filesystem::path& path, const IndexedMesh& mesh,
                                       const DracoOptions& options);
StatusOr<IndexedMesh> read_draco(const std::filesystem::path& path);
// A MeshReader over a decoded Draco file (used by open_mesh for .drc).
StatusOr<std::unique_ptr<MeshReader>> open_draco_reader(const std::filesystem::path& path, ReaderOptions options);

}  // namespace raylod
