// Draco round trips: same triangle count, positions within the reported
// quantisation bound, normals within the reported angle bound.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <set>

#include <tbb/global_control.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include "core/system.h"
#include "draco_hostile.h"
#include "simplify/collapse.h"
#include "streaming/draco_io.h"
#include "test_meshes.h"
#include "test_tmp.h"

namespace raylod {
namespace {

std::filesystem::path tmp_dir() {
  return test::scratch_dir("simplify");
}

IndexedMesh indexed(const TriangleBatch& soup) {
  CollapseBuilder b({}, !soup.normals.empty());
  b.add(soup, std::vector<uint32_t>(soup.positions.size(), kKeepVertex));
  return b.finish();
}

// Every input triangle matches a distinct decoded triangle (some rotation,
// same orientation) with all corners within `tol`; brute force.
void expect_same_triangles(const IndexedMesh& in, const IndexedMesh& out, double tol, double normal_tol) {
  ASSERT_EQ(in.triangle_count(), out.triangle_count());
  std::vector<bool> used(out.triangle_count(), false);
  double worst = 0, worst_normal = 0;
  for (size_t t = 0; t < in.triangle_count(); ++t) {
    bool found = false;
    for (size_t s = 0; s < out.triangle_count() && !found; ++s) {
      if (used[s]) continue;
      for (int rot = 0; rot < 3 && !found; ++rot) {
        double err = 0, nerr = 0;
        for (int k = 0; k < 3; ++k) {
          const uint32_t a = in.indices[3 * t + k], b = out.indices[3 * s + (k + rot) % 3];
          err = std::max(err, glm::distance(Vec3d(in.positions[a]), Vec3d(out.positions[b])));
          if (!in.normals.empty())
            nerr = std::max(nerr, std::acos(std::clamp(double(glm::dot(in.normals[a], out.normals[b])), -1.0, 1.0)));
        }
        if (err <= tol) {
          found = used[s] = true;
          worst = std::max(worst, err);
          worst_normal = std::max(worst_normal, nerr);
        }
      }
    }
    ASSERT_TRUE(found) << "input triangle " << t << " has no decoded match within " << tol;
  }
  EXPECT_LE(worst, tol);
  EXPECT_LE(worst_normal, normal_tol);
}

TEST(DracoIo, ChoosesBitsFromTheRequestedError) {
  EXPECT_EQ(choose_position_bits(1.0, 1.0, 1.0), 1);
  const int b = choose_position_bits(100.0, 100.0, 1e-3);
  EXPECT_LE(position_error_bound(100.0, 100.0, b), 1e-3);
  EXPECT_GT(position_error_bound(100.0, 100.0, b - 1), 1e-3);  // the smallest that works
  // Unreachable (float rounding of 1e6 dominates): not 30 bits, which only
  // costs encoder memory, but the fewest within 10% of the best bound.
  const int u = choose_position_bits(1.0, 1e6, 1e-12);
  EXPECT_LT(u, 30);
  EXPECT_LE(position_error_bound(1.0, 1e6, u), 1.1 * position_error_bound(1.0, 1e6, 30));
  EXPECT_GT(position_error_bound(1.0, 1e6, u - 1), 1.1 * position_error_bound(1.0, 1e6, 30));
}

TEST(DracoIo, RoundTripSphereWithinTheStatedErrors) {
  const IndexedMesh mesh = indexed(test::uv_sphere({10, -3, 2}, 2.0f, 24, 32));
  const auto path = tmp_dir() / "sphere.drc";
  // Both speeds the pipeline uses (draco_speed_for) keep the stated bounds.
  EXPECT_EQ(draco_speed_for(kFastDracoFromTriangles - 1), 5);
  EXPECT_EQ(draco_speed_for(kFastDracoFromTriangles), 6);
  for (auto [want, speed] : {std::pair{1e-2, 5}, {1e-4, 5}, {1e-2, 6}, {1e-4, 6}}) {
    DracoOptions opt;
    opt.max_position_error = want;
    opt.speed = speed;
    auto rep = write_draco(path, mesh, opt);
    ASSERT_TRUE(rep.is_ok()) << rep.status().message();
    EXPECT_LE(rep->max_position_error, want);
    EXPECT_GT(rep->position_bits, 0);
    EXPECT_EQ(rep->bytes, std::filesystem::file_size(path));
    auto back = read_draco(path);
    ASSERT_TRUE(back.is_ok()) << back.status().message();
    ASSERT_EQ(back->normals.size(), back->positions.size());
    expect_same_triangles(mesh, *back, rep->max_position_error, rep->max_normal_error);
  }
}

// A mesh read from a float file keeps its coordinates (origin 0): a sphere
// of radius 1 at x = 1e7 has x on a 1.0 grid (the file's own rounding) and
// y, z to 1e-7. Draco's one grid over all axes was sized by x's rounding (4
// bits, positions 2.18 off, found by a bug hunt); encoded relative to a
// local origin it keeps every coordinate the file held, within the bound.
TEST(DracoIo, AFloatMeshFarFromZeroKeepsItsPrecision) {
  const IndexedMesh mesh = indexed(test::uv_sphere({1e7, 0.5, -0.25}, 1.0f, 24, 32));
  ASSERT_EQ(mesh.origin, Vec3d(0));
  for (int parts : {1, 3}) {
    DracoOptions opt;
    opt.max_position_error = 1e-5;
    opt.parts = parts;
    const auto path = tmp_dir() / ("far" + std::to_string(parts) + ".drc");
    auto rep = write_draco(path, mesh, opt);
    ASSERT_TRUE(rep.is_ok()) << rep.status().message();
    EXPECT_LE(rep->max_position_error, 1e-5);
    auto back = read_draco(path);
    ASSERT_TRUE(back.is_ok()) << back.status().message();
    ASSERT_EQ(back->triangle_count(), mesh.triangle_count());
    // Every decoded corner lies within the bound of an input vertex (world
    // coordinates: the decoded mesh has its own origin).
    std::vector<Vec3d> input;
    for (const Vec3& p : mesh.positions) input.push_back(mesh.origin + Vec3d(p));
    double worst = 0;
    for (const Vec3& q : back->positions) {
      const Vec3d w = back->origin + Vec3d(q);
      double nearest = std::numeric_limits<double>::infinity();
      for (const Vec3d& p : input) nearest = std::min(nearest, glm::distance(p, w));
      worst = std::max(worst, nearest);
    }
    EXPECT_LE(worst, rep->max_position_error) << parts << " parts";
  }
}

// The reference encoding: the mesh handed to Draco one point per vertex,
// deduplicated by Draco's own DeduplicateAttributeValues and
// DeduplicatePointIds, encoded with the settings encode_draco chose.
std::vector<char> encode_with_dracos_deduplication(const IndexedMesh& mesh, const DracoWriteReport& report) {
  draco::Mesh dm;
  const uint32_t n = uint32_t(mesh.positions.size());
  dm.set_num_points(n);
  auto add = [&](draco::GeometryAttribute::Type type, const std::vector<Vec3>& values) {
    draco::GeometryAttribute att;
    att.Init(type, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
    const int id = dm.AddAttribute(att, true, n);
    for (uint32_t i = 0; i < n; ++i) dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(i), &values[i].x);
  };
  add(draco::GeometryAttribute::POSITION, mesh.positions);
  if (!mesh.normals.empty()) add(draco::GeometryAttribute::NORMAL, mesh.normals);
  dm.SetNumFaces(mesh.triangle_count());
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    draco::Mesh::Face f;
    for (int k = 0; k < 3; ++k) f[k] = draco::PointIndex(mesh.indices[3 * t + k]);
    dm.SetFace(draco::FaceIndex(uint32_t(t)), f);
  }
  dm.DeduplicateAttributeValues();
  dm.DeduplicatePointIds();
  auto metadata = std::make_unique<draco::GeometryMetadata>();  // as write_draco adds
  metadata->AddEntryDouble("raylod_triangles", double(dm.num_faces()));
  dm.AddMetadata(std::move(metadata));
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, report.position_bits);
  if (!mesh.normals.empty()) encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, report.normal_bits);
  encoder.SetSpeedOptions(5, 5);
  draco::EncoderBuffer buffer;
  EXPECT_TRUE(encoder.EncodeMeshToBuffer(dm, &buffer).ok());
  return std::vector<char>(buffer.data(), buffer.data() + buffer.size());
}

TEST(DracoIo, DeduplicatesAsDracoDoes) {
  // Split normals at the box's edges (positions repeat with other normals),
  // exact repeats of whole vertices, a -0 beside a +0, and a mesh without
  // normals: the bytes match Draco's own deduplication.
  IndexedMesh box = indexed(test::closed_box({-1, 0, -0.5f}, {1, 0.5f, 0.5f}, 5));
  ASSERT_GT(box.positions.size(), 0u);
  std::mt19937 rng(7);
  const size_t triangles = box.triangle_count();
  for (int r = 0; r < 40; ++r) {  // reverse twins of random triangles, on copies of their vertices
    const uint32_t* f = &box.indices[3 * (rng() % triangles)];
    const uint32_t a = f[0], b = f[2], c = f[1];
    for (uint32_t v : {a, b, c}) {
      box.indices.push_back(uint32_t(box.positions.size()));
      box.positions.push_back(box.positions[v]);
      box.normals.push_back(box.normals[v]);
    }
  }
  box.positions.push_back(Vec3(-0.0f, 0.25f, 0.5f));
  box.normals.push_back(Vec3(0, 0, 1));
  box.positions.push_back(Vec3(0.0f, 0.25f, 0.5f));
  box.normals.push_back(Vec3(0, 0, 1));
  box.positions.push_back(Vec3(0.5f, 0.5f, 0.5f));
  box.normals.push_back(Vec3(0, 0, 1));
  box.positions.push_back(Vec3(0.5f, 0.25f, 0.5f));
  box.normals.push_back(Vec3(0, 0, 1));
  const uint32_t p = uint32_t(box.positions.size()) - 4;  // -0, +0, then two more corners
  for (uint32_t v : {p, p + 3, p + 2, p + 1, p + 2, p + 3}) box.indices.push_back(v);
  IndexedMesh bare = box;
  bare.normals.clear();
  for (const IndexedMesh* m : {&box, &bare}) {
    DracoOptions opt;
    opt.max_position_error = 1e-4;
    auto got = encode_draco("dedup.drc", *m, opt);
    ASSERT_TRUE(got.is_ok()) << got.status().message();
    EXPECT_EQ(got->bytes, encode_with_dracos_deduplication(*m, got->report)) << (m == &box ? "with" : "without")
                                                                             << " normals";
    IndexedMesh handed = *m;  // handed over: the same bytes, and its arrays freed
    auto moved = encode_draco("dedup.drc", std::move(handed), opt);
    ASSERT_TRUE(moved.is_ok()) << moved.status().message();
    EXPECT_EQ(moved->bytes, got->bytes);
    EXPECT_EQ(handed.positions.capacity() + handed.normals.capacity() + handed.indices.capacity(), 0u);
  }
}

TEST(DracoIo, TriangleCountFromTheHeader) {
  // raylod's files carry the count in their metadata; a file Draco wrote
  // without it is decoded to count; a damaged one is an error naming it.
  const IndexedMesh mesh = indexed(test::uv_sphere({1e6, 0, 0}, 2.0f, 12, 16));
  const auto ours = tmp_dir() / "counted.drc";
  DracoOptions opt;
  opt.max_position_error = 1e-3;
  auto rep = write_draco(ours, mesh, opt);
  ASSERT_TRUE(rep.is_ok()) << rep.status().message();
  auto n = draco_triangle_count(ours);
  ASSERT_TRUE(n.is_ok()) << n.status().message();
  EXPECT_EQ(*n, read_draco(ours)->triangle_count());
  EXPECT_EQ(*n, mesh.triangle_count());
  {  // from the header alone: the first 160 bytes hold it, and cannot be decoded
    std::ifstream in(ours, std::ios::binary);
    std::vector<char> head(160);
    in.read(head.data(), std::streamsize(head.size()));
    const auto cut = tmp_dir() / "head.drc";
    std::ofstream(cut, std::ios::binary).write(head.data(), std::streamsize(head.size()));
    EXPECT_FALSE(read_draco(cut).is_ok());
    auto h = draco_triangle_count(cut);
    ASSERT_TRUE(h.is_ok()) << h.status().message();
    EXPECT_EQ(*h, mesh.triangle_count());
  }

  // The reference encoder adds the entry too; strip it by encoding plainly.
  draco::Mesh dm;
  dm.set_num_points(uint32_t(mesh.positions.size()));
  draco::GeometryAttribute att;
  att.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
  const int id = dm.AddAttribute(att, true, uint32_t(mesh.positions.size()));
  for (uint32_t i = 0; i < mesh.positions.size(); ++i)
    dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(i), &mesh.positions[i].x);
  for (size_t t = 0; t < mesh.triangle_count(); ++t)
    dm.AddFace({draco::PointIndex(mesh.indices[3 * t]), draco::PointIndex(mesh.indices[3 * t + 1]),
                draco::PointIndex(mesh.indices[3 * t + 2])});
  draco::Encoder encoder;
  encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, 14);
  draco::EncoderBuffer buffer;
  ASSERT_TRUE(encoder.EncodeMeshToBuffer(dm, &buffer).ok());
  const auto foreign = tmp_dir() / "foreign.drc";
  std::ofstream(foreign, std::ios::binary).write(buffer.data(), std::streamsize(buffer.size()));
  auto m = draco_triangle_count(foreign);
  ASSERT_TRUE(m.is_ok()) << m.status().message();
  EXPECT_EQ(*m, mesh.triangle_count());

  const auto damaged = tmp_dir() / "damaged.drc";
  std::ofstream(damaged, std::ios::binary).write(buffer.data(), 12);
  auto bad = draco_triangle_count(damaged);
  ASSERT_FALSE(bad.is_ok());
  EXPECT_NE(bad.status().message().find("damaged.drc"), std::string::npos) << bad.status().message();
}

TEST(DracoIo, RoundTripKeepsReverseTwinsAndSeams) {
  // A collapsed thin slab: reverse-wound twins and normal seams survive.
  TriangleBatch slab = test::closed_box({0, 0, 0}, {1, 1, 0.05f}, 4);
  IndexedMesh mesh = indexed(slab);
  // Add the reverse twin of the first triangle (a wall collapsed to zero thickness).
  for (int k : {0, 2, 1}) mesh.indices.push_back(mesh.indices[k]);
  for (int speed : {5, 6}) {
    DracoOptions opt;
    opt.max_position_error = 1e-5;
    opt.speed = speed;
    const auto path = tmp_dir() / "slab.drc";
    auto rep = write_draco(path, mesh, opt);
    ASSERT_TRUE(rep.is_ok()) << rep.status().message();
    auto back = read_draco(path);
    ASSERT_TRUE(back.is_ok()) << back.status().message();
    expect_same_triangles(mesh, *back, rep->max_position_error, rep->max_normal_error);
  }
}

TEST(DracoIo, NormalErrorBoundHoldsForRandomNormals) {
  std::mt19937_64 rng(5);
  std::normal_distribution<float> g;
  TriangleBatch soup;
  for (int t = 0; t < 300; ++t) {
    const Vec3 base(float(t % 20), float(t / 20), 0);
    Vec3 n[3];
    for (auto& x : n) x = glm::normalize(Vec3(g(rng), g(rng), g(rng)));
    test::add_tri_n(soup, base, base + Vec3(0.5f, 0, 0), base + Vec3(0, 0.5f, 0.1f), n[0], n[1], n[2]);
  }
  const IndexedMesh mesh = indexed(soup);
  for (int bits : {6, 8, 10, 12}) {
    DracoOptions opt;
    opt.normal_bits = bits;
    opt.max_position_error = 1e-4;
    const auto path = tmp_dir() / "normals.drc";
    auto rep = write_draco(path, mesh, opt);
    ASSERT_TRUE(rep.is_ok()) << rep.status().message();
    auto back = read_draco(path);
    ASSERT_TRUE(back.is_ok());
    expect_same_triangles(mesh, *back, rep->max_position_error, rep->max_normal_error);
  }
}

// A glossy shininess of 1e6 asked for 30 normal bits, and Draco's normal
// coder then held 4.2 GB whatever the mesh (a memory limit of 512M did not
// see it): the bits stop at kMaxNormalBits, about float normals' precision.
TEST(DracoIo, NormalBitsStopAtWhatFloatNormalsHold) {
  EXPECT_EQ(choose_normal_bits(1e-12), kMaxNormalBits);
  EXPECT_EQ(choose_normal_bits(normal_error_bound(kMaxNormalBits)), kMaxNormalBits);
  EXPECT_LT(choose_normal_bits(normal_error_bound(12)), kMaxNormalBits);
  EXPECT_LT(normal_error_bound(kMaxNormalBits), 3e-7);
  const IndexedMesh mesh = indexed(test::uv_sphere({0, 0, 0}, 1.0f, 8, 12));
  DracoOptions opt;
  opt.normal_bits = kMaxNormalBits + 1;
  auto refused = write_draco(tmp_dir() / "bits.drc", mesh, opt);
  ASSERT_FALSE(refused.is_ok());
  EXPECT_NE(refused.status().message().find("normal_bits must be between 2 and 24"), std::string::npos)
      << refused.status().message();
  opt.normal_bits = kMaxNormalBits;
  ASSERT_TRUE(write_draco(tmp_dir() / "bits.drc", mesh, opt).is_ok());
}

TEST(DracoIo, MeshReaderOverADecodedFile) {
  const IndexedMesh mesh = indexed(test::uv_sphere({0, 0, 0}, 1.0f, 8, 12));
  const auto path = tmp_dir() / "reader.drc";
  ASSERT_TRUE(write_draco(path, mesh, {}).is_ok());
  auto reader = open_draco_reader(path, ReaderOptions{50});
  ASSERT_TRUE(reader.is_ok()) << reader.status().message();
  EXPECT_EQ((*reader)->header().format, MeshFormat::Draco);
  EXPECT_TRUE((*reader)->header().has_normals);
  TriangleBatch batch;
  size_t total = 0, batches = 0;
  while (true) {
    auto more = (*reader)->next(batch);
    ASSERT_TRUE(more.is_ok());
    if (!*more) break;
    EXPECT_LE(batch.size(), 50u);
    EXPECT_EQ(batch.normals.size(), batch.positions.size());
    total += batch.size();
    ++batches;
  }
  EXPECT_EQ(total, mesh.triangle_count());
  EXPECT_GT(batches, 1u);
}

TEST(DracoIo, BadInputsGiveClearErrorsAndNoFile) {
  const auto dir = tmp_dir();
  IndexedMesh degenerate;
  degenerate.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  degenerate.indices = {0, 1, 1};
  const auto out = dir / "degenerate.drc";
  std::filesystem::remove(out);
  auto r = write_draco(out, degenerate, {});
  ASSERT_FALSE(r.is_ok());
  EXPECT_NE(r.status().message().find("degenerate"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(out));
  degenerate.indices = {0, 1, 7};
  EXPECT_FALSE(write_draco(out, degenerate, {}).is_ok());

  const auto junk = dir / "junk.drc";
  std::ofstream(junk) << "not draco at all";
  auto j = read_draco(junk);
  ASSERT_FALSE(j.is_ok());
  EXPECT_NE(j.status().message().find("junk.drc"), std::string::npos);
  // A truncated real file.
  const IndexedMesh mesh = indexed(test::uv_sphere({0, 0, 0}, 1.0f, 8, 12));
  const auto good = dir / "truncated.drc";
  ASSERT_TRUE(write_draco(good, mesh, {}).is_ok());
  std::filesystem::resize_file(good, std::filesystem::file_size(good) / 2);
  EXPECT_FALSE(read_draco(good).is_ok());
  EXPECT_FALSE(read_draco(dir / "missing.drc").is_ok());
}

std::vector<char> file_bytes(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

TEST(DracoParts, DecodeWithinTheBoundsAndWithoutCracks) {
  // The parts are quantised on the whole mesh's grid (the bits chosen for
  // the whole mesh), so a vertex on the seam between two parts decodes to
  // the same position in both.
  const IndexedMesh mesh = indexed(test::uv_sphere({0.3f, -1.2f, 2.0f}, 1.7f, 40, 64));
  const test::ScratchDir dir("draco-parts");
  DracoOptions one;
  one.max_position_error = 1e-4;
  DracoOptions four = one;
  four.parts = 4;
  auto w1 = write_draco(dir.path / "one.drc", mesh, one);
  auto w4 = write_draco(dir.path / "four.drc", mesh, four);
  ASSERT_TRUE(w1.is_ok()) << w1.status().message();
  ASSERT_TRUE(w4.is_ok()) << w4.status().message();
  EXPECT_EQ(w4->position_bits, w1->position_bits);
  EXPECT_EQ(w4->max_position_error, w1->max_position_error);
  EXPECT_EQ(w4->bytes, std::filesystem::file_size(dir.path / "four.drc"));
  const std::vector<char> bytes = file_bytes(dir.path / "four.drc");
  ASSERT_GE(bytes.size(), 8u);
  EXPECT_EQ(std::memcmp(bytes.data(), kDracoPartsMagic, 8), 0);
  auto parts = draco_parts(bytes.data(), bytes.size(), "four.drc");
  ASSERT_TRUE(parts.is_ok()) << parts.status().message();
  EXPECT_EQ(parts->size(), 4u);

  auto r1 = read_draco(dir.path / "one.drc");
  auto r4 = read_draco(dir.path / "four.drc");
  ASSERT_TRUE(r1.is_ok()) << r1.status().message();
  ASSERT_TRUE(r4.is_ok()) << r4.status().message();
  EXPECT_EQ(r4->triangle_count(), mesh.triangle_count());
  // Within the stated bounds of the input, and without cracks: a vertex two
  // parts share decodes to one position, so the part file has as many
  // distinct positions as the single bitstream.
  expect_same_triangles(mesh, *r4, w4->max_position_error, w4->max_normal_error);
  auto distinct = [](const IndexedMesh& m) {
    std::set<std::array<float, 3>> s;
    for (const Vec3& p : m.positions) s.insert({p.x, p.y, p.z});
    return s.size();
  };
  EXPECT_EQ(distinct(*r4), distinct(*r1));
  EXPECT_EQ(distinct(*r1), distinct(mesh));
  auto count = draco_triangle_count(dir.path / "four.drc");
  ASSERT_TRUE(count.is_ok()) << count.status().message();
  EXPECT_EQ(*count, mesh.triangle_count());
}

TEST(DracoParts, SameBytesForAnyThreadCount) {
  const IndexedMesh mesh = indexed(test::uv_sphere({0, 0, 0}, 1.0f, 30, 50));
  const test::ScratchDir dir("draco-parts-threads");
  DracoOptions o;
  o.parts = 5;
  std::vector<std::vector<char>> got;
  for (int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    const auto path = dir.path / ("t" + std::to_string(threads) + ".drc");
    auto w = write_draco(path, mesh, o);
    ASSERT_TRUE(w.is_ok()) << w.status().message();
    got.push_back(file_bytes(path));
  }
  EXPECT_EQ(got[0], got[1]);
}

TEST(DracoParts, DamagedPartFilesGiveErrorsNamingTheFile) {
  const IndexedMesh mesh = indexed(test::uv_sphere({0, 0, 0}, 1.0f, 20, 30));
  const test::ScratchDir dir("draco-parts-damage");
  DracoOptions o;
  o.parts = 3;
  const auto good = dir.path / "good.drc";
  ASSERT_TRUE(write_draco(good, mesh, o).is_ok());
  const std::vector<char> bytes = file_bytes(good);
  auto write = [&](const std::string& name, const std::vector<char>& b) {
    const auto p = dir.path / name;
    std::ofstream(p, std::ios::binary).write(b.data(), std::streamsize(b.size()));
    return p;
  };
  struct Case {
    std::string name, expect;
    std::vector<char> bytes;
  };
  std::vector<Case> cases;
  cases.push_back({"truncated.drc", "runs past the end", std::vector<char>(bytes.begin(), bytes.end() - 10)});
  cases.push_back({"header.drc", "truncated", std::vector<char>(bytes.begin(), bytes.begin() + 12)});
  std::vector<char> zero_parts = bytes;
  zero_parts[12] = zero_parts[13] = zero_parts[14] = zero_parts[15] = 0;
  cases.push_back({"zero.drc", "parts (1 to 256)", zero_parts});
  std::vector<char> version = bytes;
  version[8] = 9;
  cases.push_back({"version.drc", "version 9", version});
  std::vector<char> tail = bytes;
  tail.push_back(0);
  cases.push_back({"tail.drc", "after the last part", tail});
  std::vector<char> garbled = bytes;
  for (size_t i = 16 + 16 * 3 + 40; i < 16 + 16 * 3 + 80 && i < garbled.size(); ++i) garbled[i] = char(0x5a);
  cases.push_back({"garbled.drc", "part 1", garbled});
  for (const Case& c : cases) {
    const auto path = write(c.name, c.bytes);
    auto r = read_draco(path);
    ASSERT_FALSE(r.is_ok()) << c.name;
    EXPECT_NE(r.status().message().find(path.string()), std::string::npos) << r.status().message();
    EXPECT_NE(r.status().message().find(c.expect), std::string::npos) << c.name << ": " << r.status().message();
  }
}

}  // namespace

#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer) || __has_feature(thread_sanitizer)
#define RAYLOD_TEST_OWN_MALLOC 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define RAYLOD_TEST_OWN_MALLOC 1
#endif

// ScopedKeptFreeMemory (around Draco's encoder): while one lives, a large
// block comes from the heap rather than a mapping of its own, so freeing it
// keeps its pages; a nested one leaves the outer one's setting; after the
// last, large blocks are mapped again (glibc's defaults).
TEST(KeptFreeMemory, LargeBlocksStayInTheHeapWhileOneLives) {
#if defined(__GLIBC__) && !defined(RAYLOD_TEST_OWN_MALLOC)
  auto mapped = [] {
    const size_t before = mallinfo2().hblks;
    void* p = std::malloc(size_t(64) << 20);
    static_cast<volatile char*>(p)[0] = 1;
    const size_t during = mallinfo2().hblks;
    std::free(p);
    return during > before;
  };
  EXPECT_TRUE(mapped());
  {
    const ScopedKeptFreeMemory outer;
    EXPECT_FALSE(mapped());
    { const ScopedKeptFreeMemory inner; }
    EXPECT_FALSE(mapped());
  }
  EXPECT_TRUE(mapped());
#else
  GTEST_SKIP() << "glibc's allocator is not the one in use";
#endif
}

// A version 1.2 bitstream whose connectivity header claims 101 million
// vertices (the bytes 0x06060606): Draco's decoder allocated 3 GB for it
// before reading anything more (found by fuzz_draco, 2026-11-28). Bitstreams
// before version 2 are refused with a message naming the version.
TEST(DracoRead, AnOldBitstreamVersionIsRefusedBeforeDracoAllocatesForIt) {
  const test::ScratchDir dir("draco-old-version");
  std::string bytes = std::string("DRACO\x01\x02\x01\x01\x00\x80\x00", 12) + std::string(120, '\x06');
  const std::filesystem::path path = dir.path / "old.drc";
  std::ofstream(path, std::ios::binary) << bytes;
  auto got = read_draco(path);
  ASSERT_FALSE(got.is_ok());
  EXPECT_NE(got.status().message().find("old.drc: Draco bitstream version 1.2 is not read"), std::string::npos)
      << got.status().message();
}

// A Draco 2.2 edgebreaker header claiming counts the file cannot hold is
// refused before Draco sizes its tables from them: fuzz_draco found a
// 415-byte file claiming 242,565,077 triangles, for which Draco allocated
// 2.9 GB; and more vertices than three a triangle cannot be.
TEST(DracoRead, ClaimedCountsBeyondWhatTheFileHoldsAreRefused) {
  const test::ScratchDir dir("draco-counts");
  struct Case {
    uint64_t vertices, faces;
    std::string says;
  };
  for (const Case& c : {Case{35, 242565077, "claims 242565077 triangles and 35 vertices in 154 bytes"},
                        Case{1000000, 10, "claims 1000000 vertices for 10 triangles"}}) {
    const std::string bytes = test::draco_header_claiming(c.vertices, c.faces, 154);
    ASSERT_EQ(bytes.size(), 154u);
    const std::filesystem::path path = dir.path / "claims.drc";
    std::ofstream(path, std::ios::binary) << bytes;
    auto got = read_draco(path);
    ASSERT_FALSE(got.is_ok());
    EXPECT_NE(got.status().message().find("claims.drc: the Draco header " + c.says), std::string::npos)
        << got.status().message();
  }
}

// Positions or normals stored as bools (Draco allows any data type) are
// refused: Draco converts them by reading each byte as a C++ bool, undefined
// for bytes other than 0 and 1 (fuzz_draco, under UBSan, found a file whose
// bool position held 3).
TEST(DracoRead, PositionsOrNormalsStoredAsBoolsAreRefused) {
  const test::ScratchDir dir("draco-bool");
  for (const bool bool_normals : {false, true}) {
    const test::DracoBytes mesh = test::draco_mesh_with_bools(bool_normals);
    ASSERT_FALSE(mesh.bytes.empty());
    const std::filesystem::path path = dir.path / "bool.drc";
    std::ofstream(path, std::ios::binary) << mesh.bytes;
    auto got = read_draco(path);
    ASSERT_FALSE(got.is_ok());
    const std::string what = bool_normals ? "bool.drc: the normal attribute does not hold numbers"
                                          : "bool.drc: the position attribute does not hold numbers";
    EXPECT_NE(got.status().message().find(what), std::string::npos) << got.status().message();
  }
}

}  // namespace raylod
