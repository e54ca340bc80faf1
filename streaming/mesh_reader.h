// Streaming mesh readers: PLY (ASCII, binary little/big endian), STL (ASCII,
// binary), OBJ, and Draco (.drc). A reader yields the mesh as a sequence of
// triangle batches (polygons triangulated as fans around their first corner)
// and never holds the whole face list in memory.
//
// Memory bound (per open reader), for B = ReaderOptions::batch_triangles and
// P = the largest polygon's corner count in the file:
//   * heap: the caller's TriangleBatch, at most B + P - 3 triangles, i.e.
//     36 bytes per triangle without normals and 72 with them (the reader
//     stops filling a batch once it holds >= B triangles; a polygon is never
//     split across batches), plus O(P + header size + longest OBJ logical
//     line) reader state;
//   * vertex table: binary PLY indexes vertices in place in the memory-mapped
//     file (stride = vertex record size) and drops that mapping after every
//     64 MiB of face data, so only the vertex pages touched within such a
//     window stay resident (they refault from the page cache). ASCII PLY and
//     OBJ first spill their vertices (12 bytes per position, 12 per normal,
//     as float) to an unlinked scratch file in $TMPDIR that is then
//     memory-mapped (if $TMPDIR is a tmpfs, that is RAM). These pages are
//     file backed and clean, so the OS pages them out under memory pressure;
//   * the input file itself is memory-mapped; face/facet data is read
//     sequentially (MADV_SEQUENTIAL) and the pages behind the cursor are
//     dropped from the process (MADV_DONTNEED) in 4 MiB steps. Text formats
//     are scanned twice: once on open (to spill vertices, count faces and
//     check the structure) and once while streaming.
//   STL needs no vertex table (triangles are stored whole). Draco files are
//   decoded whole (they are the small, simplified meshes this project writes).
//
// Validation: every bad input is an error naming the file and, for text
// formats, the line: truncated data, bad headers, wrong counts in headers
// (too little or too much data), indices out of range, NaN/Inf coordinates,
// coordinates and normals beyond the float range (1e39 in text, or a double
// PLY property past +-3.4e38: no float holds them), non-finite normals,
// polygons with fewer than 3 corners, unsupported PLY property types, empty
// meshes. Text vertices are checked as they are read; binary PLY vertices
// where a face uses them (an unreferenced one is not inspected).
// Zero-length normals (CAD tessellations write (0, 0, 0) on degenerate
// triangles) are not an error: each such triangle corner gets the triangle's
// face normal (repair_zero_normals in vertex_table.h), and the count is
// printed once per file as a warning on stderr when the mesh has been read.
// Format decisions: STL facet normals are parsed and must be finite (NaN is
// an error, a zero normal is accepted, since many exporters write 0 0 0) but
// are otherwise ignored (has_normals = false). OBJ normals are used only if
// every face gives one for every corner; otherwise the mesh is read without
// normals (MeshHeader::has_normals says which).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"

namespace raylod {

enum class MeshFormat { Ply, Stl, Obj, Draco, Gltf };
const char* to_string(MeshFormat f);

// A batch of independent triangles: positions[3*i+k] is vertex k of triangle i,
// relative to the reader's MeshHeader::origin.
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
  // Batch positions are relative to this point: the file's coordinates are
  // origin + position. It is (0, 0, 0) unless the file holds more precision
  // than a float keeps far from zero (double or integer PLY coordinates,
  // ASCII PLY, OBJ) and its first vertex lies kLocalOriginThreshold or more
  // from zero; then it is that vertex rounded to integers, so a mesh at a
  // 1e7 offset keeps its 1e-3 detail (floats near 1e7 are 1 apart). (An
  // unused far-away first vertex would make a mesh near zero lose detail:
  // the rule looks at the first vertex only.) glTF: the first instance's node
  // translation, by the same rule. A .drc: its "raylod_origin" metadata.
  // Binary STL holds floats: always (0, 0, 0).
  Vec3d origin{0};
};

// How far from zero (largest coordinate magnitude) a mesh's first vertex must
// lie for its reader to keep positions relative to a local origin (floats are
// 2^-11 apart there, about 5e-4).
inline constexpr double kLocalOriginThreshold = 4096;
// The local origin for a mesh whose first vertex is p (MeshHeader::origin).
Vec3d local_origin_for(const Vec3d& p);

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
  // Triangle corners so far whose zero-length normal was replaced by a face normal.
  uint64_t repaired_normals() const { return repaired_normals_; }

 protected:
  // At the end of the mesh: if normals were repaired, prints "raylod:
  // warning: FILE: N triangle corners ..." to stderr, once per file in this
  // process (a build reads its mesh twice; one warning is enough).
  void warn_repaired_normals() const;

  MeshHeader header_;
  std::filesystem::path path_;
  uint64_t repaired_normals_ = 0;
};

// A mesh path names a file, or one mesh of a glTF file: "FILE.glb#meshes[N]"
// (streaming/gltf_io.h). Only a .gltf/.glb file name followed by exactly
// "#meshes[N]" is such a reference; anything else is a plain file name.
struct MeshRef {
  std::filesystem::path file;  // the file to open
  int gltf_mesh = -1;          // the glTF mesh, or -1 for the whole file
};
MeshRef parse_mesh_ref(const std::filesystem::path& path);
// "FILE#meshes[N]".
std::filesystem::path gltf_mesh_path(const std::filesystem::path& file, int mesh);

// Opens a mesh by extension (.ply, .stl, .obj, .drc, .gltf, .glb; case-insensitive), with
// the file's content checked against the extension. A path that is not a
// regular file fails at once and says what it is ("is a named pipe (FIFO),
// not a regular file", "is a directory, ...", "is a character device, ...").
StatusOr<std::unique_ptr<MeshReader>> open_mesh(const std::filesystem::path& path, ReaderOptions options = {});

// Full-pass summary for `raylod info`.
struct MeshSummary {
  MeshHeader header;
  uint64_t triangle_count = 0;
  Bbox bounds;
};
StatusOr<MeshSummary> summarize_mesh(const std::filesystem::path& path);

// Format-specific openers (open_mesh dispatches to these by extension); they
// check the content, not the extension.
StatusOr<std::unique_ptr<MeshReader>> open_ply_reader(const std::filesystem::path& path, ReaderOptions options = {});
StatusOr<std::unique_ptr<MeshReader>> open_stl_reader(const std::filesystem::path& path, ReaderOptions options = {});
StatusOr<std::unique_ptr<MeshReader>> open_obj_reader(const std::filesystem::path& path, ReaderOptions options = {});
// glTF: streaming/gltf_io.h (open_gltf_reader).
// The format implied by a path's extension (case-insensitive), or an error.
StatusOr<MeshFormat> mesh_format_from_extension(const std::filesystem::path& path);

}  // namespace raylod
