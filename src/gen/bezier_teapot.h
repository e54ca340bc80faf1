// The Utah teapot as an indexed tessellation of Newell's 32 bicubic Bezier
// patches (data: teapot_patches.h), with analytic vertex normals.
//
// Frame: y up, base at y = 0, classic proportions (height 3.15, x from -3.0 at
// the handle to ~3.43 at the spout tip). Newell's data is z up; it is rotated
// by (x, y, z) -> (x, z, -y), a proper rotation, so winding is preserved.
//
// Sampling: every patch is sampled on the same (rows x cols) parameter grid,
// s = a / row_segments along the patch's rows, t = b / col_segments along them.
// Neighbouring patches therefore sample their shared edge at the same
// parameters, and positions on shared edges are bitwise identical from both
// sides (see bezier_teapot.cpp for why), so vertex clustering sees no cracks.
// Vertices on patch edges are duplicated per patch (not welded).
//
// Poles: the 4 lid-top and the 4 bottom patches have a control row collapsed to
// one point. That row becomes a single vertex whose normal is the limit of the
// surface normal (dP/ds x d2P/dsdt, where dP/dt vanishes); the quads next to it
// become a fan, so no zero-area triangle is written.
//
// Triangles: 24 regular patches x 2 r c + 8 pole patches x (2 r - 1) c
//          = 64 r c - 8 c   for r row segments and c column segments.
// Normals point out of the teapot and agree with the counter-clockwise winding.
#pragma once

#include <cstdint>
#include <vector>

#include "gen/grid_mesh.h"

namespace raylod {

struct TeapotPlan {
  uint32_t row_segments = 1;  // segments along s (each patch has row_segments + 1 vertex rows)
  uint32_t col_segments = 1;  // segments along t
  uint64_t triangles = 0;
  uint64_t vertices = 0;
};

// Exact triangle count for a grid resolution (64 r c - 8 c).
uint64_t teapot_triangle_count(uint32_t row_segments, uint32_t col_segments);
// The grid resolution whose triangle count is closest to `target` (>= 56),
// keeping patches' grids within an aspect ratio of 2.
TeapotPlan plan_teapot(uint64_t target_triangles);

class BezierTeapot final : public GridSurface {
 public:
  explicit BezierTeapot(const TeapotPlan& plan);
  const std::vector<GridPiece>& pieces() const override { return pieces_; }
  void eval_row(size_t piece, uint32_t row, std::span<Vec3> positions, std::span<Vec3> normals) const override;

  // Position and unit outward normal of patch `patch` at (s, t) in [0,1]^2, in
  // the y-up frame, in double (for tests; handles poles by the same limit).
  void evaluate(int patch, double s, double t, Vec3d& position, Vec3d& normal) const;

 private:
  struct Basis {
    double b[4];  // Bernstein basis values
    double d[4];  // their derivatives
  };
  static Basis bernstein(uint32_t i, uint32_t n);
  static Basis bernstein(double t);
  static Basis bernstein_tu(double t, double u);  // u = 1 - t, computed by the caller

  TeapotPlan plan_;
  std::vector<GridPiece> pieces_;
  std::vector<Basis> col_basis_;  // per column b: basis at t = b / col_segments
};

}  // namespace raylod
