// generate_mesh / ensure_generated_mesh: files that read back to the
// tessellation, STL records, determinism across thread counts, the cache.
#include <thread>

#include <tbb/task_arena.h>

#include "gen/generate.h"
#include "gen_test_util.h"
#include "streaming/mesh_reader.h"

namespace raylod {
namespace {

TEST(Generate, PlyReadsBackAsTheTessellation) {
  const auto dir = test::test_tmp_dir("ply");
  for (const char* shape : {"teapot", "bottle"}) {
    const auto path = dir / (std::string(shape) + ".ply");
    auto r = generate_mesh({shape, 5000}, path);
    ASSERT_TRUE(r.is_ok()) << r.status().message();
    EXPECT_EQ(r->format, "ply");
    EXPECT_EQ(r->bytes, std::filesystem::file_size(path));
    const auto m = test::read_generated_ply(path);
    auto surface = make_generated_surface(shape, 5000);
    ASSERT_TRUE(surface.is_ok());
    const auto expected = test::grid_to_mesh(**surface);
    EXPECT_EQ(m.triangles(), r->triangles);
    EXPECT_EQ(m.positions.size(), r->vertices);
    EXPECT_EQ(m.positions, expected.positions);
    EXPECT_EQ(m.normals, expected.normals);
    EXPECT_EQ(m.indices, expected.indices);
    Bbox b;
    for (const Vec3& p : m.positions) b.expand(p);
    EXPECT_EQ(b.lo, r->bounds.lo);
    EXPECT_EQ(b.hi, r->bounds.hi);
    EXPECT_NE(m.header_lines[2].find("raylod gen " + std::string(shape) + " --triangles 5000"), std::string::npos);
  }
}

TEST(Generate, NoNormalsOption) {
  const auto dir = test::test_tmp_dir("nonormals");
  GenOptions o{"teapot", 1000, false};
  auto r = generate_mesh(o, dir / "t.ply");
  ASSERT_TRUE(r.is_ok());
  const auto m = test::read_generated_ply(dir / "t.ply");
  EXPECT_TRUE(m.normals.empty());
  EXPECT_EQ(m.triangles(), r->triangles);
}

TEST(Generate, ProjectReaderOpensTheOutput) {
  const auto dir = test::test_tmp_dir("reader");
  auto r = generate_mesh({"teapot", 3000}, dir / "t.ply");
  ASSERT_TRUE(r.is_ok());
  auto reader = open_mesh(dir / "t.ply");
  ASSERT_TRUE(reader.is_ok()) << reader.status().message();
  EXPECT_EQ((*reader)->header().face_count, r->triangles);
  EXPECT_EQ((*reader)->header().vertex_count, r->vertices);
  EXPECT_TRUE((*reader)->header().has_normals);
  TriangleBatch batch;
  uint64_t n = 0;
  for (;;) {
    auto more = (*reader)->next(batch);
    ASSERT_TRUE(more.is_ok()) << more.status().message();
    if (!*more) break;
    n += batch.size();
  }
  EXPECT_EQ(n, r->triangles);
}

TEST(Generate, StlHasTheSameTrianglesWithFaceNormals) {
  const auto dir = test::test_tmp_dir("stl");
  auto r = generate_mesh({"bottle", 3000}, dir / "b.STL");
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  EXPECT_EQ(r->format, "stl");
  const std::string bytes = test::read_bytes(dir / "b.STL");
  ASSERT_EQ(bytes.size(), 84 + 50 * r->triangles);
  EXPECT_NE(bytes.substr(0, 5), "solid");
  uint32_t count;
  std::memcpy(&count, bytes.data() + 80, 4);
  EXPECT_EQ(count, r->triangles);
  auto surface = make_generated_surface("bottle", 3000);
  const auto m = test::grid_to_mesh(**surface);
  ASSERT_EQ(m.triangles(), count);
  for (size_t t = 0; t < count; ++t) {
    float f[12];
    std::memcpy(f, bytes.data() + 84 + 50 * t, 48);
    const Vec3d n(f[0], f[1], f[2]);
    ASSERT_NEAR(glm::length(n), 1.0, 1e-6);
    for (int k = 0; k < 3; ++k) ASSERT_EQ(Vec3(f[3 + 3 * k], f[4 + 3 * k], f[5 + 3 * k]), m.positions[m.indices[3 * t + k]]);
    const Vec3d fn = face_normal(test::corner(m, t, 0), test::corner(m, t, 1), test::corner(m, t, 2));
    ASSERT_GT(glm::dot(n, fn), 0.9999);
  }
}

TEST(Generate, SameBytesWhateverTheThreadCount) {
  const auto dir = test::test_tmp_dir("determinism");
  // Large enough for several chunks of rows (2^16 vertices each).
  for (const char* name : {"teapot.ply", "bottle.stl"}) {
    const std::string shape = std::string(name).substr(0, 6);
    std::string first;
    for (int threads : {1, 2, 4, 1}) {
      const auto path = dir / (std::to_string(threads) + name);
      bool generated = false;
      tbb::task_arena(threads).execute([&] { generated = generate_mesh({shape, 400000}, path).is_ok(); });
      ASSERT_TRUE(generated);
      const std::string bytes = test::read_bytes(path);
      if (first.empty()) first = bytes;
      EXPECT_TRUE(bytes == first) << name << " with " << threads << " threads differs";
      std::filesystem::remove(path);
    }
  }
}

TEST(Generate, BadRequestsAreErrorsAndWriteNothing) {
  const auto dir = test::test_tmp_dir("bad");
  auto expect_error = [&](const GenOptions& o, const std::string& file, const std::string& words) {
    auto r = generate_mesh(o, dir / file);
    ASSERT_FALSE(r.is_ok());
    EXPECT_NE(r.status().message().find(words), std::string::npos) << r.status().message();
  };
  expect_error({"dragon", 1000}, "a.ply", "unknown shape 'dragon'");
  expect_error({"teapot", 10}, "a.ply", "outside");
  expect_error({"teapot", kGenMaxTriangles + 1}, "a.ply", "outside");
  expect_error({"teapot", 1000}, "a.obj", ".ply or .stl");
  GenOptions columns{"teapot", 1000};
  columns.around = 40;
  expect_error(columns, "a.ply", "bottle's, not a teapot's");
  columns.shape = "bottle";
  columns.around = 2;
  expect_error(columns, "a.ply", "outside [3, 500]");
  columns.around = 501;
  expect_error(columns, "a.ply", "outside [3, 500]");
  auto r = generate_mesh({"teapot", 1000}, dir / "missing" / "a.ply");
  EXPECT_FALSE(r.is_ok());
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

TEST(Generate, ABottleWithAGivenNumberOfColumns) {
  const auto dir = test::test_tmp_dir("around");
  GenOptions o{"bottle", 1200};
  o.around = 40;  // 2 x 40 x 15 = 1200
  auto r = generate_mesh(o, dir / "b.ply");
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  EXPECT_EQ(r->triangles, 1200u);
  EXPECT_EQ(r->vertices, 40u * 15u + 2u);
  EXPECT_EQ(r->grid, "16 profile segments x 40 around");
  const auto m = test::read_generated_ply(dir / "b.ply");
  EXPECT_EQ(m.indices.size(), 3u * 1200u);
}

TEST(Generate, CacheGeneratesOnceAndReuses) {
  const auto cache = test::test_tmp_dir("cache");
  const GeneratedMesh g{"teapot", 2000};
  auto p1 = ensure_generated_mesh(g, cache);
  ASSERT_TRUE(p1.is_ok()) << p1.status().message();
  EXPECT_EQ(*p1, cache / "meshes" / "teapot-2000.ply");
  const std::string fresh = test::read_bytes(*p1);
  // Mark the file without changing its size: a second call must reuse it.
  {
    std::fstream f(*p1, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(0);
    f.write("PLY", 3);
  }
  auto p2 = ensure_generated_mesh(g, cache);
  ASSERT_TRUE(p2.is_ok());
  EXPECT_EQ(*p2, *p1);
  EXPECT_EQ(test::read_bytes(*p2).substr(0, 3), "PLY");
  // A truncated file (an interrupted copy, say) is regenerated.
  std::filesystem::resize_file(*p1, 100);
  auto p3 = ensure_generated_mesh(g, cache);
  ASSERT_TRUE(p3.is_ok());
  EXPECT_TRUE(test::read_bytes(*p3) == fresh);
  EXPECT_FALSE(ensure_generated_mesh({"cube", 2000}, cache).is_ok());
}

TEST(Generate, CacheIsSafeWhenWritersRace) {
  const auto cache = test::test_tmp_dir("race");
  const GeneratedMesh g{"bottle", 100000};
  std::vector<std::thread> threads;
  std::vector<Status> results(4);
  for (int i = 0; i < 4; ++i)
    threads.emplace_back([&, i] {
      auto p = ensure_generated_mesh(g, cache);
      results[i] = p.status();
    });
  for (auto& t : threads) t.join();
  for (const auto& st : results) EXPECT_TRUE(st.is_ok()) << st.message();
  // One complete file, no temporaries left behind.
  const auto m = test::read_generated_ply(generated_mesh_path(g, cache));
  auto surface = make_generated_surface("bottle", 100000);
  ASSERT_TRUE(surface.is_ok());
  EXPECT_EQ(m.triangles(), surface.value()->triangle_count());
  size_t files = 0;
  for (const auto& e : std::filesystem::directory_iterator(cache / "meshes"))
    files += e.is_regular_file() && e.path().extension() != ".lock";  // the generation lock stays
  EXPECT_EQ(files, 1u);
}

TEST(Generate, ResolvesGeneratedSceneObjects) {
  const auto cache = test::test_tmp_dir("scene");
  Scene scene;
  SceneObject plain;
  plain.mesh = "/some/where/mesh.ply";
  SceneObject generated;
  generated.generate = GeneratedMesh{"teapot", 1500};
  scene.objects = {plain, generated};
  ASSERT_TRUE(resolve_generated_meshes(scene, cache).is_ok());
  EXPECT_EQ(scene.objects[0].mesh, "/some/where/mesh.ply");
  EXPECT_EQ(scene.objects[1].mesh, cache / "meshes" / "teapot-1500.ply");
  EXPECT_TRUE(std::filesystem::exists(scene.objects[1].mesh));

  scene.objects[1].generate->triangles = 5;
  const Status st = resolve_generated_meshes(scene, cache);
  EXPECT_FALSE(st.is_ok());
  EXPECT_NE(st.message().find("object 1"), std::string::npos) << st.message();
}

}  // namespace
}  // namespace raylod
