// Streaming mesh readers: PLY (ASCII, binary little/big endian), STL (ASCII,
// binary), OBJ, and Draco (.drc). A reader yields the mesh as a sequence of
// triangle batches (polygons triangulated as fans) and never holds the whole
// face list in memory.
//
// Memory bound (per open reader): O(batch_triangles) for the batch buffers,
// plus, for indexed formats (PLY, OBJ), the vertex table, which is memory-
// mapped from the file (binary PLY) or from a temporary file next to the
// system temp dir (ASCII PLY, OBJ) so that it is paged by the OS rather than
// resident. Draco files are decoded whole (they are the small, simplified
// meshes this project writes).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"

namespace raylod {

enum class MeshFormat { Ply, Stl, Obj, Draco };
const char* to_string(MeshFormat f);

// A batch of independent triangles: positions[3*i+k] is vertex k of triangle i.
// normals is either empty (the file has no vertex normals) or the same size
// as positions, holding unit-length per-vertex normals.
struct TriangleBatch {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;
  size_t size() const { return positions.size() / 3; }
  void clear() { positions.clear(); normals.clear(); }
};

// What the header (or a cheap look at the file) says before any triangle is read.
struct MeshHeader {
  MeshFormat format = MeshFormat::Ply;
  std::string encoding;            // "binary_little_endian", "ascii", ...
  uint64_t vertex_count = 0;       // as declared; for STL 3 * triangles
  uint64_t face_count = 0;         // as declared (polygons); for OBJ counted on open
  bool has_normals = false;        // per-vertex normals present
  uint64_t file_bytes = 0;
};

struct ReaderOptions {
  size_t batch_triangles = 1 << 16;
};

class MeshReader {
 public:
  virtual ~MeshReader() = default;
  const MeshHeader& header() const { return header_; }
  const std::filesystem::path& path() const { return path_; }
  // Fills batch with the next triangles (clearing it first). Returns true if
  // the batch holds triangles, false at the end of the mesh, or an error that
  // names the file and what is wrong (truncated data, index out of range,
  // NaN/Inf coordinates, zero-length normal, ...). At the end, a mesh that
  // yielded no triangle at all is an error ("empty mesh").
  virtual StatusOr<bool> next(TriangleBatch& batch) = 0;

 protected:
  MeshHeader header_;
  std::filesystem::path path_;
};

// Opens a mesh by extension (.ply, .stl, .obj, .drc; case-insensitive), with
// the file's content checked against the extension.
StatusOr<std::unique_ptr<MeshReader>> open_mesh(const std::filesystem::path& path, ReaderOptions options = {});

// Full-pass summary for `raylod info`.
struct MeshSummary {
  MeshHeader header;
  uint64_t triangle_count = 0;
  Bbox bounds;
};
StatusOr<MeshSummary> summarize_mesh(const std::filesystem::path& path);

}  // namespace raylod
