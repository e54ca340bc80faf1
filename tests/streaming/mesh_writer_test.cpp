// Mesh writers (round trips, atomic output, errors) and the seeded property
// test: a random mesh written in every format reads back as the same triangles.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <random>
#include <sstream>

#include "reader_test_util.h"
#include "streaming/mesh_writer.h"

namespace raylod {
namespace {

using test::Bytes;
using test::read_all;
using test::write_file;

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

size_t files_in(const std::filesystem::path& dir) {
  size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) ++n;
  return n;
}

TriangleBatch two_triangles(bool normals) {
  TriangleBatch b;
  b.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 0}, {0, 0, 2}, {1, 0, 0}};
  if (normals) b.normals = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 1, 0}, {0, 1, 0}, {0, 1, 0}};
  return b;
}

TEST(MeshWriter, PlyRoundTripWithAndWithoutNormals) {
  for (bool normals : {true, false}) {
    const auto path = test::scratch_dir() / (normals ? "n.ply" : "plain.ply");
    auto w = create_mesh_writer(path, WriterOptions{normals});
    ASSERT_TRUE(w.is_ok()) << w.status().message();
    const TriangleBatch b = two_triangles(true);
    ASSERT_TRUE(w.value()->write(b).is_ok());
    ASSERT_TRUE(w.value()->write(b).is_ok());
    EXPECT_EQ(w.value()->triangles_written(), 4u);
    ASSERT_TRUE(w.value()->finish().is_ok());
    auto r = read_all(path, 3);
    ASSERT_TRUE(r.status.is_ok()) << r.status.message();
    EXPECT_EQ(r.header.encoding, "binary_little_endian");
    EXPECT_EQ(r.header.has_normals, normals);
    ASSERT_EQ(r.triangles(), 4u);
    std::vector<Vec3> want = b.positions;
    want.insert(want.end(), b.positions.begin(), b.positions.end());
    EXPECT_EQ(r.positions, want);
    if (normals) {
      std::vector<Vec3> wn = b.normals;
      wn.insert(wn.end(), b.normals.begin(), b.normals.end());
      EXPECT_EQ(r.normals, wn);
    }
  }
}

TEST(MeshWriter, StlRoundTripWritesFaceNormalsAndANonSolidHeader) {
  const auto path = test::scratch_dir() / "two.stl";
  auto w = create_mesh_writer(path);
  ASSERT_TRUE(w.is_ok());
  ASSERT_TRUE(w.value()->write(two_triangles(true)).is_ok());
  ASSERT_TRUE(w.value()->finish().is_ok());
  const std::string bytes = slurp(path);
  ASSERT_EQ(bytes.size(), 84u + 2 * 50u);
  EXPECT_NE(bytes.substr(0, 5), "solid");
  float n[3];
  std::memcpy(n, bytes.data() + 84 + 50, 12);  // second triangle: (0,0,0) (0,0,2) (1,0,0) -> +y
  EXPECT_EQ(Vec3(n[0], n[1], n[2]), Vec3(0, 1, 0));
  auto r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, two_triangles(false).positions);
}

TEST(MeshWriter, NothingAppearsUnlessFinishSucceeds) {
  const auto dir = test::scratch_dir();
  const size_t before = files_in(dir);
  {
    auto w = create_mesh_writer(dir / "abandoned.ply");
    ASSERT_TRUE(w.is_ok());
    ASSERT_TRUE(w.value()->write(two_triangles(false)).is_ok());
  }  // destroyed without finish()
  EXPECT_FALSE(std::filesystem::exists(dir / "abandoned.ply"));
  for (const char* name : {"empty.ply", "empty.stl"}) {
    auto w = create_mesh_writer(dir / name);
    ASSERT_TRUE(w.is_ok());
    Status s = w.value()->finish();
    EXPECT_FALSE(s.is_ok());
    EXPECT_NE(s.message().find("no triangles to write"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find(name), std::string::npos) << s.message();
  }
  EXPECT_EQ(files_in(dir), before) << "no temporary or partial file may be left behind";
}

TEST(MeshWriter, Errors) {
  const auto dir = test::scratch_dir();
  auto bad_ext = create_mesh_writer(dir / "mesh.obj");
  ASSERT_FALSE(bad_ext.is_ok());
  EXPECT_NE(bad_ext.status().message().find("expected .ply or .stl"), std::string::npos);
  auto no_dir = create_mesh_writer(dir / "missing" / "mesh.ply");
  ASSERT_FALSE(no_dir.is_ok());
  EXPECT_NE(no_dir.status().message().find("mesh.ply: cannot create"), std::string::npos) << no_dir.status().message();

  auto w = create_mesh_writer(dir / "mixed.ply");
  ASSERT_TRUE(w.is_ok());
  ASSERT_TRUE(w.value()->write(two_triangles(true)).is_ok());
  Status s = w.value()->write(two_triangles(false));
  EXPECT_NE(s.message().find("a batch without normals follows batches with normals"), std::string::npos) << s.message();
  TriangleBatch odd;
  odd.positions = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_NE(w.value()->write(odd).message().find("not a multiple of 3"), std::string::npos);
  TriangleBatch mismatched = two_triangles(true);
  mismatched.normals.pop_back();
  EXPECT_NE(w.value()->write(mismatched).message().find("5 normals for 6 positions"), std::string::npos);
}

// ---- seeded property test: every format reads back the same triangles ----

struct RandomMesh {
  std::vector<Vec3> v, n;
  std::vector<std::array<uint32_t, 3>> f;
};

RandomMesh random_mesh(uint32_t seed, size_t vertices, size_t faces) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> coord(-1000.f, 1000.f), unit(-1.f, 1.f);
  std::uniform_int_distribution<uint32_t> pick(0, uint32_t(vertices - 1));
  RandomMesh m;
  for (size_t i = 0; i < vertices; ++i) {
    m.v.emplace_back(coord(rng), coord(rng), coord(rng));
    Vec3 d;
    do d = Vec3(unit(rng), unit(rng), unit(rng));
    while (glm::length(d) < 0.1f);
    m.n.push_back(glm::normalize(d));
  }
  for (size_t i = 0; i < faces; ++i) m.f.push_back({pick(rng), pick(rng), pick(rng)});
  return m;
}

std::string g9(float x) {
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", double(x));  // round-trips a float exactly
  return b;
}

// 18 floats per triangle: positions then normals (zero when absent).
std::vector<std::array<float, 18>> corners(const std::vector<Vec3>& p, const std::vector<Vec3>& n) {
  std::vector<std::array<float, 18>> t(p.size() / 3);
  for (size_t i = 0; i < t.size(); ++i)
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) {
        t[i][3 * k + c] = p[3 * i + k][c];
        t[i][9 + 3 * k + c] = n.empty() ? 0.f : n[3 * i + k][c];
      }
  std::sort(t.begin(), t.end());
  return t;
}

TEST(ReaderProperty, RandomMeshReadsBackTheSameInEveryFormat) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const RandomMesh m = random_mesh(seed, 50 + seed * 37, 200 + seed * 101);
    TriangleBatch all;
    for (const auto& f : m.f)
      for (uint32_t i : f) {
        all.positions.push_back(m.v[i]);
        all.normals.push_back(m.n[i]);
      }
    const auto want = corners(all.positions, all.normals);
    const auto want_no_normals = corners(all.positions, {});
    const auto dir = test::scratch_dir();
    std::vector<std::pair<std::filesystem::path, bool>> files;  // path, has normals

    for (const char* name : {"soup.ply", "soup.stl"}) {
      auto w = create_mesh_writer(dir / name);
      ASSERT_TRUE(w.is_ok());
      // Written in uneven batches.
      for (size_t start = 0; start < m.f.size(); start += 77) {
        TriangleBatch b;
        const size_t end = std::min(m.f.size(), start + 77);
        b.positions.assign(all.positions.begin() + 3 * start, all.positions.begin() + 3 * end);
        b.normals.assign(all.normals.begin() + 3 * start, all.normals.begin() + 3 * end);
        ASSERT_TRUE(w.value()->write(b).is_ok());
      }
      ASSERT_TRUE(w.value()->finish().is_ok());
      files.push_back({dir / name, std::string(name) == "soup.ply"});
    }
    // Indexed PLY: ASCII, and binary big endian with uint indices.
    const std::string head = "element vertex " + std::to_string(m.v.size()) +
                             "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n"
                             "property float nz\nelement face " + std::to_string(m.f.size()) +
                             "\nproperty list uchar uint vertex_indices\nend_header\n";
    std::string ascii = "ply\nformat ascii 1.0\n" + head;
    Bytes be;
    be.big = true;
    be.text("ply\nformat binary_big_endian 1.0\n" + head);
    for (size_t i = 0; i < m.v.size(); ++i) {
      ascii += g9(m.v[i].x) + " " + g9(m.v[i].y) + " " + g9(m.v[i].z) + " " + g9(m.n[i].x) + " " + g9(m.n[i].y) + " " +
               g9(m.n[i].z) + "\n";
      be.put(m.v[i].x).put(m.v[i].y).put(m.v[i].z).put(m.n[i].x).put(m.n[i].y).put(m.n[i].z);
    }
    for (const auto& f : m.f) {
      ascii += "3 " + std::to_string(f[0]) + " " + std::to_string(f[1]) + " " + std::to_string(f[2]) + "\n";
      be.put<uint8_t>(3).put(f[0]).put(f[1]).put(f[2]);
    }
    files.push_back({write_file("indexed_ascii.ply", ascii), true});
    files.push_back({write_file("indexed_be.ply", be.data), true});
    // OBJ: every face in one of the index forms, absolute or relative.
    std::string obj = "# random mesh\n";
    for (size_t i = 0; i < m.v.size(); ++i) {
      obj += "v " + g9(m.v[i].x) + " " + g9(m.v[i].y) + " " + g9(m.v[i].z) + "\n";
      obj += "vn " + g9(m.n[i].x) + " " + g9(m.n[i].y) + " " + g9(m.n[i].z) + "\n";
    }
    obj += "vt 0.5 0.5\n";
    const long nv = long(m.v.size());
    for (size_t k = 0; k < m.f.size(); ++k) {
      obj += "f";
      for (uint32_t i : m.f[k]) {
        const std::string a = std::to_string(i + 1), r = std::to_string(long(i) - nv);
        obj += k % 3 == 0 ? " " + a + "//" + a : k % 3 == 1 ? " " + r + "/1/" + r : " " + a + "/-1/" + r;
      }
      obj += "\n";
    }
    files.push_back({write_file("random.obj", obj), true});
    // ASCII STL.
    std::string stl = "solid random\n";
    for (const auto& f : m.f) {
      stl += "facet normal 0 0 0\nouter loop\n";
      for (uint32_t i : f) stl += "vertex " + g9(m.v[i].x) + " " + g9(m.v[i].y) + " " + g9(m.v[i].z) + "\n";
      stl += "endloop\nendfacet\n";
    }
    files.push_back({write_file("random_ascii.stl", stl + "endsolid random\n"), false});

    std::mt19937 rng(seed);
    for (const auto& [path, normals] : files) {
      const size_t batch = std::uniform_int_distribution<size_t>(1, 300)(rng);
      auto r = read_all(path, batch);
      ASSERT_TRUE(r.status.is_ok()) << path << ": " << r.status.message();
      EXPECT_EQ(r.header.has_normals, normals) << path;
      EXPECT_EQ(r.triangles(), m.f.size()) << path;
      EXPECT_TRUE(corners(r.positions, r.normals) == (normals ? want : want_no_normals))
          << path << " (seed " << seed << ", batch " << batch << ")";
    }
  }
}

}  // namespace
}  // namespace raylod
