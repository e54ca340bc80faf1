// Uniform vertex clustering at one grid level, in memory (Rossignac and
// Borrel 1993, with Lindstrom 2000 QEM representatives, eqs. 3-4): every
// vertex moves to the representative of its grid cell. Deliberately simple
// (ordered maps, whole mesh in memory); it is the reference that the
// streaming collapse of a uniform cut is checked against.
#pragma once

#include "geometry/qem_solve.h"
#include "streaming/draco_io.h"
#include "streaming/mesh_reader.h"

namespace raylod {

struct VertexClusteringConfig {
  Vec3d root_lo{0};     // grid cube corner (world)
  double root_size = 1;  // grid cube side; cells have side root_size / 2^level
  int level = 0;
  Vec3d origin{0};      // frame the quadrics are accumulated in (a local origin)
  QemSolveConfig qem;
};

// soup: triangles as in TriangleBatch (normals empty or per corner).
// The quadric of a cell sums, over the corners in it, the plane quadric of the
// corner's triangle (unit plane normal: quadric_plane_normal; weight: a third
// of the triangle's area), as the octree store does. Triangles whose corners
// fall in fewer than three cells, or have exactly zero area, are
// dropped, as are same-orientation repeats. Normals as in collapse.h.
IndexedMesh cluster_vertices(const TriangleBatch& soup, const VertexClusteringConfig& config);

// The plane normal a triangle contributes to the quadrics, as the store build
// defines it: the normalised mean of the vertex normals if given and not
// cancelling (length > 1e-12), else the face normal (zero if degenerate).
Vec3d quadric_plane_normal(const Vec3d& a, const Vec3d& b, const Vec3d& c, const Vec3* normals);

}  // namespace raylod
