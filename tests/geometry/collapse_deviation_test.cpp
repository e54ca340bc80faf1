// Collapse deviation from a quadric (geometry/collapse_deviation.h): exact
// cases (plane, crease, corner) and the analytic chord error of spherical caps.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "geometry/collapse_deviation.h"

namespace raylod {
namespace {

// The nodes below sum their faces' own normals, as a store of a mesh
// without normals does.
constexpr NodeNormals kFaces = NodeNormals::Faces;

// Accumulates a triangle into a node as the store build does: each corner
// adds the triangle's plane quadric and unit normal with weight area / 3.
void add_triangle(NodeRecord& node, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  const Vec3d cross = glm::cross(b - a, c - a);
  const double twice_area = glm::length(cross);
  if (!(twice_area > 0)) return;
  const Vec3d n = cross / twice_area;
  for (const Vec3d& p : {a, b, c}) {
    quadric_add(node.quadric, quadric_from_plane(n, p, twice_area / 6.0));
    node.normal_sum += (twice_area / 6.0) * n;
    node.vertex_sum += p;
    ++node.corner_count;
  }
}

// A spherical cap of radius r and half-angle alpha around +z, finely tessellated.
NodeRecord cap(double r, double alpha, int rings = 80, int slices = 160) {
  NodeRecord node;
  auto at = [&](int i, int j) {
    const double th = alpha * double(i) / rings, ph = 2 * M_PI * double(j) / slices;
    return Vec3d(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th));
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < slices; ++j) {
      add_triangle(node, at(i, j), at(i + 1, j), at(i + 1, j + 1));
      if (i > 0) add_triangle(node, at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  return node;
}

// The exact cases: a plane across the cell
// (y = 0), the same with a second plane meeting it at 90 degrees along
// x = 0.2 (a crease), and with a third closing a box corner.
NodeRecord flat_node() {
  NodeRecord n;
  add_triangle(n, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1});
  add_triangle(n, {-1, 0, -1}, {1, 0, 1}, {1, 0, -1});
  return n;
}
NodeRecord crease_node() {
  NodeRecord n = flat_node();
  add_triangle(n, {0.2, 0, -1}, {0.2, 1, -1}, {0.2, 1, 1});
  add_triangle(n, {0.2, 0, -1}, {0.2, 1, 1}, {0.2, 0, 1});
  return n;
}
NodeRecord corner_node() {
  NodeRecord n = crease_node();
  add_triangle(n, {0.2, 0, 0.3}, {0.2, 1, 0.3}, {-1, 1, 0.3});
  return n;
}

TEST(CollapseDeviation, FlatCreaseAndCornerCellsDoNotMove) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  EXPECT_NEAR(collapse_deviation(flat_node(), cell, kFaces).position, 0.0, 1e-9);
  EXPECT_NEAR(collapse_deviation(flat_node(), cell, kFaces).normal, 0.0, 1e-12);
  // A 90-degree crease (floor + wall) and a box corner (three faces): the
  // representative lies on every plane, and crease-split normals keep them sharp.
  const CollapseDeviation c = collapse_deviation(crease_node(), cell, kFaces);
  EXPECT_NEAR(c.position, 0.0, 1e-9);
  EXPECT_NEAR(c.normal, 0.0, 1e-12);
  EXPECT_NEAR(collapse_deviation(corner_node(), cell, kFaces).position, 0.0, 1e-9);
  // Empty and zero-area cells: nothing to move.
  NodeRecord empty;
  EXPECT_EQ(collapse_deviation(empty, cell, kFaces).position, 0.0);
}

TEST(CollapseDeviation, SphericalCapsGiveTheirChordError) {
  // position = the cap's sagitta r (1 - cos alpha); normal = kappa * sagitta
  // = alpha^2 / 2 to leading order.
  for (double r : {0.5, 1.0, 40.0})
    for (double alpha : {0.02, 0.1, 0.3}) {
      const NodeRecord node = cap(r, alpha);
      const double h = r * std::sin(alpha) * 1.01;
      const Bbox cell{Vec3d(-h, -h, r * std::cos(alpha) - h), Vec3d(h, h, r + h)};
      const CollapseDeviation d = collapse_deviation(node, cell, kFaces);
      const double sagitta = r * (1 - std::cos(alpha));
      EXPECT_NEAR(d.position / sagitta, 1.0, 0.03) << "r " << r << " alpha " << alpha;
      EXPECT_NEAR(d.normal / (alpha * alpha / 2), 1.0, 0.05) << "r " << r << " alpha " << alpha;
    }
}

TEST(CollapseDeviation, ThinWallIsItsThickness) {
  // Two parallel sheets facing away from each other, t apart: the
  // representative sits between them, and the collapse moves each by t / 2.
  const double t = 0.01;
  NodeRecord wall;
  add_triangle(wall, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1});
  add_triangle(wall, {-1, t, -1}, {1, t, 1}, {-1, t, 1});
  const CollapseDeviation d = collapse_deviation(wall, Bbox{Vec3d(-1), Vec3d(1)}, kFaces);
  EXPECT_GE(d.position, t / 2);
  EXPECT_LE(d.position, 2 * t);
}

// A crease or corner the solve holds exactly has no deviation, yet its
// normals spread: flagged, so that mirrors and glass (where the triangles
// joining it to the cells beside it show as chamfers) treat it as a rim.
// Planes and curved patches are not creases.
TEST(CollapseDeviation, CreasesAreFlaggedPlanesAndCurvesAreNot) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  EXPECT_FALSE(collapse_deviation(flat_node(), cell, kFaces).crease);
  const CollapseDeviation c = collapse_deviation(crease_node(), cell, kFaces);
  EXPECT_TRUE(c.crease);
  EXPECT_LT(c.position, 1e-6);
  EXPECT_TRUE(collapse_deviation(corner_node(), cell, kFaces).crease);
  for (double alpha : {0.05, 0.3, 1.0})
    EXPECT_FALSE(collapse_deviation(cap(1.0, alpha), Bbox{Vec3d(-2), Vec3d(2)}, kFaces).crease) << "alpha " << alpha;
}

TEST(CollapseDeviation, FoldsAreFlaggedOneSidedSurfacesAreNot) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  // A knife edge: two faces meeting at a 0-degree dihedral along x = 1 (the
  // lower one tilted by 0.02 rad, facing down). The solve sees one plane
  // and puts the representative at the corners' mean, well inside the
  // edge, while the quadric's deviation stays near zero.
  NodeRecord knife;
  add_triangle(knife, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1});
  add_triangle(knife, {-1, 0, -1}, {1, 0, 1}, {1, 0, -1});
  add_triangle(knife, {-1, -0.04, -1}, {1, 0, 1}, {-1, -0.04, 1});
  add_triangle(knife, {-1, -0.04, -1}, {1, 0, -1}, {1, 0, 1});
  const CollapseDeviation k = collapse_deviation(knife, cell, kFaces);
  EXPECT_TRUE(k.folded);
  EXPECT_LT(k.position, 0.05);
  // A thin wall (two sheets facing away from each other) is a fold too.
  NodeRecord wall;
  add_triangle(wall, {-1, 0, -1}, {1, 0, 1}, {-1, 0, 1});
  add_triangle(wall, {-1, 0.001, -1}, {-1, 0.001, 1}, {1, 0.001, 1});
  EXPECT_TRUE(collapse_deviation(wall, cell, kFaces).folded);
  // One-sided surfaces are not: a plane, a crease, a box corner, a
  // spherical cap, a 30-degree wedge (two planes the solve keeps apart: its
  // ridge pins the representative).
  EXPECT_FALSE(collapse_deviation(flat_node(), cell, kFaces).folded);
  EXPECT_FALSE(collapse_deviation(crease_node(), cell, kFaces).folded);
  EXPECT_FALSE(collapse_deviation(corner_node(), cell, kFaces).folded);
  for (double alpha : {0.05, 0.3, 1.0})
    EXPECT_FALSE(collapse_deviation(cap(1.0, alpha), Bbox{Vec3d(-2), Vec3d(2)}, kFaces).folded) << "alpha " << alpha;
  NodeRecord wedge = flat_node();
  const double s = std::tan(M_PI / 6);
  add_triangle(wedge, {-1, -2 * s, -1}, {1, 0, 1}, {-1, -2 * s, 1});
  add_triangle(wedge, {-1, -2 * s, -1}, {1, 0, -1}, {1, 0, 1});
  EXPECT_FALSE(collapse_deviation(wedge, cell, kFaces).folded);
}

// A knife edge whose underside is a sliver (2% of the cell's area) hides in
// a smooth-normal margin: where the node sums its faces' own normals the
// fold test is exact, and any area facing the other way is a fold.
TEST(CollapseDeviation, AKnifeEdgeWithASliverUndersideIsAFoldWhenTheNormalsAreTheFaces) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  NodeRecord knife = flat_node();
  add_triangle(knife, {0.96, -0.0008, -1}, {1, 0, 1}, {0.96, -0.0008, 1});
  add_triangle(knife, {0.96, -0.0008, -1}, {1, 0, -1}, {1, 0, 1});
  EXPECT_TRUE(collapse_deviation(knife, cell, NodeNormals::Faces).folded);
  EXPECT_FALSE(collapse_deviation(knife, cell, NodeNormals::Input).folded);
  // A plane is one-sided whatever its normals.
  EXPECT_FALSE(collapse_deviation(flat_node(), cell, NodeNormals::Faces).folded);
}

// A knife edge whose underside curls away (the concave end of a CAD plate:
// a groove of radius 0.5 whose surface leaves the top face tangentially at
// x = 1). The groove's tilted planes give the solve a second direction, so
// it is not the one-plane fold above; but they pin the representative only
// weakly across the edge, and the least-squares point lies well inside it,
// while the quadric's residual alone says a fraction of that. The deviation
// covers how far the edge moves.
TEST(CollapseDeviation, ACurledKnifeEdgeBoundsHowFarItsEdgeMoves) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  for (double radius : {0.5, 2.0}) {
    NodeRecord node = flat_node();
    const int segments = 40;
    const double sweep = 0.6 / radius;  // the groove's arc within the cell
    auto at = [&](int i, double z) {
      const double t = sweep * i / segments;
      return Vec3d(1 - radius * std::sin(t), -radius * (1 - std::cos(t)), z);
    };
    for (int i = 0; i < segments; ++i) {  // facing down and out of the groove
      add_triangle(node, at(i, -1), at(i + 1, 1), at(i + 1, -1));
      add_triangle(node, at(i, -1), at(i, 1), at(i + 1, 1));
    }
    const Vec3d mean = node.vertex_sum / double(node.corner_count);
    const QemSolution s = solve_representative_vertex(node.quadric, mean, cell);
    EXPECT_GE(s.rank, 2) << "radius " << radius;
    const double edge_moved = std::hypot(1 - s.position.x, s.position.y);
    const CollapseDeviation d = collapse_deviation(node, cell, kFaces);
    EXPECT_GE(d.position, edge_moved) << "radius " << radius << ": representative at x " << s.position.x;
    EXPECT_LE(d.position, 4 * edge_moved) << "radius " << radius;
    EXPECT_GT(edge_moved, 0.05) << "radius " << radius << ": the case should move the edge";
  }
}

}  // namespace
}  // namespace raylod
