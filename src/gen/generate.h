// `raylod gen`: large CAD-like test meshes with analytic vertex normals,
// streamed to disk (binary PLY, indexed; or binary STL with face normals).
//
// Memory is bounded independently of the triangle count: vertices are
// evaluated and written a chunk of grid rows at a time (rows evaluated in
// parallel with TBB), then faces are generated from index arithmetic in
// chunks. Output is byte-identical whatever the thread count.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "core/math.h"
#include "core/status.h"
#include "gen/grid_mesh.h"
#include "scene/scene.h"

namespace raylod {

// Accepted triangle counts.
inline constexpr uint64_t kGenMinTriangles = 100;
inline constexpr uint64_t kGenMaxTriangles = 1'000'000'000;

struct GenOptions {
  std::string shape;        // "teapot" or "bottle"
  uint64_t triangles = 0;   // requested; the written count is within ~1% (see GenReport)
  bool normals = true;      // PLY vertex normals (STL always has face normals)
  uint32_t around = 0;      // bottle only: columns around the axis (0: the squarest grid for the count)
  bool progress = false;    // show a progress bar on stderr
};

struct GenReport {
  std::filesystem::path path;
  std::string shape;
  std::string format;            // "ply" or "stl"
  std::string grid;              // the tessellation, e.g. "32 patches x 64 x 65 vertices"
  uint64_t requested_triangles = 0;
  uint64_t triangles = 0;        // exactly as written
  uint64_t vertices = 0;         // distinct vertices of the tessellation (PLY vertex count)
  uint64_t bytes = 0;            // file size
  double seconds = 0;
  Bbox bounds;
};

// The tessellation of `shape` closest to `triangles`, without writing it.
// `grid` (optional) receives a description of the resolution. `around` > 0
// (bottle only) fixes the columns around the axis (plan_bottle_around).
StatusOr<std::unique_ptr<GridSurface>> make_generated_surface(const std::string& shape, uint64_t triangles,
                                                              std::string* grid = nullptr, uint32_t around = 0);

// Writes the mesh to `out`, choosing PLY or STL by extension (case-insensitive).
// The file appears only when complete (AtomicOutput).
StatusOr<GenReport> generate_mesh(const GenOptions& options, const std::filesystem::path& out);

// Streams any grid surface to binary PLY / binary STL (used by generate_mesh).
Status write_grid_ply(const GridSurface& surface, const std::filesystem::path& out, bool normals,
                      const std::vector<std::string>& comments, Bbox* bounds = nullptr, bool progress = false);
Status write_grid_stl(const GridSurface& surface, const std::filesystem::path& out, const std::string& header_text,
                      Bbox* bounds = nullptr, bool progress = false);

// Path of the cached mesh for g: <cache_dir>/meshes/<generator>-<triangles>.ply.
std::filesystem::path generated_mesh_path(const GeneratedMesh& g, const std::filesystem::path& cache_dir);
// Returns generated_mesh_path(g, cache_dir), generating it on first use. An
// existing file is reused if its size is exactly what the generator writes;
// otherwise (truncated, foreign) it is regenerated. Safe when processes race:
// generation holds flock() on <mesh>.lock beside it, a file found complete
// (after taking the lock) is never rewritten, and the mesh is written to a
// temporary and renamed into place, so readers see no file or a whole one.
StatusOr<std::filesystem::path> ensure_generated_mesh(const GeneratedMesh& g, const std::filesystem::path& cache_dir);
// Sets SceneObject::mesh for every object with `generate` set.
Status resolve_generated_meshes(Scene& scene, const std::filesystem::path& cache_dir);

}  // namespace raylod
