// Collapse deviation from a quadric (geometry/collapse_deviation.h): exact
// cases (plane, crease, corner) and the analytic chord error of spherical caps.
#include <gtest/gtest.h>

#include <array>
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

// The normal at a long triangle's far end (far_normal): the mean of the
// cell's normals is off the normal at the cap's rim by the cap's half-angle;
// a plane's, and each side's of a crease or corner (split by the crease
// rule), is exact.
TEST(CollapseDeviation, TheFarEndNormalIsTheSpreadOfACurvedCellOnly) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  EXPECT_LT(collapse_deviation(flat_node(), cell, kFaces).far_normal, 1e-6);
  EXPECT_LT(collapse_deviation(crease_node(), cell, kFaces).far_normal, 1e-6);
  EXPECT_LT(collapse_deviation(corner_node(), cell, kFaces).far_normal, 1e-6);
  for (double r : {0.5, 40.0})
    for (double alpha : {0.02, 0.1, 0.3}) {
      const double h = r * std::sin(alpha) * 1.01;
      const Bbox box{Vec3d(-h, -h, r * std::cos(alpha) - h), Vec3d(h, h, r + h)};
      EXPECT_NEAR(collapse_deviation(cap(r, alpha), box, kFaces).far_normal / alpha, 1.0, 0.05)
          << "r " << r << " alpha " << alpha;
    }
}

// The normals' spread without a solve (normal_spread_angle): a cap's
// half-angle, its sides' sizes aside (so over the cell's side, the
// curvature); 0 on a plane; across a crease a value set by the crease's
// angle and its sides' areas, not by curvature, which is why the probe's
// unreached-cell rule that reads it as curvature calibrates on the measured
// cells and keeps creases to the rim's rule.
TEST(CollapseDeviation, TheNormalSpreadIsACapsHalfAngleAndACreasesAngle) {
  EXPECT_LT(normal_spread_angle(flat_node()), 1e-6);
  EXPECT_EQ(normal_spread_angle(NodeRecord{}), 0.0);
  for (double r : {0.5, 40.0})
    for (double alpha : {0.02, 0.1, 0.3})
      EXPECT_NEAR(normal_spread_angle(cap(r, alpha)) / alpha, 1.0, 0.05) << "r " << r << " alpha " << alpha;
  // Floor (area 4) and wall (area 2) at 90 degrees: r = |(4, 2)| / 6.
  EXPECT_NEAR(normal_spread_angle(crease_node()), 2.0 * std::sqrt(1.0 - std::sqrt(20.0) / 6.0), 1e-9);
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

namespace raylod {
namespace {

// A flat face tessellated as a fan of large triangles, beside a small round
// (a quarter cylinder of radius r along x) finely tessellated: in one cell,
// the fan's area outweighs the round, so the representative sits on the
// face's plane and the cell's RMS distance hides how far the round moves.
// A descendant that holds only the round sees it.
TEST(CollapseDeviation, ADescendantShowsARoundTheCellsLargeTrianglesOutweigh) {
  const double r = 0.3;
  NodeRecord fan, round;
  // The face z = 1 for y <= 0.7: a fan of long slivers whose far corners lie
  // well outside the unit cell, so that, as in a store, only the two near
  // corners of each add its plane (area / 3 each) to this cell.
  const int slivers = 12;
  for (int k = 0; k < slivers; ++k) {
    const double x0 = double(k) / slivers, x1 = double(k + 1) / slivers;
    NodeRecord whole;
    add_triangle(whole, {x0, 0.7, 1}, {x1, 0.7, 1}, {0.5 * (x0 + x1), -200, 1});
    const double two_thirds = 2.0 / 3.0;
    Quadric q = whole.quadric;
    for (double* c : {&q.a00, &q.a01, &q.a02, &q.a11, &q.a12, &q.a22, &q.b0, &q.b1, &q.b2, &q.c}) *c *= two_thirds;
    quadric_add(fan.quadric, q);
    fan.normal_sum += two_thirds * whole.normal_sum;
    fan.vertex_sum += Vec3d(x0, 0.7, 1) + Vec3d(x1, 0.7, 1);
    fan.corner_count += 2;
  }
  // The round from the face (angle 0, z = 1) to the side y = 1 (angle 90).
  const int rows = 24;
  auto at = [&](double x, int i) {
    const double a = 0.5 * M_PI * i / rows;
    return Vec3d(x, 0.7 + r * std::sin(a), 0.7 + r * std::cos(a));
  };
  std::vector<std::array<Vec3d, 3>> round_triangles;
  for (int j = 0; j < 6; ++j)
    for (int i = 0; i < rows; ++i) {
      const double x0 = j / 6.0, x1 = (j + 1) / 6.0;
      round_triangles.push_back({at(x0, i), at(x0, i + 1), at(x1, i + 1)});
      round_triangles.push_back({at(x0, i), at(x1, i + 1), at(x1, i)});
    }
  for (const auto& t : round_triangles) add_triangle(round, t[0], t[1], t[2]);
  NodeRecord cell = fan;
  quadric_add(cell.quadric, round.quadric);
  cell.normal_sum += round.normal_sum;
  cell.vertex_sum += round.vertex_sum;
  cell.corner_count += round.corner_count;

  const CollapseDeviation d = collapse_deviation(cell, Bbox{Vec3d(0), Vec3d(1)}, kFaces);
  // Brute force: the largest distance of a round facet's plane from the
  // representative.
  double worst = 0;
  for (const auto& t : round_triangles) {
    const Vec3d n = glm::normalize(glm::cross(t[1] - t[0], t[2] - t[0]));
    worst = std::max(worst, std::abs(glm::dot(n, d.representative - t[0])));
  }
  ASSERT_GT(worst, 0.05);
  EXPECT_LT(d.position, 0.5 * worst) << "the cell's own quadric no longer hides the round";
  const NodeRecord descendants[] = {fan, round};
  const double seen = descendant_deviation(descendants, d.representative);
  // An RMS over the round's planes: below the largest, and well above what
  // the cell's own quadric says.
  EXPECT_LE(seen, worst + 1e-12);
  EXPECT_GE(seen, 0.4 * worst);
  EXPECT_GE(seen, 2.0 * d.position) << "position " << d.position << ", seen " << seen << ", worst " << worst;
}

// Where the cell's own estimate holds, its descendants add nothing: every
// part of a flat face, a crease or a corner passes through the
// representative, and a spherical cap's outer ring lies no farther than its
// chord error.
TEST(CollapseDeviation, DescendantsOfPlanesCreasesAndCapsAddNothing) {
  const Bbox cell{Vec3d(-1), Vec3d(1)};
  for (const NodeRecord& n : {flat_node(), crease_node(), corner_node()}) {
    const CollapseDeviation d = collapse_deviation(n, cell, kFaces);
    const NodeRecord one[] = {n};
    EXPECT_LT(descendant_deviation(one, d.representative), 1e-9);
  }
  for (double alpha : {0.05, 0.2}) {
    const double r = 1.0, h = r * std::sin(alpha) * 1.01;
    const NodeRecord whole = cap(r, alpha);
    const CollapseDeviation d =
        collapse_deviation(whole, Bbox{Vec3d(-h, -h, r * std::cos(alpha) - h), Vec3d(h, h, r + h)}, kFaces);
    // The outer half of the rings, and the inner half, as two descendants.
    NodeRecord outer, inner;
    const int rings = 80, slices = 160;
    auto at = [&](int i, int j) {
      const double th = alpha * double(i) / rings, ph = 2 * M_PI * double(j) / slices;
      return Vec3d(r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th));
    };
    for (int i = 0; i < rings; ++i)
      for (int j = 0; j < slices; ++j) {
        NodeRecord& n = i < rings / 2 ? inner : outer;
        add_triangle(n, at(i, j), at(i + 1, j), at(i + 1, j + 1));
        if (i > 0) add_triangle(n, at(i, j), at(i + 1, j + 1), at(i, j + 1));
      }
    const NodeRecord halves[] = {inner, outer};
    EXPECT_LE(descendant_deviation(halves, d.representative), d.position) << "alpha " << alpha;
  }
}

}  // namespace
}  // namespace raylod
