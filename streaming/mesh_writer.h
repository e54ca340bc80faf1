// Streaming mesh writers: binary PLY (little endian, float positions and
// optional float normals, uchar-count int faces) and binary STL. Triangles
// are appended batch by batch; counts in the header are patched on finish(),
// and the file appears under its name only after finish() succeeds (written
// to a temporary name, then renamed).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>

#include "core/status.h"
#include "streaming/mesh_reader.h"

namespace raylod {

class MeshWriter {
 public:
  virtual ~MeshWriter() = default;
  virtual Status write(const TriangleBatch& batch) = 0;
  virtual Status finish() = 0;
  virtual uint64_t triangles_written() const = 0;
};

struct WriterOptions {
  bool normals = true;  // write vertex normals (PLY only; STL stores face normals)
};

// Chooses the format from the extension: .ply or .stl.
StatusOr<std::unique_ptr<MeshWriter>> create_mesh_writer(const std::filesystem::path& path, WriterOptions options = {});

}  // namespace raylod
