// Streaming writer for indexed triangle meshes as binary little-endian PLY,
// when the vertex and face counts are known before the first vertex (as for
// a generated tessellation). The header is written up front; vertices are
// appended in chunks, then faces in chunks; finish() checks that exactly the
// declared counts arrived and only then renames the file into place
// (AtomicOutput), so a failure never leaves a partial mesh under the name.
//
// Layout (what streaming/ply_reader reads, and every common PLY tool):
//   element vertex V: float x y z [nx ny nz]   (double x y z when the layout
//                     has an origin: origin + position, in full precision)
//   element face F:   list uchar int vertex_indices   (always 3)
// Memory: one staging buffer of at most kStagingBytes plus the caller's chunk.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"
#include "core/system.h"

namespace raylod {

struct IndexedPlyLayout {
  uint64_t vertex_count = 0;
  uint64_t face_count = 0;         // triangles
  bool normals = true;             // write nx ny nz per vertex
  std::vector<std::string> comments;  // "comment" header lines (no newlines)
  // Positions are relative to this point (IndexedMesh::origin); when it is
  // not (0, 0, 0) they are written as double x y z = origin + position.
  Vec3d origin{0};
};

// The header text and the exact file size a layout produces.
std::string indexed_ply_header(const IndexedPlyLayout& layout);
uint64_t indexed_ply_file_bytes(const IndexedPlyLayout& layout);

class IndexedPlyWriter {
 public:
  static constexpr size_t kStagingBytes = size_t(4) << 20;

  // Creates the temporary file and writes the header. Vertex indices are
  // stored as 32-bit signed ints, so vertex_count must be below 2^31.
  static StatusOr<std::unique_ptr<IndexedPlyWriter>> create(const std::filesystem::path& path,
                                                            IndexedPlyLayout layout);
  ~IndexedPlyWriter();

  // Appends vertices; normals must have the same size as positions when the
  // layout has normals and is ignored otherwise. Errors past vertex_count.
  Status append_vertices(std::span<const Vec3> positions, std::span<const Vec3> normals);
  // Appends triangles as 3 indices each, after all vertices. Every index must
  // be below vertex_count.
  Status append_triangles(std::span<const uint32_t> indices);
  // Checks the counts, flushes, fsyncs and renames into place.
  Status finish();

  uint64_t vertices_written() const { return vertices_; }
  uint64_t triangles_written() const { return triangles_; }
  uint64_t bytes_written() const { return bytes_; }
  const std::filesystem::path& path() const { return out_.destination(); }

 private:
  IndexedPlyWriter(const std::filesystem::path& path, IndexedPlyLayout layout);
  Status write_bytes(const void* data, size_t n);
  Status flush_staging();
  Status fail(const std::string& what);

  IndexedPlyLayout layout_;
  AtomicOutput out_;
  std::FILE* file_ = nullptr;
  std::vector<unsigned char> staging_;
  uint64_t vertices_ = 0, triangles_ = 0, bytes_ = 0;
  bool failed_ = false, finished_ = false;
};

}  // namespace raylod
