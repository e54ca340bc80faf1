// A glass bottle as a surface of revolution about the y axis, the stand-in for
// the paper's uniformly tessellated NURBS bottle (Miyashita et al., Sec. 5).
//
// The profile is a CAD-style sketch of lines and circular arcs joined with
// tangent continuity (G1): flat base, rounded base corner, cylindrical body, an
// S-shaped shoulder made of a convex and a concave arc, cylindrical neck and a
// rounded lip. With a wall thickness the inside is the outside offset inwards
// (lines shift, arcs keep their centres), joined over the lip, so the glass is
// one closed, watertight, genus-0 surface from the outer base centre, up the
// outside, over the lip and down the inside to the inner base centre. With
// thickness 0 the bottle is solid and closed by a rounded top.
//
// Normals are analytic: the profile's outward normal (dy/ds, -dr/ds) revolved,
// continuous everywhere because the sketch is G1. Sampling is uniform in the
// profile's arc length and in angle, so triangles are close to uniform in size.
//
// Mesh: one grid with a pole at each end of the profile, `around` columns
// wrapping round the axis and profile_segments - 1 rings:
//   triangles = 2 * around * (profile_segments - 1)
//   vertices  =     around * (profile_segments - 1) + 2
// Units: body radius 1, base at y = 0, height 3.9 by default.
#pragma once

#include <cstdint>
#include <vector>

#include "core/status.h"
#include "gen/grid_mesh.h"

namespace raylod {

struct BottleConfig {
  double body_radius = 1.0;          // outer radius of the body
  double base_corner_radius = 0.2;   // fillet between base and body
  double shoulder_start = 2.2;       // y where the body ends and the shoulder begins
  double neck_start = 3.1;           // y where the shoulder meets the neck
  double neck_radius = 0.36;         // outer radius of the neck
  double height = 3.9;               // y of the top of the lip
  double convex_share = 0.6;         // share of the shoulder's S curve that is convex
  double wall_thickness = 0.06;      // glass thickness; 0 = solid bottle
};

// Checks that the sketch is well formed (positive sizes, offsets that do not
// invert arcs, a neck narrower than the body, ...).
Status validate_bottle(const BottleConfig& config);

// A point of the profile in the (r, y) half plane with its unit outward normal.
struct ProfileSample {
  glm::dvec2 point;   // (r, y)
  glm::dvec2 normal;  // (n_r, n_y)
};

class BottleProfile {
 public:
  // `config` must pass validate_bottle.
  explicit BottleProfile(const BottleConfig& config);
  double length() const { return length_; }
  // Sample at arc length s in [0, length()]; s = 0 and s = length() are on the axis.
  ProfileSample at(double s) const;

 private:
  struct Segment {
    bool arc = false;
    glm::dvec2 a{0}, b{0};       // line end points
    glm::dvec2 centre{0};        // arc centre
    double radius = 0, ang0 = 0, ang1 = 0;
    double length = 0;
  };
  static Segment line(glm::dvec2 a, glm::dvec2 b);
  static Segment arc(glm::dvec2 centre, double radius, double ang0, double ang1);
  static Segment reversed_offset(const Segment& s, double d);
  static ProfileSample eval(const Segment& s, double u);

  std::vector<Segment> segments_;
  std::vector<double> starts_;  // cumulative arc length at each segment's start
  double length_ = 0;
};

struct BottlePlan {
  uint32_t profile_segments = 2;  // samples along the profile, poles included: profile_segments + 1
  uint32_t around = 3;            // columns around the axis
  uint64_t triangles = 0;
  uint64_t vertices = 0;
};

uint64_t bottle_triangle_count(uint32_t profile_segments, uint32_t around);
// The resolution whose triangle count is closest to `target` (>= 6), with
// angular and profile spacing within a factor 2 of each other on the body.
BottlePlan plan_bottle(uint64_t target_triangles, const BottleConfig& config = {});
// The resolution with exactly `around` columns whose triangle count is
// closest to `target` (at least 2 profile segments): long thin triangles
// along the profile when `around` is small, as a cylinder allows. Used to
// ask how few triangles the exact surface needs (tools/glass_reference.sh).
BottlePlan plan_bottle_around(uint64_t target_triangles, uint32_t around);

class BottleSurface final : public GridSurface {
 public:
  BottleSurface(const BottlePlan& plan, const BottleConfig& config = {});
  const std::vector<GridPiece>& pieces() const override { return pieces_; }
  void eval_row(size_t piece, uint32_t row, std::span<Vec3> positions, std::span<Vec3> normals) const override;
  const BottleProfile& profile() const { return profile_; }

 private:
  BottlePlan plan_;
  BottleProfile profile_;
  std::vector<GridPiece> pieces_;
  std::vector<double> cos_, sin_;  // per column
};

}  // namespace raylod
