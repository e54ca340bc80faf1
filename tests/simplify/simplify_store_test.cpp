// End to end through a real octree store: build_store_from_stream, a cut,
// simplify(), and the Draco output of the result.
#include <gtest/gtest.h>
#include <cstdlib>

#include <algorithm>
#include <set>

#include <glm/gtc/matrix_transform.hpp>

#include "core/progress.h"
#include "octree/octree_test_util.h"
#include "one_object_scene.h"
#include "probe/probe.h"
#include "probe/store_tracer.h"
#include "simplify/collapse.h"
#include "simplify/indexed_mesh_writer.h"
#include "simplify/vertex_clustering.h"
#include "streaming/cut_file.h"
#include "streaming/draco_io.h"
#include "test_meshes.h"

namespace raylod {
namespace {

using test::add_tri;

struct BuiltStore {
  std::unique_ptr<OctreeStore> store;
  std::filesystem::path dir;
};

BuiltStore build(const TriangleBatch& soup, const std::string& name, int max_depth = 7) {
  Progress::set_enabled(false);
  auto mesh = std::make_shared<testing::SoupMesh>();
  mesh->positions = soup.positions;
  mesh->normals = soup.normals;
  BuiltStore b;
  b.dir = testing::scratch_dir("simplify-" + name);
  StoreOptions opt;
  opt.max_depth = max_depth;
  opt.page_triangles = 256;  // several pages even for small meshes
  auto report = build_store_from_stream(testing::opener(mesh, 700), testing::fake_source(), b.dir / "s.raylod", opt);
  if (!report.is_ok()) {
    ADD_FAILURE() << report.status().message();
    return b;
  }
  auto store = OctreeStore::open(b.dir / "s.raylod");
  if (!store.is_ok()) {
    ADD_FAILURE() << store.status().message();
    return b;
  }
  b.store = std::move(store).value();
  return b;
}

// The cut the probe selects for the store's mesh as the one object of
// `scene` (an empty cut, after a test failure, if the probe fails).
Cut probed_cut(const BuiltStore& b, const Scene& scene, uint64_t rays, uint64_t seed) {
  const ProbeStore store{b.store.get(), b.dir / "s.raylod"};
  const ProbeObject object{0, glm::dmat4(1.0), 0};
  ProbeConfig c;
  c.rays = rays;
  c.seed = seed;
  auto r = run_probe(scene, std::span(&store, 1), std::span(&object, 1), c);
  EXPECT_TRUE(r.is_ok()) << r.status().message();
  return r.is_ok() ? r->cuts[0] : Cut{};
}

Cut uniform_cut(const OctreeStore& store, int level) {
  Cut cut;
  for (const NodeRecord& n : store.level(level)) cut.cells.push_back({{uint32_t(level), n.code}, 0.01f, 1});
  return cut;
}

// Triangles compared as sorted canonical position triples with a tolerance:
// the store sums quadrics in a different order than the reference, so a
// representative may differ in its last bits.
void expect_meshes_match(const IndexedMesh& a, const IndexedMesh& b, float tol) {
  ASSERT_EQ(a.triangle_count(), b.triangle_count());
  const auto ta = test::canonical_triangles(a), tb = test::canonical_triangles(b);
  size_t bad = 0;
  for (size_t i = 0; i < ta.size(); ++i)
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c)
        if (std::abs(ta[i][k][c] - tb[i][k][c]) > tol) ++bad;
  EXPECT_EQ(bad, 0u);
}

TEST(SimplifyStore, UniformCutEqualsReferenceClustering) {
  // Sphere with normals plus a box without a normal attribute would mix; use
  // two meshes, one each.
  const TriangleBatch sphere = test::uv_sphere({0.3f, 1.2f, -0.4f}, 1.5f, 48, 80);
  const TriangleBatch box = test::closed_box({-1, -0.5f, -2}, {2, 0.5f, 1}, 24);
  for (const TriangleBatch* soup : {&sphere, &box}) {
    BuiltStore b = build(*soup, soup == &sphere ? "sphere" : "box");
    ASSERT_TRUE(b.store);
    const StoreHeader& h = b.store->header();
    ASSERT_GE(h.quadric_depth, 5);
    uint64_t page_triangles = 0;
    for (const PageInfo& p : b.store->pages()) page_triangles += p.triangle_count;
    ASSERT_EQ(page_triangles, soup->size());  // each triangle in exactly one page
    for (int level : {3, 5}) {
      auto result = simplify(*b.store, uniform_cut(*b.store, level));
      ASSERT_TRUE(result.is_ok()) << result.status().message();
      EXPECT_EQ(result->stats.input_triangles, soup->size());
      EXPECT_EQ(result->cut_cells_missing, 0u);
      EXPECT_GT(result->pages_read, 1u);
      // The reference clusters the soup as the store holds it.
      TriangleBatch stored = *soup;
      testing::to_store_precision(stored.positions, stored.normals, h);
      VertexClusteringConfig cfg;
      cfg.root_lo = h.root_lo;
      cfg.root_size = h.root_size;
      cfg.level = level;
      cfg.origin = h.origin;
      const IndexedMesh ref = cluster_vertices(stored, cfg);
      expect_meshes_match(result->mesh, ref, 1e-5f);
    }
  }
}

// What a cut's cells (keys, with their representatives) build from every
// page: the mesh, the cells that turned a triangle over, and the counts.
struct FullBuild {
  IndexedMesh mesh;
  std::vector<uint8_t> folding;
  CollapseStats stats;
};
FullBuild build_from_every_page(const OctreeStore& store, const std::vector<CellKey>& keys,
                                const std::vector<Representative>& reps) {
  const StoreHeader& h = store.header();
  CollapseBuilder builder(reps, h.has_normals);
  const CutLookup lookup(h.root_lo, h.root_size, keys);
  for (size_t i = 0; i < store.pages().size(); ++i) {
    TriangleBatch batch;
    EXPECT_TRUE(store.read_page(i, batch).ok());
    std::vector<uint32_t> cells;
    for (const Vec3& p : batch.positions) cells.push_back(lookup.find(Vec3d(p)));
    builder.add(batch, cells);
  }
  FullBuild out;
  out.folding = builder.folding();
  out.mesh = builder.finish(&out.stats);
  return out;
}

// The fold passes done the plain way: every pass builds the whole mesh from
// every page and refines the cells it saw turn a triangle over; a refinement
// after which the build turns no fewer triangles over is taken back, and the
// passes stop. `undone`, if given, says whether that happened.
IndexedMesh fold_passes_by_full_rebuilds(const OctreeStore& store, const Cut& cut, int passes, bool* undone = nullptr) {
  const StoreHeader& h = store.header();
  std::vector<CellKey> keys;
  std::vector<Representative> reps;
  for (const auto& c : cut.cells) {
    if (const NodeRecord* n = store.find(c.key)) {
      keys.push_back(c.key);
      reps.push_back(make_representative(*n, store.cell_bounds(c.key), h.origin));
    }
  }
  if (undone) *undone = false;
  std::vector<CellKey> last_keys;  // the cut before the last refinement
  std::vector<Representative> last_reps;
  uint64_t last_folded = 0;
  for (int pass = 0;; ++pass) {
    FullBuild built = build_from_every_page(store, keys, reps);
    if (!last_keys.empty() && !(built.stats.folded < last_folded)) {
      if (undone) *undone = true;
      return build_from_every_page(store, last_keys, last_reps).mesh;
    }
    const std::vector<uint8_t>& folding = built.folding;
    if (pass >= passes || std::count(folding.begin(), folding.end(), 1) == 0) return std::move(built.mesh);
    last_keys = keys;
    last_reps = reps;
    last_folded = built.stats.folded;
    std::vector<CellKey> next_keys;
    std::vector<Representative> next_reps;
    for (size_t i = 0; i < keys.size(); ++i) {
      if (!folding[i]) {
        next_keys.push_back(keys[i]);
        next_reps.push_back(reps[i]);
      } else if (keys[i].level < uint32_t(h.quadric_depth)) {
        for (uint64_t c = 0; c < 8; ++c) {
          const CellKey child{keys[i].level + 1, (keys[i].code << 3) | c};
          if (const NodeRecord* n = store.find(child)) {
            next_keys.push_back(child);
            next_reps.push_back(make_representative(*n, store.cell_bounds(child), h.origin));
          }
        }
      }
    }
    keys.swap(next_keys);
    reps.swap(next_reps);
  }
}

// Two concentric spheres 0.06 apart, the inner one facing inwards, positions
// only (as an STL gives them): a thin glass wall.
TriangleBatch thin_glass_wall() {
  TriangleBatch shell = test::uv_sphere({0, 0, 0}, 1.0f, 96, 160);
  const TriangleBatch inner = test::uv_sphere({0, 0, 0}, 0.94f, 96, 160);
  for (size_t t = 0; t < inner.size(); ++t)
    add_tri(shell, inner.positions[3 * t], inner.positions[3 * t + 2], inner.positions[3 * t + 1]);
  shell.normals.clear();
  return shell;
}

// Its level-5 cells above y = 0.3: about as large as the wall is thick.
Cut thin_wall_cut(const OctreeStore& store) {
  const int level = 5;
  Cut cut;
  for (const NodeRecord& n : store.level(level))
    if (store.cell_bounds({uint32_t(level), n.code}).lo.y >= 0.3) cut.cells.push_back({{uint32_t(level), n.code}, 0.05f, 1});
  return cut;
}

// A collapsed cell whose representative lands beyond a thin triangle's other
// corners turns that triangle over; a thin glass wall (two concentric spheres
// 0.06 apart, the inner one facing inwards) collapsed at cells about as large
// as the wall is thick does so. simplify() replaces such cells by their
// children until no triangle faces against its input triangle.
TEST(SimplifyStore, CellsThatTurnTrianglesOverAreRefined) {
  const TriangleBatch shell = thin_glass_wall();
  BuiltStore b = build(shell, "folds");
  ASSERT_TRUE(b.store);
  const Cut cut = thin_wall_cut(*b.store);
  ASSERT_GT(cut.cells.size(), 100u);
  SimplifyConfig as_given;
  as_given.fold_passes = 0;
  auto raw = simplify(*b.store, cut, as_given);
  ASSERT_TRUE(raw.is_ok()) << raw.status().message();
  ASSERT_GT(raw->stats.folded, 0u) << "the case must turn triangles over to test anything";
  EXPECT_EQ(raw->fold_passes, 0u);

  SimplifyConfig refine;
  refine.fold_passes = kSpecularFoldPasses;
  auto fixed = simplify(*b.store, cut, refine);
  ASSERT_TRUE(fixed.is_ok()) << fixed.status().message();
  EXPECT_EQ(fixed->stats.folded, 0u);
  EXPECT_FALSE(fixed->folds_stopped_by_memory);
  EXPECT_GT(fixed->fold_passes, 0u);
  EXPECT_GT(fixed->fold_cells_refined, 0u);
  // The cut as given built from every page, scans of only the pages near
  // the refined cells (before the first refinement, then after each), and
  // the refined cut built again (a page inside one collapsed cell is visited
  // but not read).
  const size_t pages = b.store->pages().size();
  const size_t visits = fixed->pages_read + fixed->pages_skipped;
  ASSERT_GE(visits, 2 * pages);
  EXPECT_GT(visits - 2 * pages, 0u);
  EXPECT_LT(visits - 2 * pages, (fixed->fold_passes + 1) * pages);
  // Refined only where folds were: still fewer triangles than the input.
  EXPECT_LT(fixed->mesh.triangle_count(), shell.size());
  EXPECT_GE(fixed->mesh.triangle_count(), raw->mesh.triangle_count());
  // The same mesh as building the whole mesh in every pass (the reference).
  for (int passes : {1, 2, kSpecularFoldPasses}) {
    SimplifyConfig c;
    c.fold_passes = passes;
    auto got = simplify(*b.store, cut, c);
    ASSERT_TRUE(got.is_ok()) << got.status().message();
    const IndexedMesh want = fold_passes_by_full_rebuilds(*b.store, cut, passes);
    EXPECT_EQ(got->mesh.indices, want.indices) << passes << " passes";
    EXPECT_EQ(got->mesh.positions, want.positions) << passes << " passes";
    EXPECT_EQ(got->mesh.normals, want.normals) << passes << " passes";
  }
}

// Without fold passes (opaque meshes) the triangles the collapse turns over
// are unfolded in place (simplify/unfold.h): representatives slide, or
// edges collapse, within their cells' deviation. The thin wall's folds
// mostly go, and the mesh only loses triangles.
TEST(SimplifyStore, TurnedOverTrianglesAreUnfoldedWithoutRefining) {
  const TriangleBatch shell = thin_glass_wall();
  BuiltStore b = build(shell, "unfold");
  ASSERT_TRUE(b.store);
  const Cut cut = thin_wall_cut(*b.store);
  SimplifyConfig off;
  off.unfold = false;
  auto raw = simplify(*b.store, cut, off);
  ASSERT_TRUE(raw.is_ok()) << raw.status().message();
  ASSERT_GT(raw->stats.folded, 10u) << "the case must turn triangles over to test anything";
  EXPECT_EQ(raw->stats.folded_before_unfold, 0u);
  EXPECT_EQ(raw->stats.unfold_moved + raw->stats.unfold_merged, 0u);
  auto got = simplify(*b.store, cut, SimplifyConfig{});
  ASSERT_TRUE(got.is_ok()) << got.status().message();
  EXPECT_EQ(got->stats.folded, raw->stats.folded);  // counted as built
  EXPECT_GT(got->stats.unfold_moved + got->stats.unfold_merged, 0u);
  EXPECT_GT(got->stats.folded_before_unfold, 10u);
  EXPECT_LT(got->stats.folded_after_unfold * 2, got->stats.folded_before_unfold);
  EXPECT_EQ(got->fold_passes, 0u);
  EXPECT_LE(got->mesh.triangle_count(), raw->mesh.triangle_count());
  // The same bytes at any thread count is the pipeline's test; here: again.
  auto again = simplify(*b.store, cut, SimplifyConfig{});
  ASSERT_TRUE(again.is_ok());
  EXPECT_EQ(again->mesh.indices, got->mesh.indices);
  EXPECT_EQ(again->mesh.positions, got->mesh.positions);
}

// A folding cell at the store's finest level is not collapsed: its input
// triangles stay, and they can turn over against the representatives of
// the cells beside it. Then refining leaves no fewer triangles turned over
// (the 100M teapot: 5,671 before, 11,636 after, for three times the
// triangles), and the refinement is taken back. A thin glass wall built
// four and five levels deep and cut at its finest level: at five the first
// refinement is taken back; at four it removes folds and is kept, and the
// second is taken back.
TEST(SimplifyStore, ARefinementThatLeavesNoFewerFoldsIsTakenBack) {
  TriangleBatch shell = test::uv_sphere({0, 0, 0}, 1.0f, 96, 160);
  const TriangleBatch inner = test::uv_sphere({0, 0, 0}, 0.94f, 96, 160);
  for (size_t t = 0; t < inner.size(); ++t)
    add_tri(shell, inner.positions[3 * t], inner.positions[3 * t + 2], inner.positions[3 * t + 1]);
  shell.normals.clear();
  for (const int depth : {5, 4}) {
    BuiltStore b = build(shell, "folds-undone-" + std::to_string(depth), depth);
    ASSERT_TRUE(b.store);
    ASSERT_EQ(b.store->header().quadric_depth, depth);
    const Cut cut = uniform_cut(*b.store, depth);
    SimplifyConfig as_given;
    auto raw = simplify(*b.store, cut, as_given);
    ASSERT_TRUE(raw.is_ok()) << raw.status().message();
    ASSERT_GT(raw->stats.folded, 0u) << "the case must turn triangles over to test anything";
    SimplifyConfig refine;
    refine.fold_passes = kSpecularFoldPasses;
    auto got = simplify(*b.store, cut, refine);
    ASSERT_TRUE(got.is_ok()) << got.status().message();
    EXPECT_EQ(got->fold_passes_undone, 1u) << "depth " << depth;
    // Never more turned over than the cut as given.
    EXPECT_LE(got->stats.folded, raw->stats.folded) << "depth " << depth;
    if (depth == 5) {
      EXPECT_EQ(got->fold_passes, 0u);
      EXPECT_EQ(got->fold_cells_refined, 0u);
      EXPECT_EQ(got->mesh.indices, raw->mesh.indices);
    } else {
      EXPECT_EQ(got->fold_passes, 1u);
      EXPECT_LT(got->stats.folded, raw->stats.folded);
    }
    bool undone = false;
    const IndexedMesh want = fold_passes_by_full_rebuilds(*b.store, cut, kSpecularFoldPasses, &undone);
    EXPECT_TRUE(undone) << "depth " << depth;
    EXPECT_EQ(got->mesh.indices, want.indices) << "depth " << depth;
    EXPECT_EQ(got->mesh.positions, want.positions) << "depth " << depth;
    EXPECT_EQ(got->mesh.normals, want.normals) << "depth " << depth;
  }
}

// A glass cube turned so that its edges cross the octree's cells: each
// cell on an edge or corner holds it exactly (no deviation), yet the
// triangles joining such a cell to its neighbours cut across the edge
// wherever it does not follow the cells' faces, chamfers and folded flaps
// that refraction shows (found by a bug hunt: 23.78 dB against a 36.02 dB
// floor). On mirrors and glass such cells collapse only while the whole
// cell is within the tolerance: every output vertex stays on the cube and
// every face on one of its planes. A diffuse cube keeps the coarse cut.
TEST(SimplifyStore, AGlassCubeTurnedAgainstTheCellsKeepsItsEdges) {
  const glm::dmat4 turn = glm::rotate(glm::rotate(glm::dmat4(1.0), 0.61, Vec3d(0, 1, 0)), 0.37, Vec3d(1, 0, 0));
  TriangleBatch cube = test::closed_box({-1, -1, -1}, {1, 1, 1}, 30);
  for (Vec3& p : cube.positions) p = Vec3(turn * glm::dvec4(Vec3d(p), 1.0));
  for (Vec3& n : cube.normals) n = Vec3(glm::normalize(Vec3d(turn * glm::dvec4(Vec3d(n), 0.0))));
  BuiltStore b = build(cube, "turned-cube");
  ASSERT_TRUE(b.store);
  auto cut_for = [&](MaterialType type) {
    Scene scene = test::one_object_scene(type, Vec3d(0.5, 2.5, 7.0), Vec3d(0), 160, 120, 35, false, true);
    scene.max_depth = 6;
    return probed_cut(b, scene, 3000, 7);
  };
  const Cut diffuse = cut_for(MaterialType::Diffuse), glass = cut_for(MaterialType::Glass);
  EXPECT_EQ(diffuse.counters.at("cells_kept_for_crease"), 0u);
  EXPECT_GT(glass.counters.at("cells_kept_for_crease"), 0u);
  SimplifyConfig config;
  config.fold_passes = kSpecularFoldPasses;
  auto out = simplify(*b.store, glass, config);
  ASSERT_TRUE(out.is_ok()) << out.status().message();
  const IndexedMesh& mesh = out->mesh;
  ASSERT_GT(mesh.triangle_count(), 0u);
  EXPECT_LT(mesh.triangle_count(), cube.size());  // still simplified
  const glm::dmat4 back = glm::inverse(turn);
  size_t off = 0, tilted = 0;
  for (const Vec3& q : mesh.positions) {
    const Vec3d p = Vec3d(back * glm::dvec4(mesh.origin + Vec3d(q), 1.0));
    off += std::abs(std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}) - 1.0) > 1e-4;
  }
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3d a(mesh.positions[mesh.indices[3 * t]]), b2(mesh.positions[mesh.indices[3 * t + 1]]),
        c(mesh.positions[mesh.indices[3 * t + 2]]);
    const Vec3d n = Vec3d(back * glm::dvec4(face_normal(a, b2, c), 0.0));
    if (glm::length(n) == 0) continue;
    tilted += std::max({std::abs(n.x), std::abs(n.y), std::abs(n.z)}) < 0.999;  // 2.6 degrees
  }
  EXPECT_EQ(off, 0u);
  EXPECT_EQ(tilted, 0u);
}

// A sheet z = a sin(k x + 0.9), wavelength 0.25, over x in [-1, 1] and y in
// [-h, h]: 384 columns of ny rows of two triangles, corners carrying the
// analytic normal when `normals`, none otherwise (as a CAD STL comes).
struct Ripple {
  double a, k = 2 * M_PI / 0.25;
  Vec3d normal_at(double x) const { return glm::normalize(Vec3d(-a * k * std::cos(k * x + 0.9), 0, 1)); }
  TriangleBatch sheet(double h, int ny, bool normals) const {
    TriangleBatch out;
    const int nx = 384;
    auto p = [&](int i, int j) {
      const double x = -1.0 + 2.0 * i / nx, y = -h + 2 * h * j / ny;
      return Vec3(Vec3d(x, y, a * std::sin(k * x + 0.9)));
    };
    auto n = [&](int i) { return Vec3(normal_at(-1.0 + 2.0 * i / nx)); };
    for (int i = 0; i < nx; ++i)
      for (int j = 0; j < ny; ++j) {
        if (normals) {
          test::add_tri_n(out, p(i, j), p(i + 1, j), p(i + 1, j + 1), n(i), n(i + 1), n(i + 1));
          test::add_tri_n(out, p(i, j), p(i + 1, j + 1), p(i, j + 1), n(i), n(i + 1), n(i));
        } else {
          test::add_tri(out, p(i, j), p(i + 1, j), p(i + 1, j + 1));
          test::add_tri(out, p(i, j), p(i + 1, j + 1), p(i, j + 1));
        }
      }
    return out;
  }
};

// Simplifies a ripple's store at cells about a wavelength wide, whose mean
// normal is near +z while the normal at the representative may be anywhere
// in the swing; returns the largest and (through `mean`) the mean angle
// between an output vertex's normal and the analytic one, over vertices
// with |x|, |y| <= inner.
double ripple_normal_error(const Ripple& r, const BuiltStore& b, bool exact, double inner, double* mean) {
  const Cut cut = uniform_cut(*b.store, int(std::round(std::log2(b.store->header().root_size / 0.25))));
  SimplifyConfig config;
  config.exact_normals = exact;
  auto out = simplify(*b.store, cut, config);
  EXPECT_TRUE(out.is_ok()) << out.status().message();
  if (!out.is_ok()) return 10.0;
  const uint64_t sampled = out->stats.representatives_used - out->stats.one_vertex_cells;
  if (!exact) {
    EXPECT_EQ(out->stats.exact_normals, 0u);
  } else if (b.store->header().has_normals) {
    EXPECT_EQ(out->stats.exact_normals, sampled);  // every representative but the cells of one vertex
  } else {
    // Not beside the sheet's rim, whose vertices' fans are open (their
    // corner normals would miss triangles: collapse.cpp, open_fan_vertices).
    EXPECT_GT(out->stats.exact_normals, sampled / 2);
  }
  const IndexedMesh& m = out->mesh;
  double most = 0, sum = 0;
  size_t counted = 0;
  for (size_t v = 0; v < m.positions.size(); ++v) {
    const double x = m.origin.x + m.positions[v].x, y = m.origin.y + m.positions[v].y;
    if (std::abs(x) > inner || std::abs(y) > inner) continue;
    const double e = std::acos(std::min(1.0, glm::dot(Vec3d(m.normals[v]), r.normal_at(x))));
    most = std::max(most, e);
    sum += e;
    ++counted;
  }
  EXPECT_GT(counted, 0u);
  *mean = sum / double(std::max<size_t>(counted, 1));
  return most;
}

// A sheet whose normal swings while its position barely moves (amplitude
// 0.004, slopes up to 0.1 rad): the quadric lets cells a quarter wavelength
// wide collapse, and the mean normal of such a cell is not the normal at
// its representative. Exact normals take the input's normal at the
// representative, which here is the analytic one.
TEST(SimplifyStore, ExactNormalsFollowTheInputAtTheRepresentative) {
  const Ripple r{0.004};
  BuiltStore b = build(r.sheet(0.25, 8, true), "ripple");
  ASSERT_TRUE(b.store);
  double mean_exact = 0, mean_cluster = 0;
  const double exact = ripple_normal_error(r, b, true, 2, &mean_exact);
  const double cluster = ripple_normal_error(r, b, false, 2, &mean_cluster);
  // The input interpolates the analytic normal linearly over triangles
  // 1/192 wide: within 0.005 rad of it.
  EXPECT_LT(exact, 0.005);
  EXPECT_GT(cluster, 0.03);  // the mean normals miss by more (the case this is for)
  EXPECT_LT(mean_exact, 0.25 * mean_cluster);
}

// A ripple without input normals: the full render shades the crease rule's
// corner normals (crease_normals.h), here the mean of the faces around each
// vertex, which exact normals interpolate at the representative's nearest
// input point; the clusters' mean misses as before. Amplitude 0.0006
// (slopes up to 0.015 rad): a crease-rule sample turns a representative's
// normal by at most a degree (collapse.h).
TEST(SimplifyStore, ExactNormalsWithoutInputNormalsFollowTheCreaseRule) {
  const Ripple r{0.0006};
  BuiltStore b = build(r.sheet(1.0, 96, false), "ripple-stl");
  ASSERT_TRUE(b.store);
  ASSERT_FALSE(b.store->header().has_normals);
  double mean_exact = 0, mean_cluster = 0;
  const double exact = ripple_normal_error(r, b, true, 0.7, &mean_exact);  // cells at the rim keep their mean
  const double cluster = ripple_normal_error(r, b, false, 0.7, &mean_cluster);
  // Measured: 0.00037 against 0.0146 rad (means 0.0003 and 0.0074).
  EXPECT_LT(exact, 0.002);
  EXPECT_GT(cluster, 0.01);
  EXPECT_LT(mean_exact, 0.1 * mean_cluster);
}

// Where the clusters' mean misses by more (slopes up to 0.1 rad, as in the
// first ripple), a crease-rule sample turns no corner's normal by more than
// a degree: further off, samples on ABC's abc3.stl shaded single strips of
// its cylinder as streaks (collapse.h).
TEST(SimplifyStore, ACreaseRuleSampleTurnsANormalByAtMostADegree) {
  BuiltStore b = build(Ripple{0.004}.sheet(1.0, 96, false), "ripple-stl-steep");
  ASSERT_TRUE(b.store);
  const Cut cut = uniform_cut(*b.store, int(std::round(std::log2(b.store->header().root_size / 0.25))));
  SimplifyConfig plain, exact;
  exact.exact_normals = true;
  auto without = simplify(*b.store, cut, plain), with = simplify(*b.store, cut, exact);
  ASSERT_TRUE(without.is_ok() && with.is_ok());
  EXPECT_GT(with->stats.exact_normals, 0u);
  ASSERT_EQ(without->mesh.indices.size(), with->mesh.indices.size());
  double most = 0;
  for (size_t i = 0; i < with->mesh.indices.size(); ++i) {
    const Vec3d n0(without->mesh.normals[without->mesh.indices[i]]), n1(with->mesh.normals[with->mesh.indices[i]]);
    most = std::max(most, std::acos(std::clamp(glm::dot(n0, n1), -1.0, 1.0)));
  }
  EXPECT_GT(most, 0.0);
  EXPECT_LE(most, M_PI / 180.0 + 1e-4);
}

// A closed box, 12 x 12 quads a side, each corner carrying its face's normal.
TriangleBatch faceted_box() {
  TriangleBatch box = test::closed_box({-1, -1, -1}, {1, 1, 1}, 12);
  for (size_t t = 0; t < box.size(); ++t) {
    const Vec3 f(face_normal(Vec3d(box.positions[3 * t]), Vec3d(box.positions[3 * t + 1]),
                             Vec3d(box.positions[3 * t + 2])));
    box.normals.insert(box.normals.end(), {f, f, f});
  }
  return box;
}

// Across a crease the nearest input point lies on one side: only the corners
// of that side take its normal, and every face of a box keeps its own, with
// its faces' normals as input and without (then the crease rule's corner
// normals are the faces' own: 90 degrees is beyond the crease angle).
TEST(SimplifyStore, ExactNormalsKeepCreasesSplit) {
  for (const bool normals : {true, false}) {
    BuiltStore b = build(normals ? faceted_box() : test::closed_box({-1, -1, -1}, {1, 1, 1}, 12),
                         normals ? "exact-box" : "exact-box-stl");
    ASSERT_TRUE(b.store);
    ASSERT_EQ(b.store->header().has_normals, normals);
    SimplifyConfig config;
    config.exact_normals = true;
    auto out = simplify(*b.store, uniform_cut(*b.store, 4), config);
    ASSERT_TRUE(out.is_ok()) << out.status().message();
    EXPECT_GT(out->stats.exact_normals, 0u);
    const IndexedMesh& m = out->mesh;
    ASSERT_GT(m.triangle_count(), 0u);
    size_t off_face = 0;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const Vec3d f = face_normal(Vec3d(m.positions[m.indices[3 * t]]), Vec3d(m.positions[m.indices[3 * t + 1]]),
                                  Vec3d(m.positions[m.indices[3 * t + 2]]));
      for (int k = 0; k < 3; ++k) off_face += glm::dot(Vec3d(m.normals[m.indices[3 * t + k]]), f) < 1 - 1e-6;
    }
    EXPECT_EQ(off_face, 0u) << (normals ? "with" : "without") << " input normals";
  }
}

// A mesh with normals of its own renders with them whatever the crease
// angle (the full render ignores it), so the simplified mesh does too: a
// faceted box at 180 degrees keeps its faces' normals as at the default.
TEST(SimplifyStore, TheCreaseAngleLeavesMeshesWithNormalsAlone) {
  const TriangleBatch box = faceted_box();
  BuiltStore b = build(box, "crease-box");
  ASSERT_TRUE(b.store);
  const Cut cut = uniform_cut(*b.store, 4);
  SimplifyConfig at_default, at_180;
  at_180.crease_angle_deg = 180;
  auto a = simplify(*b.store, cut, at_default);
  auto c = simplify(*b.store, cut, at_180);
  ASSERT_TRUE(a.is_ok() && c.is_ok());
  EXPECT_EQ(a->mesh.positions, c->mesh.positions);
  EXPECT_EQ(a->mesh.normals, c->mesh.normals);
  EXPECT_EQ(a->mesh.indices, c->mesh.indices);
}

TEST(SimplifyStore, PagesInsideOneCollapsedCellAreNotReadAndChangeNothing) {
  // A cut coarser than the pages: many pages lie wholly inside one collapsed
  // cell and are not read, and the mesh is the one built from every page.
  // Positions only (as an STL gives them): with input normals the reference,
  // which adds every corner on its own, rounds the clusters' float sums in
  // another order.
  TriangleBatch sphere = test::uv_sphere({0.1f, 0.2f, -0.3f}, 1.5f, 128, 192);
  sphere.normals.clear();
  BuiltStore b = build(sphere, "inside-one-cell");
  ASSERT_TRUE(b.store);
  const StoreHeader& h = b.store->header();
  ASSERT_GE(h.page_level, 2);
  for (int level : {1, h.page_level - 1, h.page_level}) {
    const Cut cut = uniform_cut(*b.store, level);
    for (int passes : {0, kSpecularFoldPasses}) {
      SimplifyConfig c;
      c.fold_passes = passes;
      auto got = simplify(*b.store, cut, c);
      ASSERT_TRUE(got.is_ok()) << got.status().message();
      if (level < h.page_level) {
        EXPECT_GT(got->pages_skipped, 0u) << "level " << level;
      }
      EXPECT_EQ(got->stats.input_triangles, sphere.size());
      const IndexedMesh want = fold_passes_by_full_rebuilds(*b.store, cut, passes);
      EXPECT_EQ(got->mesh.indices, want.indices) << "level " << level << ", " << passes << " passes";
      EXPECT_EQ(got->mesh.positions, want.positions) << "level " << level << ", " << passes << " passes";
      EXPECT_EQ(got->mesh.normals, want.normals) << "level " << level << ", " << passes << " passes";
    }
  }
}

TEST(SimplifyStore, FoldRefinementStopsAtTheMemoryLimit) {
  // Refining keeps more triangles than the cut's estimate: with a limit the
  // cut just fits, the refinement is left out (folds stay, reported) rather
  // than the building pass failing at the limit part way.
  BuiltStore b = build(thin_glass_wall(), "fold-limit");
  ASSERT_TRUE(b.store);
  const Cut cut = thin_wall_cut(*b.store);
  SimplifyConfig as_given;
  auto raw = simplify(*b.store, cut, as_given);
  ASSERT_TRUE(raw.is_ok()) << raw.status().message();
  ASSERT_GT(raw->stats.folded, 0u);

  SimplifyConfig tight;
  tight.fold_passes = kSpecularFoldPasses;
  // The cut's own estimate: it fits, any refinement does not. (The building
  // pass checks memory_limit against what it really holds; at this small
  // size that is more than the estimate, so the fold limit is given apart.)
  tight.fold_memory_limit = estimate_simplify(*b.store, cut).bytes;
  auto got = simplify(*b.store, cut, tight);
  ASSERT_TRUE(got.is_ok()) << got.status().message();
  EXPECT_TRUE(got->folds_stopped_by_memory);
  EXPECT_EQ(got->fold_passes, 0u);
  EXPECT_EQ(got->fold_cells_refined, 0u);
  EXPECT_EQ(got->stats.folded, raw->stats.folded);
  EXPECT_EQ(got->mesh.indices, raw->mesh.indices);
  EXPECT_EQ(got->mesh.positions, raw->mesh.positions);
}

TEST(SimplifyStore, MixedCutKeepsOtherTrianglesExactly) {
  const TriangleBatch sphere = test::uv_sphere({0, 0, 0}, 1.0f, 40, 64);
  BuiltStore b = build(sphere, "mixed");
  ASSERT_TRUE(b.store);
  // Collapse the level-4 cells in the upper half (y > 0.2) only.
  Cut cut;
  for (const NodeRecord& n : b.store->level(4)) {
    const Bbox box = b.store->cell_bounds({4, n.code});
    if (box.lo.y > 0.2) cut.cells.push_back({{4, n.code}, 0.05f, 3});
  }
  cut.cells.push_back({{4, 0x7fff}, 0.05f, 0});  // a cell the store does not have
  ASSERT_GT(cut.cells.size(), 5u);
  auto result = simplify(*b.store, cut);
  ASSERT_TRUE(result.is_ok()) << result.status().message();
  EXPECT_EQ(result->cut_cells_missing, 1u);
  EXPECT_LT(result->mesh.triangle_count(), sphere.size());
  // Every input triangle entirely below y = 0.2 is in the output unchanged
  // (as the store holds it).
  std::set<test::PosTri> out;
  for (const auto& t : test::canonical_triangles(result->mesh)) out.insert(t);
  TriangleBatch stored = sphere;
  testing::to_store_precision(stored.positions, stored.normals, b.store->header());
  IndexedMesh below;
  for (size_t t = 0; t < stored.size(); ++t) {
    bool low = true;
    for (int k = 0; k < 3; ++k) low &= stored.positions[3 * t + k].y < 0.2f - 1e-3f;
    if (!low) continue;
    for (int k = 0; k < 3; ++k) {
      below.indices.push_back(uint32_t(below.positions.size()));
      below.positions.push_back(stored.positions[3 * t + k]);
    }
  }
  ASSERT_GT(below.triangle_count(), 100u);
  for (const auto& t : test::canonical_triangles(below)) EXPECT_TRUE(out.count(t));
  // Representatives lie inside their cells; kept vertices keep their normals.
  for (const auto& c : cut.cells) {
    const NodeRecord* n = b.store->find(c.key);
    if (!n) continue;
    const Representative r = make_representative(*n, b.store->cell_bounds(c.key), b.store->header().origin);
    EXPECT_TRUE(test::inside(r.position, b.store->cell_bounds(c.key)));
  }
  // The simplified sphere is still closed.
  size_t unpaired = 0;
  EXPECT_TRUE(test::edges_paired(result->mesh, &unpaired)) << unpaired;

  // And its Draco round trip keeps the triangle count.
  const auto drc = b.dir / "mixed.drc";
  DracoOptions opt;
  opt.max_position_error = 0.05 / 8;
  auto w = write_draco(drc, result->mesh, opt);
  ASSERT_TRUE(w.is_ok()) << w.status().message();
  EXPECT_LE(w->max_position_error, opt.max_position_error);
  auto back = read_draco(drc);
  ASSERT_TRUE(back.is_ok());
  EXPECT_EQ(back->triangle_count(), result->mesh.triangle_count());
  // PLY and OBJ outputs exist and the PLY size is as computed.
  ASSERT_TRUE(write_indexed_ply(b.dir / "mixed.ply", result->mesh).is_ok());
  EXPECT_EQ(std::filesystem::file_size(b.dir / "mixed.ply"), indexed_ply_bytes(result->mesh));
  ASSERT_TRUE(write_indexed_obj(b.dir / "mixed.obj", result->mesh).is_ok());
  auto obj = open_mesh(b.dir / "mixed.obj");
  ASSERT_TRUE(obj.is_ok()) << obj.status().message();
  TriangleBatch batch;
  uint64_t obj_tris = 0;
  while (true) {
    auto more = (*obj)->next(batch);
    ASSERT_TRUE(more.is_ok()) << more.status().message();
    if (!*more) break;
    obj_tris += batch.size();
  }
  EXPECT_EQ(obj_tris, result->mesh.triangle_count());
}

TEST(SimplifyStore, MemoryLimitRefusesBeforeWork) {
  const TriangleBatch sphere = test::uv_sphere({0, 0, 0}, 1.0f, 20, 32);
  BuiltStore b = build(sphere, "limit");
  ASSERT_TRUE(b.store);
  SimplifyConfig cfg;
  cfg.memory_limit = 1000;  // bytes
  auto result = simplify(*b.store, uniform_cut(*b.store, 6), cfg);
  ASSERT_FALSE(result.is_ok());
  EXPECT_NE(result.status().message().find("memory limit"), std::string::npos) << result.status().message();
  // The estimate is close to the real output (here within 25% on a coarse cut).
  const Cut cut = uniform_cut(*b.store, 3);
  const SimplifyEstimate e = estimate_simplify(*b.store, cut);
  auto ok = simplify(*b.store, cut);
  ASSERT_TRUE(ok.is_ok());
  EXPECT_NEAR(double(e.triangles), double(ok->stats.output_triangles), 0.25 * double(ok->stats.output_triangles));
}

// Open boundaries (streaming/open_edges.h): a closed box built over many
// pages has none (its edges that cross pages are matched across them); a
// plate with a square hole has exactly the leaves of its two rims flagged.
TEST(SimplifyStore, OpenBoundaryLeavesAreTheRimsExactly) {
  BuiltStore box = build(test::closed_box({-1, -0.5f, -2}, {2, 0.5f, 1}, 24), "closed-box");
  ASSERT_TRUE(box.store);
  ASSERT_GT(box.store->pages().size(), 4u);
  EXPECT_EQ(box.store->boundary_leaves(), 0u);

  // A 32 x 32 plate of unit quads with the middle 8 x 8 missing.
  TriangleBatch plate;
  std::vector<Vec3> rim;
  const int n = 32;
  auto at = [](int i, int j) { return Vec3(float(i) / 8, 0.25f, float(j) / 8); };
  auto hole = [&](int i, int j) { return i >= 12 && i < 20 && j >= 12 && j < 20; };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      if (hole(i, j)) continue;
      add_tri(plate, at(i, j), at(i, j + 1), at(i + 1, j + 1));
      add_tri(plate, at(i, j), at(i + 1, j + 1), at(i + 1, j));
    }
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      const bool outer = i == 0 || j == 0 || i == n || j == n;
      const bool inner = i >= 12 && i <= 20 && j >= 12 && j <= 20 && (i == 12 || i == 20 || j == 12 || j == 20);
      if (outer || inner) rim.push_back(at(i, j));
    }
  BuiltStore b = build(plate, "plate-with-hole");
  ASSERT_TRUE(b.store);
  ASSERT_GE(b.store->pages().size(), 4u);  // the hole's rim crosses pages
  const int q = b.store->header().quadric_depth;
  std::set<uint64_t> rim_cells;
  for (const Vec3& p : rim) rim_cells.insert(b.store->cell_of(Vec3d(p), q).code);
  EXPECT_EQ(b.store->boundary_leaves(), rim_cells.size());
  size_t interior = 0;
  for (const NodeRecord& leaf : b.store->level(q)) {
    const bool flagged = b.store->touches_boundary({uint32_t(q), leaf.code});
    EXPECT_EQ(flagged, rim_cells.count(leaf.code) == 1) << "leaf " << leaf.code;
    interior += !flagged;
  }
  EXPECT_GT(interior, 0u);
  // A parent touches the boundary exactly when one of its leaves does.
  for (int level = 0; level < q; ++level)
    for (const NodeRecord& node : b.store->level(level)) {
      bool any = false;
      for (uint64_t c : rim_cells) any = any || (c >> (3 * (q - level))) == node.code;
      EXPECT_EQ(b.store->touches_boundary({uint32_t(level), node.code}), any) << "level " << level;
    }
}

// Past the cap on open edges pending a match (the memory limit's share, at
// least 64k), the build stops matching and flags later open edges as they
// come: more leaves flagged, never a rim missed. A soup of 30,000 separate
// triangles has 90,000 open edges, every vertex on a rim.
TEST(SimplifyStore, PastTheOpenEdgeCapEveryRimLeafIsStillFlagged) {
  Progress::set_enabled(false);
  auto mesh = std::make_shared<testing::SoupMesh>();
  for (int i = 0; i < 30000; ++i) {
    const Vec3 o(float(i % 31) * 0.03f, float((i / 31) % 31) * 0.03f, float(i / 961) * 0.03f);
    const Vec3 tri[3] = {o, o + Vec3(0.01f, 0, 0), o + Vec3(0, 0.01f, 0.005f)};
    mesh->positions.insert(mesh->positions.end(), tri, tri + 3);
  }
  const std::filesystem::path dir = testing::scratch_dir("simplify-soup-cap");
  StoreOptions opt;
  opt.max_depth = 7;
  opt.page_triangles = 256;
  opt.memory_limit = 64 << 20;  // a cap of 64k pending edges
  auto report = build_store_from_stream(testing::opener(mesh, 700), testing::fake_source(), dir / "s.raylod", opt);
  ASSERT_TRUE(report.is_ok()) << report.status().message();
  EXPECT_TRUE(report->open_edges_capped);
  EXPECT_GE(report->open_edges, 90000u);
  auto store = OctreeStore::open(dir / "s.raylod");
  ASSERT_TRUE(store.is_ok()) << store.status().message();
  const int q = (*store)->header().quadric_depth;
  std::set<uint64_t> cells;
  for (const Vec3& p : mesh->positions) cells.insert((*store)->cell_of(Vec3d(p), q).code);
  EXPECT_EQ((*store)->boundary_leaves(), cells.size());
  for (uint64_t c : cells) EXPECT_TRUE((*store)->touches_boundary({uint32_t(q), c}));
}


// A bottle's body as OpenCASCADE tessellates it (facets only, as a CAD STL):
// a cylinder wall of long strips, each one triangle pair from the bottom to
// the top, a fillet of 8 rows rounding the top into a flat cap, and a sharp
// edge at the bottom. A close-up sees only the middle of the wall, so every
// strip it sees ends in cells off the view, and the cell at the top end
// holds the fillet too: collapsed, the strip's corner there takes the mean
// normal of the cell's faces, tilted towards the fillet, and the whole
// visible strip is shaded by it (the OpenCASCADE bottle's close-up, 11.6 dB
// below its noise floor). The cut keeps such cells for the far-end normal
// (collapse_deviation.h, far_normal): the visible wall's normals match the
// input's, interpolated from the same corners, where the cut leaves it.
TEST(SimplifyStore, LongStripsKeepTheNormalsAtTheirFarEnds) {
  constexpr int kColumns = 96, kRows = 8;
  constexpr double kRadius = 1, kFillet = 0.25, kBottom = -1.75, kTop = 1.5;
  TriangleBatch body;
  auto tri = [&](const Vec3d& a, const Vec3d& b, const Vec3d& c) {
    // Outwards from the axis (the body is convex around it).
    const Vec3d centre = (a + b + c) / 3.0;
    const bool out = glm::dot(glm::cross(b - a, c - a), centre - Vec3d(0, centre.y * 0.5, 0)) > 0;
    add_tri(body, Vec3(a), Vec3(out ? b : c), Vec3(out ? c : b));
  };
  auto ring = [&](int column, double radius, double y) {
    const double phi = 2 * M_PI * column / kColumns;
    return Vec3d(radius * std::sin(phi), y, radius * std::cos(phi));
  };
  auto fillet = [&](int column, int row) {
    const double a = 0.5 * M_PI * row / kRows;
    return ring(column, kRadius - kFillet + kFillet * std::cos(a), kTop + kFillet * std::sin(a));
  };
  const Vec3d top_centre(0, kTop + kFillet, 0), bottom_centre(0, kBottom, 0);
  for (int c = 0; c < kColumns; ++c) {
    const int d = c + 1;
    tri(ring(c, kRadius, kBottom), ring(d, kRadius, kBottom), ring(d, kRadius, kTop));
    tri(ring(c, kRadius, kBottom), ring(d, kRadius, kTop), ring(c, kRadius, kTop));
    for (int r = 0; r < kRows; ++r) {
      tri(fillet(c, r), fillet(d, r), fillet(d, r + 1));
      tri(fillet(c, r), fillet(d, r + 1), fillet(c, r + 1));
    }
    tri(fillet(c, kRows), fillet(d, kRows), top_centre);
    tri(ring(c, kRadius, kBottom), bottom_centre, ring(d, kRadius, kBottom));
  }
  BuiltStore b = build(body, "long-strips");
  ASSERT_TRUE(b.store);
  ASSERT_FALSE(b.store->header().has_normals);
  Scene scene = test::one_object_scene(MaterialType::Diffuse, Vec3d(0, 0, 2.4), Vec3d(0, 0, 0), 200, 150, 28, false,
                                       true);
  const Cut cut = probed_cut(b, scene, 4000, 3);
  ASSERT_FALSE(cut.cells.empty());
  EXPECT_GT(cut.counters.at("cells_kept_for_far_normal"), 0u);
  auto simplified = simplify(*b.store, cut, SimplifyConfig{});
  ASSERT_TRUE(simplified.is_ok()) << simplified.status().message();
  const IndexedMesh& mesh = simplified->mesh;
  EXPECT_LT(mesh.triangle_count(), body.size());  // still simplified
  // The input with its crease normals, as the full render shades it.
  auto whole = simplify(*b.store, Cut{}, SimplifyConfig{});
  ASSERT_TRUE(whole.is_ok()) << whole.status().message();
  ASSERT_EQ(whole->mesh.triangle_count(), body.size());
  // The interpolated normal where a ray out from the axis at height y meets
  // the wall.
  auto normal_at = [](const IndexedMesh& m, double phi, double y) {
    const Vec3d o = Vec3d(0, y, 0) - m.origin, dir(std::sin(phi), 0, std::cos(phi));
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const uint32_t* v = &m.indices[3 * t];
      double hit = 0, b1 = 0, b2 = 0;
      if (!intersect_triangle(o, dir, Vec3d(m.positions[v[0]]), Vec3d(m.positions[v[1]]), Vec3d(m.positions[v[2]]), 0.5,
                              1.5, hit, b1, b2))
        continue;
      return glm::normalize((1 - b1 - b2) * Vec3d(m.normals[v[0]]) + b1 * Vec3d(m.normals[v[1]]) +
                            b2 * Vec3d(m.normals[v[2]]));
    }
    return Vec3d(0);
  };
  double worst = 0;
  size_t samples = 0;
  for (double phi = -0.2; phi <= 0.2; phi += 0.01)
    for (double y = -0.2; y <= 0.2; y += 0.05) {
      const Vec3d want = normal_at(whole->mesh, phi, y), got = normal_at(mesh, phi, y);
      ASSERT_GT(glm::length(want), 0.5) << phi << " " << y;
      ASSERT_GT(glm::length(got), 0.5) << phi << " " << y;
      worst = std::max(worst, std::acos(std::min(1.0, glm::dot(want, got))));
      ++samples;
    }
  EXPECT_GT(samples, 300u);
  EXPECT_LT(worst, 2e-3) << "radians between the input's and the simplified wall's normals in view";
}

}  // namespace
}  // namespace raylod
