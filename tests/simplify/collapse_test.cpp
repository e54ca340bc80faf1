// The collapse core without a store: CutLookup, CollapseBuilder and the
// differential test against the in-memory reference vertex clustering.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <set>

#include "geometry/collapse_deviation.h"
#include "simplify/collapse.h"
#include "simplify/vertex_clustering.h"
#include "test_meshes.h"

namespace raylod {
namespace {

using test::add_tri;
using test::add_tri_n;

// Collapses `soup` with the given cells of a uniform level (all occupied
// cells if `codes` is empty) through CutLookup + CollapseBuilder.
struct Collapsed {
  IndexedMesh mesh;
  CollapseStats stats;
  std::vector<Representative> reps;
  std::vector<CellKey> keys;
};
Collapsed collapse_level(const TriangleBatch& soup, const test::MemoryNodes& nodes, std::vector<uint64_t> codes = {},
                         double crease_angle_deg = kDefaultCreaseAngleDeg, bool unfold = true) {
  Collapsed out;
  if (codes.empty()) for (const auto& [c, r] : nodes.nodes) codes.push_back(c);
  for (uint64_t c : codes) {
    out.keys.push_back({uint32_t(nodes.level), c});
    out.reps.push_back(make_representative(nodes.nodes.at(c), nodes.cell_bounds(c), nodes.origin));
  }
  const CutLookup lookup(nodes.root_lo, nodes.root_size, out.keys);
  CollapseBuilder builder(out.reps, !soup.normals.empty(), crease_angle_deg);
  std::vector<uint32_t> cell(soup.positions.size());
  for (size_t i = 0; i < cell.size(); ++i) cell[i] = lookup.find(Vec3d(soup.positions[i]));
  builder.add(soup, cell);
  builder.set_unfold(unfold);
  out.mesh = builder.finish(&out.stats);
  return out;
}

// A soup welded by position: the distinct positions, and per corner its index.
std::pair<std::vector<Vec3>, std::vector<uint32_t>> weld(const TriangleBatch& soup) {
  std::map<std::array<float, 3>, uint32_t> ids;
  std::vector<Vec3> pos;
  std::vector<uint32_t> idx;
  for (const Vec3& p : soup.positions) {
    auto [it, fresh] = ids.try_emplace({p.x, p.y, p.z}, uint32_t(pos.size()));
    if (fresh) pos.push_back(p);
    idx.push_back(it->second);
  }
  return {pos, idx};
}

TEST(CutLookup, FindsTheCutCellAmongMixedLevels) {
  // Root [0, 8]^3; cut: cell (level 1, x=0,y=0,z=0) and cell (level 3, x=5,y=5,z=5).
  const std::vector<CellKey> keys = {{1, morton_encode(0, 0, 0)}, {3, morton_encode(5, 5, 5)}};
  const CutLookup lookup(Vec3d(0), 8.0, keys);
  EXPECT_EQ(lookup.find(Vec3d(1, 2, 3.9)), 0u);
  EXPECT_EQ(lookup.find(Vec3d(3.99, 0, 0)), 0u);
  EXPECT_EQ(lookup.find(Vec3d(4.0, 0, 0)), kKeepVertex);  // next cell at level 1
  EXPECT_EQ(lookup.find(Vec3d(5.5, 5.5, 5.5)), 1u);
  EXPECT_EQ(lookup.find(Vec3d(6.0, 5.5, 5.5)), kKeepVertex);
  EXPECT_EQ(lookup.find(Vec3d(-1, -1, -1)), 0u);  // clamped to the grid like OctreeStore::cell_of
  EXPECT_EQ(CutLookup(Vec3d(0), 8.0, {}).find(Vec3d(1)), kKeepVertex);
}

TEST(CollapseBuilder, KeepsUncollapsedTrianglesExactlyAndIndexesSharedVertices) {
  TriangleBatch soup;
  add_tri(soup, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  add_tri(soup, {1, 0, 0}, {1, 1, 0}, {0, 1, 0});
  CollapseBuilder b({}, false);
  std::vector<uint32_t> cell(6, kKeepVertex);
  b.add(soup, cell);
  CollapseStats st;
  const IndexedMesh m = b.finish(&st);
  ASSERT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(m.positions.size(), 4u);
  for (size_t i = 0; i < 6; ++i) EXPECT_EQ(m.positions[m.indices[i]], soup.positions[i]);
  for (const Vec3& n : m.normals) EXPECT_NEAR(glm::distance(n, Vec3(0, 0, 1)), 0.0f, 1e-6f);
}

TEST(CollapseBuilder, DropsCollapsedZeroAreaAndDuplicateTrianglesButKeepsReverseTwins) {
  TriangleBatch soup;
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0), d(2, 0, 0);
  add_tri(soup, a, b, c);   // kept
  add_tri(soup, b, c, a);   // same triangle, rotated: duplicate
  add_tri(soup, a, c, b);   // reverse-wound twin: kept
  add_tri(soup, a, b, d);   // zero area (collinear)
  add_tri(soup, a, a, c);   // repeated vertex
  CollapseBuilder builder({}, false);
  builder.add(soup, std::vector<uint32_t>(soup.positions.size(), kKeepVertex));
  CollapseStats st;
  const IndexedMesh m = builder.finish(&st);
  EXPECT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(st.input_triangles, 5u);
  EXPECT_EQ(st.dropped_duplicate, 1u);
  EXPECT_EQ(st.dropped_zero_area, 1u);
  EXPECT_EQ(st.dropped_collapsed, 1u);
  EXPECT_EQ(st.reverse_twins, 2u);
  for (const Vec3& n : m.normals) {
    EXPECT_TRUE(is_finite(n));
    EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f);
  }
}

TEST(CollapseBuilder, FlagsTheRepresentativesOfTrianglesTurnedOver) {
  // Two triangles facing +z; corner c of the first moves to a representative
  // below edge ab (turned over, now facing -z), corner f of the second to
  // one that keeps it facing +z.
  TriangleBatch soup;
  add_tri(soup, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
  add_tri(soup, {5, 0, 0}, {6, 0, 0}, {5, 1, 0});
  std::vector<Representative> reps(2);
  reps[0].position = Vec3d(0.5, -1, 0);
  reps[1].position = Vec3d(5.2, 0.8, 0);
  CollapseBuilder b(reps, false);
  b.add(soup, std::vector<uint32_t>{kKeepVertex, kKeepVertex, 0, kKeepVertex, kKeepVertex, 1});
  ASSERT_EQ(b.folding().size(), 2u);
  EXPECT_EQ(b.folding()[0], 1);
  EXPECT_EQ(b.folding()[1], 0);
  CollapseStats st;
  const IndexedMesh m = b.finish(&st);
  EXPECT_EQ(m.triangle_count(), 2u);
  EXPECT_EQ(st.folded, 1u);
}

TEST(CollapseBuilder, AMergeAcrossACreaseKeepsEachSidesNormal) {
  // A vertex c on a 90-degree crease: three triangles on the top face
  // (z = 0, normal +z) and three on the side wall (y = 0, normal -y). Its
  // cell's representative lands below the wall's bottom edge, turning the
  // wall triangle (c, qa, qb) over, and the cell is too small for it to
  // slide back: unfolding collapses its shortest edge, onto the wall's
  // corner qb, whose own normals are all the wall's. The top triangles then
  // meet at qb; their corners there keep the top's normal (the
  // representative's cluster within the crease angle), not the wall's.
  const Vec3 c(0, 0, 0), ep(1, 0, 0), em(-1, 0, 0), pa(0.5f, 1, 0), pb(-0.5f, 1, 0), qa(-0.5f, 0, -1),
      qb(0.5f, 0, -1);
  TriangleBatch soup;
  add_tri(soup, c, ep, pa);
  add_tri(soup, c, pa, pb);
  add_tri(soup, c, pb, em);
  add_tri(soup, c, em, qa);
  add_tri(soup, c, qa, qb);
  add_tri(soup, c, qb, ep);
  std::vector<Representative> reps(1);
  reps[0].position = Vec3d(0.4, 0, -1.1);
  reps[0].side = 0.1;
  reps[0].cell_lo = Vec3d(0.35, -0.05, -1.15);
  reps[0].deviation = 1.0;  // lets the merge move the surface by 0.1
  std::vector<uint32_t> cell(soup.positions.size(), kKeepVertex);
  for (size_t t = 0; t < 6; ++t) cell[3 * t] = 0;
  for (const bool unfold : {false, true}) {
    CollapseBuilder b(reps, false);
    b.add(soup, cell);
    b.set_unfold(unfold);
    CollapseStats st;
    const IndexedMesh m = b.finish(&st);
    EXPECT_EQ(st.folded, 1u);
    if (!unfold) {
      EXPECT_EQ(m.triangle_count(), 6u);
      continue;
    }
    EXPECT_EQ(st.unfold_moved, 0u);
    EXPECT_EQ(st.unfold_merged, 1u);
    EXPECT_EQ(st.unfold_dropped, 2u);
    EXPECT_EQ(st.folded_after_unfold, 0u);
    ASSERT_EQ(m.triangle_count(), 4u);
    int top_corners_at_qb = 0;
    for (size_t t = 0; t < 4; ++t) {  // in input order: the three top ones, then the wall's (c, em, qa)
      const uint32_t* i = &m.indices[3 * t];
      const bool top = t < 3;
      for (int k = 0; k < 3; ++k) {
        EXPECT_NE(m.positions[i[k]], Vec3(reps[0].position)) << "the representative is merged away";
        if (m.positions[i[k]] != qb) continue;
        top_corners_at_qb += top;
        EXPECT_GT(glm::dot(m.normals[i[k]], top ? Vec3(0, 0, 1) : Vec3(0, -1, 0)), 0.999f) << "triangle " << t;
      }
    }
    EXPECT_EQ(top_corners_at_qb, 3);
  }
}

TEST(CollapseBuilder, TrianglesWhollyInsideACellGiveTheirNormalsThroughTheCellsSum) {
  // Triangle A reaches from the cell (its corner at the origin) to two kept
  // corners and faces +z. Triangle B lies wholly inside the cell, tilted by
  // `tilt` about x: it vanishes unexamined, and its normal comes back as the
  // cell's sum (the store's node) less what A gave. Within 10 degrees of A's
  // normal it joins A's cluster; farther, it stays out of the crease rule.
  for (const double tilt_deg : {5.0, 20.0}) {
    const double tilt = tilt_deg * M_PI / 180.0;
    TriangleBatch soup;
    add_tri(soup, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    const float s = float(std::sin(tilt)), c = float(std::cos(tilt));
    add_tri(soup, {0.1f, 0.1f, 0}, {0.3f, 0.1f, 0}, {0.1f, 0.1f + 0.2f * c, 0.2f * s});
    auto weighted_normal = [&](size_t t) {  // twice the area times the unit normal, per corner
      const Vec3d p0(soup.positions[3 * t]), p1(soup.positions[3 * t + 1]), p2(soup.positions[3 * t + 2]);
      return glm::cross(p1 - p0, p2 - p0);
    };
    std::vector<Representative> reps(1);
    reps[0].position = Vec3d(0.05, 0.05, 0);
    reps[0].normal_sum = weighted_normal(0) + 3.0 * weighted_normal(1);  // A's one corner, B's three
    reps[0].has_normal_sum = true;
    CollapseBuilder b(reps, false);
    b.add(soup, std::vector<uint32_t>{0, kKeepVertex, kKeepVertex, 0, 0, 0});
    CollapseStats st;
    const IndexedMesh m = b.finish(&st);
    ASSERT_EQ(m.triangle_count(), 1u);
    EXPECT_EQ(st.inside_cell, 1u);
    EXPECT_EQ(st.dropped_collapsed, 1u);
    EXPECT_EQ(st.input_triangles, 2u);
    const uint32_t rep = m.indices[0];
    EXPECT_EQ(m.positions[rep], Vec3(0.05f, 0.05f, 0));
    const Vec3d expect = tilt_deg < 10 ? glm::normalize(weighted_normal(0) + 3.0 * weighted_normal(1)) : Vec3d(0, 0, 1);
    EXPECT_NEAR(glm::distance(Vec3d(m.normals[rep]), expect), 0.0, 1e-6) << "tilt " << tilt_deg;
  }
}

TEST(CollapseBuilder, AZeroInputNormalAtARepresentativeTakesItsFaceNormal) {
  // A cell whose hidden triangles face +z (weight 100 in its normal sum) and
  // one triangle reaching out of it, tilted 5 degrees. A tiny second
  // reaching triangle carries a zero normal (a stored zero code, or an API
  // caller's) at its corner in the cell: it must count as its face normal,
  // not put NaN into the cluster (which dropped the hidden sum: the
  // representative then faced 5 degrees off).
  const Vec3 tilted = glm::normalize(Vec3(0.0872f, 0, 0.9962f));
  for (const bool with_zero : {false, true}) {
    std::vector<Representative> reps(1);
    reps[0].position = Vec3d(0);
    reps[0].fallback_normal = Vec3d(1, 0, 0);
    reps[0].normal_sum = Vec3d(0, 0, 100) + Vec3d(tilted);
    reps[0].has_normal_sum = true;
    CollapseBuilder b(reps, true, 30.0);
    TriangleBatch soup;
    add_tri(soup, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    soup.normals = {tilted, tilted, tilted};
    std::vector<uint32_t> cell{0, kKeepVertex, kKeepVertex};
    if (with_zero) {
      add_tri(soup, {0, 0, 0}, {0, -1e-3f, 0}, {1e-3f, 0, 0});
      soup.normals.insert(soup.normals.end(), {Vec3(0), Vec3(0, 0, 1), Vec3(0, 0, 1)});
      cell.insert(cell.end(), {0, kKeepVertex, kKeepVertex});
    }
    b.add(soup, cell);
    CollapseStats st;
    const IndexedMesh m = b.finish(&st);
    ASSERT_GE(m.triangle_count(), 1u);
    const Vec3 n = m.normals[m.indices[0]];  // the representative's corner
    EXPECT_TRUE(is_finite(n)) << with_zero;
    EXPECT_EQ(st.normal_fallbacks, 0u) << with_zero;
    // Mostly the hidden +z sum: within a degree of +z either way.
    EXPECT_GT(double(n.z), std::cos(M_PI / 180.0)) << with_zero << ": " << n.x << " " << n.y << " " << n.z;
  }
}

TEST(CollapseBuilder, ReserveMidStreamKeepsTheVerticesFoundSoFar) {
  const TriangleBatch sphere = test::uv_sphere({0, 0, 0}, 1.0f, 12, 16);
  TriangleBatch first, second;
  const size_t half = 3 * (sphere.size() / 2);
  first.positions.assign(sphere.positions.begin(), sphere.positions.begin() + long(half));
  first.normals.assign(sphere.normals.begin(), sphere.normals.begin() + long(half));
  second.positions.assign(sphere.positions.begin() + long(half), sphere.positions.end());
  second.normals.assign(sphere.normals.begin() + long(half), sphere.normals.end());
  CollapseBuilder a({}, true), b({}, true);
  a.add(sphere, std::vector<uint32_t>(sphere.positions.size(), kKeepVertex));
  b.add(first, std::vector<uint32_t>(first.positions.size(), kKeepVertex));
  b.reserve(100000, 1000);
  b.add(second, std::vector<uint32_t>(second.positions.size(), kKeepVertex));
  const IndexedMesh ma = a.finish(), mb = b.finish();
  EXPECT_EQ(ma.positions, mb.positions);
  EXPECT_EQ(ma.indices, mb.indices);
}

TEST(CollapseBuilder, ZeroAreaAndRepeatedVertexInputNeverGiveNaN) {
  // A cluster whose only triangles are degenerate: quadric A = 0, no normal
  // weight. The representative is the mean, its normal the +Y fallback.
  TriangleBatch soup;
  add_tri(soup, {0.1f, 0.1f, 0.1f}, {0.2f, 0.2f, 0.2f}, {0.3f, 0.3f, 0.3f});  // collinear
  add_tri(soup, {0.1f, 0.1f, 0.1f}, {0.1f, 0.1f, 0.1f}, {2, 2, 2});         // repeated vertex
  add_tri(soup, {0.2f, 0.2f, 0.2f}, {2, 2, 2}, {2, 3, 2});
  const test::MemoryNodes nodes = test::accumulate_nodes(soup, Vec3d(0), 4.0, 1, Vec3d(0));
  const Collapsed c = collapse_level(soup, nodes, {morton_encode(0, 0, 0)});
  EXPECT_EQ(c.reps[0].rank, 1);  // the one non-degenerate triangle has a corner in the cell
  ASSERT_EQ(c.mesh.triangle_count(), 1u);
  for (size_t i = 0; i < c.mesh.positions.size(); ++i) {
    EXPECT_TRUE(is_finite(c.mesh.positions[i]));
    EXPECT_NEAR(glm::length(c.mesh.normals[i]), 1.0f, 1e-6f);
  }
  // Only degenerate triangles in the cell: A = 0.
  TriangleBatch only_bad;
  add_tri(only_bad, {0.1f, 0.1f, 0.1f}, {0.2f, 0.2f, 0.2f}, {0.3f, 0.3f, 0.3f});
  add_tri(only_bad, {0.4f, 0.4f, 0.4f}, {0.4f, 0.4f, 0.4f}, {3, 3, 3});
  add_tri(only_bad, {0.5f, 0.5f, 0.5f}, {3, 3, 3}, {3.5f, 3.5f, 3.5f});  // collinear
  const test::MemoryNodes bad_nodes = test::accumulate_nodes(only_bad, Vec3d(0), 4.0, 1, Vec3d(0));
  const NodeRecord& r = bad_nodes.nodes.at(morton_encode(0, 0, 0));
  EXPECT_EQ(r.corner_count, 6u);
  const Representative rep = make_representative(r, bad_nodes.cell_bounds(r.code), Vec3d(0));
  EXPECT_TRUE(is_finite(rep.position));
  EXPECT_NEAR(glm::length(rep.position - r.vertex_sum / 6.0), 0.0, 1e-6);  // float-rounded
  EXPECT_EQ(rep.fallback_normal, Vec3d(0, 1, 0));
}

TEST(CollapseBuilder, RepresentativeNormalIsTheAreaWeightedMeanOfMergedNormals) {
  // Two triangles sharing corners in the collapsed cell, with vertex normals
  // tilted +-x; the larger triangle must dominate.
  TriangleBatch soup;
  const Vec3 nl = glm::normalize(Vec3(-1, 0, 1)), nr = glm::normalize(Vec3(1, 0, 1));
  add_tri_n(soup, {0.1f, 0.1f, 0}, {3, 0.2f, 0}, {3, 3, 0}, nl, nl, nl);        // area ~4.3
  add_tri_n(soup, {0.2f, 0.1f, 0}, {3, 3.5f, 0}, {2.5f, 3.5f, 0}, nr, nr, nr);  // area ~0.8
  const test::MemoryNodes nodes = test::accumulate_nodes(soup, Vec3d(0), 4.0, 1, Vec3d(0));
  const Collapsed c = collapse_level(soup, nodes, {morton_encode(0, 0, 0)});
  ASSERT_EQ(c.mesh.triangle_count(), 2u);
  const double a1 = 0.5 * glm::length(glm::cross(Vec3d(2.9, 0.1, 0), Vec3d(2.9, 2.9, 0)));
  const double a2 = 0.5 * glm::length(glm::cross(Vec3d(2.8, 3.4, 0), Vec3d(2.3, 3.4, 0)));
  const Vec3 expect = Vec3(glm::normalize(a1 * Vec3d(nl) + a2 * Vec3d(nr)));
  // The representative is the vertex used by both triangles.
  const uint32_t rep = c.mesh.indices[0];
  EXPECT_EQ(rep, c.mesh.indices[3]);
  EXPECT_NEAR(glm::distance(c.mesh.normals[rep], expect), 0.0f, 1e-6f);
  EXPECT_NEAR(glm::length(c.mesh.normals[rep]), 1.0f, 1e-6f);
}

TEST(CollapseBuilder, OppositeSheetsInOneCellKeepTheirOwnNormals) {
  // A thin wall (two coplanar sheets facing opposite ways, 1e-4 apart) in one
  // collapsed cell: the merged vertex normals sum to zero, so one averaged
  // normal would be NaN (or, with a fallback, wrong for one side). The crease
  // rule gives each sheet's corner at the representative its own side's
  // normal: one position, two vertices.
  TriangleBatch soup;
  const Vec3 up(0, 0, 1), down(0, 0, -1);
  add_tri_n(soup, {0.5f, 0.5f, 0.5f}, {3, 0.5f, 0.5f}, {0.5f, 3, 0.5f}, up, up, up);
  add_tri_n(soup, {0.6f, 0.6f, 0.5001f}, {0.6f, 3.1f, 0.5001f}, {3.1f, 0.6f, 0.5001f}, down, down, down);
  const test::MemoryNodes nodes = test::accumulate_nodes(soup, Vec3d(0), 4.0, 1, Vec3d(0));
  // Collapse only cell (0,0,0): both sheets' first corners merge.
  const Collapsed c = collapse_level(soup, nodes, {morton_encode(0, 0, 0)});
  ASSERT_EQ(c.mesh.triangle_count(), 2u);
  const uint32_t a = c.mesh.indices[0], b = c.mesh.indices[3];
  EXPECT_NE(a, b);
  EXPECT_EQ(c.mesh.positions[a], c.mesh.positions[b]);
  EXPECT_EQ(c.mesh.normals[a], up);
  EXPECT_EQ(c.mesh.normals[b], down);
  EXPECT_EQ(c.stats.representatives_used, 1u);
  EXPECT_EQ(c.stats.split_vertices, 1u);
  EXPECT_EQ(c.stats.normal_fallbacks, 0u);
  // Naive: the normalised sum of the merged normals is NaN.
  const Vec3 naive = glm::normalize(up * 1.0f + down * 1.0f);
  EXPECT_FALSE(is_finite(naive));
}

TEST(CollapseBuilder, CellSpanningACreaseGetsOneNormalPerSideAndFlatSidesTheirOwn) {
  // An L-shaped fold without input normals: a floor (y = 0, facing +y) and a
  // wall (x = 0, facing +x), each of two triangles, meeting at x = 0. The cell
  // at the fold corner collapses to one position; the floor's corners there
  // must get exactly +y and the wall's exactly +x (no pillow shading).
  TriangleBatch soup;
  add_tri(soup, {0.1f, 0, 0.1f}, {0.1f, 0, 3.9f}, {3.9f, 0, 3.9f});
  add_tri(soup, {0.1f, 0, 0.1f}, {3.9f, 0, 3.9f}, {3.9f, 0, 0.1f});
  add_tri(soup, {0, 0.2f, 0.1f}, {0, 3.9f, 0.1f}, {0, 3.9f, 3.9f});
  add_tri(soup, {0, 0.2f, 0.1f}, {0, 3.9f, 3.9f}, {0, 0.2f, 3.9f});
  const test::MemoryNodes nodes = test::accumulate_nodes(soup, Vec3d(-0.5), 8.0, 2, Vec3d(0));
  // Level 2 cells have side 2: the cell at the origin holds the floor's and
  // the wall's first corners.
  const uint64_t corner = morton_encode(0, 0, 0);
  ASSERT_EQ(nodes.nodes.count(corner), 1u);
  const Collapsed c = collapse_level(soup, nodes, {corner});
  ASSERT_EQ(c.mesh.triangle_count(), 4u);
  for (size_t t = 0; t < 4; ++t) {
    const Vec3 want = t < 2 ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
    for (int k = 0; k < 3; ++k) {
      const Vec3 n = c.mesh.normals[c.mesh.indices[3 * t + k]];
      EXPECT_NEAR(glm::distance(n, want), 0.0f, 1e-6f) << "triangle " << t << " corner " << k;
    }
  }
  EXPECT_EQ(c.stats.representatives_used, 1u);
  EXPECT_EQ(c.stats.split_vertices, 1u);
  // With a crease angle over 90 degrees the fold is smooth: one normal there.
  const Collapsed smooth = collapse_level(soup, nodes, {corner}, 100.0);
  EXPECT_EQ(smooth.stats.split_vertices, 0u);
}

// The largest angle between +y and the normals of the flat end's corners
// (triangles with a kept corner on the flat end's inner edge x = inner) in
// the collapsed fillet scene below; the number of such corners in *corners.
double flat_end_tilt(const Collapsed& c, float inner, float y, size_t* corners) {
  double worst = 0;
  *corners = 0;
  for (size_t t = 0; t < c.mesh.triangle_count(); ++t) {
    bool flat_end = false;
    for (int k = 0; k < 3; ++k) {
      const Vec3 p = c.mesh.positions[c.mesh.indices[3 * t + size_t(k)]];
      flat_end |= p.x == inner && p.y == y;
    }
    if (!flat_end) continue;
    for (int k = 0; k < 3; ++k) {
      const Vec3 n = c.mesh.normals[c.mesh.indices[3 * t + size_t(k)]];
      worst = std::max(worst, std::acos(std::clamp(double(n.y), -1.0, 1.0)));
      ++*corners;
    }
  }
  return worst;
}

TEST(CollapseBuilder, AFlatFaceBesideAFilletKeepsNearlyItsOwnNormal) {
  // A flat end (y = Y, facing +y) whose rim rounds off into a wall (x = X,
  // facing +x) through a fillet of sixty thin rows (0.75 to 89.25 degrees);
  // no input normals. Every row meets the next within the crease angle, so
  // the crease rule's band (30 degrees) around the flat end's normal holds
  // the first twenty rows, which, merged at the rim's representative,
  // tilted the flat end's corners there by as much as the cell held of the
  // fillet, differently from cell to cell (radial streaks across the flat
  // ends of pins, real CAD parts, seen closer than the cut was made for).
  // The flat end (80% or more of the weight within 10 degrees of it, beside
  // at least four rows there) takes only those rows: at most 0.0008 rad
  // here, where the band gave 0.0031 to 0.0062 (measured before the rule).
  TriangleBatch soup;
  const float X = 3.7f, Y = -0.2f, r = 0.05f, inner = 0.5f;
  for (float z = 0.5f; z < 3.f; z += 1.0f) {
    add_tri(soup, {inner, Y, z}, {inner, Y, z + 1}, {X - r, Y, z + 1});
    add_tri(soup, {inner, Y, z}, {X - r, Y, z + 1}, {X - r, Y, z});
    for (int k = 0; k < 60; ++k) {
      const double a0 = k * M_PI / 120, a1 = (k + 1) * M_PI / 120;  // 0 to 90 degrees
      const Vec3 p0(float(X - r + r * std::sin(a0)), float(Y - r + r * std::cos(a0)), 0);
      const Vec3 p1(float(X - r + r * std::sin(a1)), float(Y - r + r * std::cos(a1)), 0);
      add_tri(soup, p0 + Vec3(0, 0, z), p1 + Vec3(0, 0, z + 1), p1 + Vec3(0, 0, z));
      add_tri(soup, p0 + Vec3(0, 0, z), p0 + Vec3(0, 0, z + 1), p1 + Vec3(0, 0, z + 1));
    }
    add_tri(soup, {X, Y - r, z}, {X, Y - r, z + 1}, {X, -3.5f, z + 1});
    add_tri(soup, {X, Y - r, z}, {X, -3.5f, z + 1}, {X, -3.5f, z});
  }
  // Level 3 cells have side 1 (root 8 at -4): the flat end's rim and the
  // fillet lie in the cells x in [3, 4], y in [-1, 0], one per unit of z;
  // collapse those, keep the rest.
  const test::MemoryNodes nodes = test::accumulate_nodes(soup, Vec3d(-4), 8.0, 3, Vec3d(0));
  std::vector<uint64_t> rim;
  for (const auto& [code, node] : nodes.nodes) {
    const Bbox b = nodes.cell_bounds(code);
    if (b.lo.x == 3.0 && b.lo.y == -1.0) rim.push_back(code);
  }
  ASSERT_EQ(rim.size(), 4u);
  size_t corners = 0;
  const double tilt = flat_end_tilt(collapse_level(soup, nodes, rim), inner, Y, &corners);
  EXPECT_EQ(corners, 2u * 3u * 3u);
  EXPECT_LT(tilt, 0.0015) << "radians";
}

TEST(CollapseBuilder, CollapsingNothingGivesTheFullRendersCornerNormals) {
  // Without input normals, kept vertices follow the same crease rule as the
  // full-resolution render (crease_corner_normals on the welded mesh).
  const TriangleBatch box = test::closed_box({-1.2f, -1.3f, -0.9f}, {-0.4f, -0.8f, 1.2f}, 3);
  TriangleBatch sphere = test::uv_sphere({0.3f, -0.2f, 0.1f}, 1.0f, 12, 20);
  sphere.normals.clear();
  for (const TriangleBatch* soup : {&box, static_cast<const TriangleBatch*>(&sphere)}) {
    CollapseBuilder builder({}, false);
    std::vector<uint32_t> cell(soup->positions.size(), kKeepVertex);
    builder.add(*soup, cell);
    CollapseStats stats;
    const IndexedMesh out = builder.finish(&stats);
    // Reference: weld by position, then the rule per corner.
    const auto [pos, idx] = weld(*soup);
    const std::vector<Vec3> ref = crease_corner_normals(pos, idx, kDefaultCreaseAngleDeg);
    ASSERT_EQ(out.triangle_count(), soup->size());
    for (size_t i = 0; i < idx.size(); ++i) {
      EXPECT_EQ(out.positions[out.indices[i]], soup->positions[i]);
      EXPECT_NEAR(glm::distance(out.normals[out.indices[i]], ref[i]), 0.0f, 1e-5f) << "corner " << i;
    }
  }
  // The box: 8 corners, each split into its 3 faces' normals.
  CollapseBuilder builder({}, false);
  std::vector<uint32_t> cell(box.positions.size(), kKeepVertex);
  builder.add(box, cell);
  const IndexedMesh out = builder.finish();
  size_t axis_aligned = 0;
  for (const Vec3& n : out.normals)
    axis_aligned += std::abs(std::abs(n.x) + std::abs(n.y) + std::abs(n.z) - 1.0f) < 1e-6f;
  EXPECT_EQ(axis_aligned, out.normals.size());
}

TEST(CollapseBuilder, CellsOfOneVertexAreOutputAsKept) {
  // Without input normals, the cut marks cells that hold a single vertex
  // wherever nothing deviates there (finest cells of a CAD tessellation's
  // long strips); collapsing such a cell changes nothing, so it must come out
  // as that vertex kept: its exact position and the full render's
  // angle-weighted crease normals, not its cluster's area-weighted mean
  // (which bands a mirror's reflection along the strips). A uv sphere's
  // triangles shrink towards its poles, so the two weightings differ there.
  TriangleBatch sphere = test::uv_sphere({0.3f, -0.2f, 0.1f}, 1.0f, 12, 20);
  sphere.normals.clear();
  const auto [pos, idx] = weld(sphere);
  const std::vector<Vec3> ref = crease_corner_normals(pos, idx, kDefaultCreaseAngleDeg);
  // One representative per vertex, a little off the vertex (as a solve's
  // rounding may leave it), with the cell's corner count; then the same
  // with the counts unknown, where the cells are collapsed as any other.
  for (const bool counted : {true, false}) {
    std::vector<Representative> reps(pos.size());
    for (uint32_t i : idx) reps[i].corner_count += counted ? 1 : 0;
    for (size_t v = 0; v < pos.size(); ++v) reps[v].position = Vec3d(pos[v]) + Vec3d(1e-4);
    CollapseBuilder builder(reps, false);
    builder.add(sphere, idx);
    CollapseStats stats;
    const IndexedMesh out = builder.finish(&stats);
    ASSERT_EQ(out.triangle_count(), sphere.size());
    EXPECT_EQ(stats.one_vertex_cells, counted ? pos.size() : 0u);
    double worst = 0;
    for (size_t i = 0; i < idx.size(); ++i) {
      if (counted) {
        EXPECT_EQ(out.positions[out.indices[i]], sphere.positions[i]) << "corner " << i;
      }
      worst = std::max(worst, double(glm::distance(out.normals[out.indices[i]], ref[i])));
    }
    if (counted) {
      EXPECT_LT(worst, 1e-5) << "kept vertices' rule";
    } else {
      EXPECT_GT(worst, 1e-3) << "area weighting should differ near the poles";
    }
  }
  // With input normals each corner keeps its own: the sphere faceted (every
  // corner its face's normal, as a PLY written from an STL), one cell per
  // vertex.
  TriangleBatch faceted = sphere;
  for (size_t t = 0; t < faceted.size(); ++t) {
    const Vec3 a = faceted.positions[3 * t], b = faceted.positions[3 * t + 1], c = faceted.positions[3 * t + 2];
    const Vec3 n = glm::normalize(glm::cross(b - a, c - a));
    for (int k = 0; k < 3; ++k) faceted.normals.push_back(n);
  }
  {
    std::vector<Representative> reps(pos.size());
    for (uint32_t i : idx) ++reps[i].corner_count;
    for (size_t v = 0; v < pos.size(); ++v) reps[v].position = Vec3d(pos[v]);
    CollapseBuilder builder(reps, true);
    builder.add(faceted, idx);
    CollapseStats stats;
    const IndexedMesh out = builder.finish(&stats);
    EXPECT_EQ(stats.one_vertex_cells, pos.size());
    for (size_t i = 0; i < idx.size(); ++i)
      EXPECT_LT(glm::distance(out.normals[out.indices[i]], faceted.normals[i]), 1e-6f) << "corner " << i;  // unit again
  }
  // A cell of two vertices is a real collapse: its count is met, but by two positions.
  std::vector<Representative> reps(pos.size() - 1);
  std::vector<uint32_t> cell(idx);
  for (uint32_t& c : cell) c = c == pos.size() - 1 ? uint32_t(pos.size() - 2) : c;  // the last two vertices in one cell
  for (uint32_t c : cell) ++reps[c].corner_count;
  for (size_t v = 0; v < reps.size(); ++v) reps[v].position = Vec3d(pos[v]);
  CollapseBuilder builder(reps, false);
  builder.add(sphere, cell);
  CollapseStats stats;
  builder.finish(&stats);
  EXPECT_EQ(stats.one_vertex_cells, reps.size() - 1);
}

TEST(CollapseBuilder, ClosedInputStaysClosedWhenNoCellSpansTheWall) {
  // A thin closed slab [0,1] x [0,1] x [1, 1.1] (grid spacing 1/32):
  // collapsing only cells that hold the top sheet and not the bottom never
  // merges the two sides.
  const TriangleBatch slab = test::closed_box({0, 0, 1.0f}, {1, 1, 1.1f}, 32);
  // The input itself is closed.
  CollapseBuilder identity({}, false);
  identity.add(slab, std::vector<uint32_t>(slab.positions.size(), kKeepVertex));
  ASSERT_TRUE(test::edges_paired(identity.finish()));
  // Level-3 cells (side 0.5) hold both sheets; level-6 cells (side 1/16) separate them.
  const test::MemoryNodes nodes = test::accumulate_nodes(slab, Vec3d(0), 4.0, 3, Vec3d(2, 2, 1));
  std::vector<uint64_t> top;
  const test::MemoryNodes fine = test::accumulate_nodes(slab, Vec3d(0), 4.0, 6, Vec3d(2, 2, 1));
  for (const auto& [code, r] : fine.nodes) {
    const Bbox b = fine.cell_bounds(code);
    const bool has_top = b.lo.z <= 1.1 && b.hi.z > 1.1, has_bottom = b.lo.z <= 1.0 && b.hi.z > 1.0;
    if (has_top && !has_bottom && (code % 3 == 0)) top.push_back(code);  // a scattered subset
  }
  ASSERT_GT(top.size(), 10u);
  const Collapsed c = collapse_level(slab, fine, top);
  EXPECT_LT(c.mesh.triangle_count(), slab.size());
  size_t unpaired = 0;
  EXPECT_TRUE(test::edges_paired(c.mesh, &unpaired)) << unpaired << " unpaired edges";
  EXPECT_EQ(c.stats.reverse_twins, 0u);

  // Collapsing across the wall (every cell at level 3) makes reverse twins;
  // they are kept, so every edge is still paired.
  const Collapsed across = collapse_level(slab, nodes);
  EXPECT_GT(across.stats.reverse_twins, 0u);
  EXPECT_TRUE(test::edges_paired(across.mesh, &unpaired)) << unpaired << " unpaired edges";
}

TEST(VertexClusteringDifferential, UniformCutEqualsReferenceClustering) {
  // The whole mesh collapsed at one level through CutLookup + CollapseBuilder
  // equals the straightforward in-memory clustering on the same grid.
  const TriangleBatch mesh = test::uv_sphere({0.3f, -0.2f, 0.1f}, 1.0f, 40, 64);
  const TriangleBatch box = test::closed_box({-1.2f, -1.3f, -0.9f}, {-0.4f, -0.8f, 1.2f}, 6);  // no normals: drop them
  for (int level = 2; level <= 5; ++level) {
    const Vec3d root_lo(-1.5, -1.5, -1.5), origin(0.1, 0.0, -0.2);
    const double root_size = 3.0;
    for (const TriangleBatch* soup : {&mesh, &box}) {
      const test::MemoryNodes nodes = test::accumulate_nodes(*soup, root_lo, root_size, level, origin);
      // A crease angle of 180 degrees smooths everything: the reference's
      // one area-weighted normal per representative. The reference clusters
      // only: no unfolding (unfold.h), which may only take triangles away.
      const Collapsed c = collapse_level(*soup, nodes, {}, 180.0, false);
      const Collapsed unfolded = collapse_level(*soup, nodes, {}, 180.0, true);
      EXPECT_LE(unfolded.mesh.triangle_count(), c.mesh.triangle_count()) << "level " << level;
      EXPECT_LE(unfolded.stats.folded_after_unfold, unfolded.stats.folded_before_unfold) << "level " << level;
      if (unfolded.stats.folded_before_unfold == 0) {
        EXPECT_EQ(unfolded.mesh.positions, c.mesh.positions) << "level " << level;
        EXPECT_EQ(unfolded.mesh.indices, c.mesh.indices) << "level " << level;
      }
      VertexClusteringConfig cfg;
      cfg.root_lo = root_lo;
      cfg.root_size = root_size;
      cfg.level = level;
      cfg.origin = origin;
      const IndexedMesh ref = cluster_vertices(*soup, cfg);
      ASSERT_GT(ref.triangle_count(), 0u);
      EXPECT_EQ(c.mesh.triangle_count(), ref.triangle_count()) << "level " << level;
      EXPECT_EQ(test::canonical_triangles(c.mesh), test::canonical_triangles(ref)) << "level " << level;
      // Same normals per position; but a cell of one vertex is that vertex
      // kept (collapse.h), with the full render's angle-weighted normal.
      std::map<std::array<float, 3>, Vec3> ref_normal;
      for (size_t i = 0; i < ref.positions.size(); ++i)
        ref_normal[{ref.positions[i].x, ref.positions[i].y, ref.positions[i].z}] = ref.normals[i];
      const auto [pos, idx] = weld(*soup);
      const std::vector<Vec3> smooth = crease_corner_normals(pos, idx, 180.0);
      std::map<uint64_t, std::set<uint32_t>> vertices_of_cell;
      const CutLookup all(root_lo, root_size, c.keys);
      for (uint32_t v = 0; v < pos.size(); ++v) vertices_of_cell[all.find(Vec3d(pos[v]))].insert(v);
      size_t one_vertex = 0;
      for (const auto& [cell, vs] : vertices_of_cell)
        if (vs.size() == 1) {  // with input normals, the vertex's own (the same for all its corners here)
          const uint32_t v = *vs.begin();
          for (size_t k = 0; k < idx.size(); ++k)
            if (idx[k] == v) ref_normal[{pos[v].x, pos[v].y, pos[v].z}] = soup->normals.empty() ? smooth[k] : soup->normals[k];
          ++one_vertex;
        }
      EXPECT_EQ(c.stats.one_vertex_cells, one_vertex) << "level " << level;
      for (size_t i = 0; i < c.mesh.positions.size(); ++i) {
        const auto it = ref_normal.find({c.mesh.positions[i].x, c.mesh.positions[i].y, c.mesh.positions[i].z});
        ASSERT_NE(it, ref_normal.end());
        EXPECT_NEAR(glm::distance(it->second, c.mesh.normals[i]), 0.0f, 1e-5f) << "level " << level;
      }
    }
  }
}

TEST(CollapseProperty, SeededRandomMeshesGiveFiniteVerticesInsideTheirCells) {
  std::mt19937_64 rng(2024);
  std::uniform_real_distribution<float> u(0, 1);
  for (int it = 0; it < 40; ++it) {
    TriangleBatch soup;
    const int n = 50 + int(u(rng) * 400);
    const bool normals = it % 2;
    const float spread = it % 3 == 0 ? 1e-3f : 1.0f;  // some clumped meshes
    for (int t = 0; t < n; ++t) {
      Vec3 base(u(rng), u(rng), u(rng));
      Vec3 p[3];
      for (int k = 0; k < 3; ++k) p[k] = base + spread * 0.2f * Vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
      if (t % 17 == 0) p[2] = p[1];                                // repeated vertex
      if (t % 19 == 0) p[2] = 0.5f * (p[0] + p[1]);                // collinear
      if (t % 23 == 0 && t > 0) p[0] = soup.positions[3 * (t - 1)];  // shared vertices
      if (normals) {
        Vec3 nn[3];
        for (int k = 0; k < 3; ++k) nn[k] = glm::normalize(Vec3(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f) + 1e-3f);
        add_tri_n(soup, p[0], p[1], p[2], nn[0], nn[1], nn[2]);
      } else {
        add_tri(soup, p[0], p[1], p[2]);
      }
    }
    const int level = 1 + it % 5;
    const test::MemoryNodes nodes = test::accumulate_nodes(soup, Vec3d(-0.5), 2.0, level, Vec3d(0.5));
    std::vector<uint64_t> codes;
    for (const auto& [code, r] : nodes.nodes) if (u(rng) < 0.6f) codes.push_back(code);
    const Collapsed c = collapse_level(soup, nodes, codes);
    std::set<std::array<float, 3>> input;
    for (const Vec3& p : soup.positions) input.insert({p.x, p.y, p.z});
    std::map<std::array<float, 3>, size_t> rep_of;
    for (size_t i = 0; i < c.reps.size(); ++i) {
      const Vec3 p(c.reps[i].position);
      rep_of[{p.x, p.y, p.z}] = i;
      const Bbox cell = nodes.cell_bounds(codes[i]);
      ASSERT_TRUE(test::inside(c.reps[i].position, cell)) << "iteration " << it;
      ASSERT_TRUE(test::inside(Vec3d(Vec3(c.reps[i].position)), cell)) << "iteration " << it;  // as written
    }
    for (size_t i = 0; i < c.mesh.positions.size(); ++i) {
      const Vec3& p = c.mesh.positions[i];
      ASSERT_TRUE(is_finite(p) && is_finite(c.mesh.normals[i])) << "iteration " << it;
      ASSERT_NEAR(glm::length(c.mesh.normals[i]), 1.0f, 1e-5f);
      // Every output vertex is an input vertex or a representative (float of a point inside its cell).
      const bool known = input.count({p.x, p.y, p.z}) || rep_of.count({p.x, p.y, p.z});
      ASSERT_TRUE(known) << "iteration " << it;
    }
    for (size_t t = 0; t < c.mesh.triangle_count(); ++t) {
      const uint32_t* f = &c.mesh.indices[3 * t];
      ASSERT_TRUE(f[0] != f[1] && f[1] != f[2] && f[0] != f[2]);
    }
  }
}

}  // namespace
}  // namespace raylod

namespace raylod {
namespace {

TEST(CollapseDeviationProperty, CollapsedSphereStaysWithinTheDeviationItsCellsPromised) {
  // Differential test against the analytic surface: collapse a finely
  // tessellated sphere uniformly at several levels; every point sampled on
  // the output triangles lies within the promised deviation of the sphere
  // (a triangle spans neighbouring cells, so up to twice the largest cell
  // deviation), and every output normal is within the promised normal
  // deviation of the true normal at the point it shades, up to the angle
  // the chord itself subtends.
  const Vec3d centre(0.3, -0.2, 0.1);
  const float radius = 1.0f;
  const TriangleBatch sphere = test::uv_sphere(Vec3(centre), radius, 120, 240);
  // Level 3 cells (side 0.375) span about 25 degrees of the unit sphere;
  // level 2 cells (45 degrees and more) are beyond anything a cut accepts.
  for (int level = 3; level <= 6; ++level) {
    const Vec3d root_lo(-1.5, -1.5, -1.5), origin(0.1, 0.0, -0.2);
    const test::MemoryNodes nodes = test::accumulate_nodes(sphere, root_lo, 3.0, level, origin);
    double promised = 0, promised_normal = 0;
    for (const auto& [code, node] : nodes.nodes) {
      const Bbox b = nodes.cell_bounds(code);
      const CollapseDeviation d = collapse_deviation(node, Bbox{b.lo - origin, b.hi - origin}, NodeNormals::Faces);
      promised = std::max(promised, d.position);
      promised_normal = std::max(promised_normal, d.normal);
    }
    const Collapsed c = collapse_level(sphere, nodes);
    ASSERT_GT(c.mesh.triangle_count(), 0u);
    double worst = 0;
    for (size_t t = 0; t < c.mesh.triangle_count(); ++t) {
      const Vec3d a(c.mesh.positions[c.mesh.indices[3 * t]]), b(c.mesh.positions[c.mesh.indices[3 * t + 1]]),
          d(c.mesh.positions[c.mesh.indices[3 * t + 2]]);
      for (int i = 0; i <= 4; ++i)
        for (int j = 0; i + j <= 4; ++j) {
          const Vec3d p = a + (b - a) * (i / 4.0) + (d - a) * (j / 4.0);
          worst = std::max(worst, std::abs(glm::length(p - centre) - radius));
        }
    }
    EXPECT_LE(worst, 2.0 * promised + 1e-6) << "level " << level << ": promised " << promised;
    EXPECT_GT(worst, 0.1 * promised) << "level " << level << ": the bound is far from tight";
    for (size_t v = 0; v < c.mesh.positions.size(); ++v) {
      const Vec3d truth = glm::normalize(Vec3d(c.mesh.positions[v]) - centre);
      const double angle = std::acos(std::clamp(glm::dot(truth, Vec3d(c.mesh.normals[v])), -1.0, 1.0));
      // The rep's normal is its cell's mean normal; the rep itself sits
      // within the cell, so the true normal there differs by at most the
      // cell's angular size, sqrt(2 promised_normal) (collapse_deviation.h).
      EXPECT_LE(angle, std::sqrt(2.0 * promised_normal) + 1e-3) << "level " << level << " vertex " << v;
    }
  }
}

// Exact normals without input normals sample the crease rule's corner
// normals over the page's triangles (prepare_collapse), which are right only
// at vertices whose whole fan the page holds. A flat double cone (a closed
// mesh) whose top apex has a cell of its own: with the whole mesh on the
// page the sample is the axis; with half of it (the rest on another page) no
// sample is taken, even when triangles with a repeated corner lie along the
// cut edges (counting their two equal edges once each closed the fan).
TEST(PrepareCollapse, CreaseSamplesComeOnlyFromFansThePageHoldsWhole) {
  const int n = 12;
  auto page_of = [&](int wedges, bool degenerate) {
    PageMesh page;
    page.positions.push_back(Vec3(0, 0, 0.05f));   // top apex, vertex 0
    page.positions.push_back(Vec3(0, 0, -0.05f));  // bottom apex, vertex 1
    for (int i = 0; i < n; ++i)
      page.positions.push_back(Vec3(float(std::cos(2 * M_PI * i / n)), float(std::sin(2 * M_PI * i / n)), 0.0f));
    auto ring = [&](int i) { return uint32_t(2 + i % n); };
    for (int i = 0; i < wedges; ++i) {
      page.index.insert(page.index.end(), {0u, ring(i), ring(i + 1)});
      page.index.insert(page.index.end(), {1u, ring(i + 1), ring(i)});
    }
    if (degenerate) page.index.insert(page.index.end(), {0u, 0u, ring(0), 0u, ring(wedges), 0u});
    return page;
  };
  auto sample = [&](const PageMesh& page) -> std::optional<Vec3> {
    std::vector<uint32_t> cell(page.vertices(), kKeepVertex);
    cell[0] = 0;
    const std::vector<Vec3> rep_pos = {page.positions[0]};
    PreparedBatch out;
    prepare_collapse(page, cell, rep_pos, false, out, true);
    if (out.rep_samples.empty()) return std::nullopt;
    EXPECT_EQ(out.rep_samples.size(), 1u);
    return out.rep_samples[0].normal;
  };
  for (const bool degenerate : {false, true}) {
    const std::optional<Vec3> whole = sample(page_of(n, degenerate));
    ASSERT_TRUE(whole.has_value()) << degenerate;
    EXPECT_NEAR(whole->z, 1.0f, 1e-6f);
    EXPECT_FALSE(sample(page_of(n / 2, degenerate)).has_value()) << degenerate;
  }
}

}  // namespace
}  // namespace raylod
