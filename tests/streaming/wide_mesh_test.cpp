// A mesh whose coordinates are each floats but whose extent is not (corners
// at -3e38 and +3e38): the store build rejects it while it reads the mesh,
// naming the file and the axis, and the Draco writer refuses it instead of
// crashing in the encoder. Nothing is written either way.
#include <gtest/gtest.h>

#include "core/progress.h"
#include "reader_test_util.h"
#include "streaming/draco_io.h"
#include "streaming/octree_store.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;
using test::Bytes;
using test::write_file;

// One triangle with corners (-3e38, 0, 0), (3e38, 0, 0), (0, 1, 0) as a binary
// PLY whose coordinates are T ("float" or "double"): each coordinate is a
// float, the extent is not.
template <class T>
fs::path wide_triangle_ply(const char* type) {
  Bytes b;
  b.text(std::string("ply\nformat binary_little_endian 1.0\nelement vertex 3\n") + "property " + type + " x\nproperty " +
         type + " y\nproperty " + type + " z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n");
  for (T c : {T(-3e38), T(0), T(0), T(3e38), T(0), T(0), T(0), T(1), T(0)}) b.put<T>(c);
  b.put<uint8_t>(3).put<int32_t>(0).put<int32_t>(1).put<int32_t>(2);
  return write_file("wide.ply", b.data);
}

TEST(WideMesh, StoreBuildRejectsAMeshWiderThanTheFloatRange) {
  Progress::set_enabled(false);
  // Float coordinates: each reads fine, the build rejects the extent.
  const fs::path mesh = wide_triangle_ply<float>("float");
  ASSERT_TRUE(test::read_all(mesh).status.is_ok());
  const fs::path store = test::scratch_dir() / "wide.raylod";
  auto built = build_store(mesh, store, StoreOptions{});
  ASSERT_FALSE(built.is_ok());
  const std::string msg = built.status().message();
  EXPECT_NE(msg.find("wide.ply: the mesh spans 6e+38 along x (from -3e+38 to 3e+38), more than the float range"),
            std::string::npos) << msg;
  for (const auto& entry : fs::directory_iterator(test::scratch_dir()))
    EXPECT_EQ(entry.path(), mesh) << "left behind: " << entry.path();
}

TEST(WideMesh, ReaderRejectsADoubleMeshWiderThanTheFloatRange) {
  // Double coordinates far from zero are read relative to the first vertex
  // (MeshHeader::origin), so the reader itself finds the extent too wide.
  const fs::path mesh = wide_triangle_ply<double>("double");
  const auto read = test::read_all(mesh);
  ASSERT_FALSE(read.status.is_ok());
  const std::string msg = read.status.message();
  for (const char* part : {"wide.ply", "vertex 1 (3e+38, 0, 0) lies (6e+38, 0, 0) from the mesh's first vertex (-3e+38, 0, 0)",
                           "more than the float range"})
    EXPECT_NE(msg.find(part), std::string::npos) << msg << " lacks " << part;
}

TEST(WideMesh, DracoWriterRefusesInsteadOfCrashing) {
  IndexedMesh m;
  m.positions = {{-3e38f, 0, 0}, {3e38f, 0, 0}, {0, 1, 0}};
  m.indices = {0, 1, 2};
  const fs::path out = test::scratch_dir() / "wide.drc";
  auto written = write_draco(out, m, DracoOptions{});
  ASSERT_FALSE(written.is_ok());
  EXPECT_NE(written.status().message().find("wide.drc: the mesh spans 6e+38, more than the float range"),
            std::string::npos) << written.status().message();
  EXPECT_TRUE(fs::is_empty(test::scratch_dir()));
  // A part file checks the whole mesh, though each part alone (x from -3e38
  // to 0, and from 0 to 3e38) spans less.
  IndexedMesh halves;
  halves.positions = {{-3e38f, 0, 0}, {0, 1, 0}, {-3e38f, 1, 0}, {3e38f, 0, 0}, {3e38f, 1, 0}};
  halves.indices = {0, 1, 2, 3, 4, 1};
  DracoOptions parts;
  parts.parts = 2;
  written = write_draco(out, halves, parts);
  ASSERT_FALSE(written.is_ok());
  EXPECT_NE(written.status().message().find("wide.drc: the mesh spans 6e+38, more than the float range"),
            std::string::npos) << written.status().message();
  EXPECT_TRUE(fs::is_empty(test::scratch_dir()));
  // Just inside the range it still encodes.
  m.positions = {{-1.5e38f, 0, 0}, {1.5e38f, 0, 0}, {0, 1e38f, 0}};
  written = write_draco(out, m, DracoOptions{});
  ASSERT_TRUE(written.is_ok()) << written.status().message();
  auto back = read_draco(out);
  ASSERT_TRUE(back.is_ok()) << back.status().message();
  EXPECT_EQ(back->triangle_count(), 1u);
}

}  // namespace
}  // namespace raylod
