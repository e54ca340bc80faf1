// The glTF reader: tiny exact files (indexed, non-indexed, strips, fans,
// node hierarchies, quantized attributes, a Draco primitive), a round trip
// through the .glb writer within the Draco bound, and bad input.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>


#include "draco_hostile.h"
#include "gltf_test_util.h"
#include "reader_test_util.h"
#include "streaming/draco_io.h"
#include "core/progress.h"
#include "streaming/gltf_io.h"
#include "streaming/octree_store.h"

namespace raylod {
namespace {

using test::GltfBuilder;
using nlohmann::json;

const std::vector<Vec3> kQuad = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};

std::vector<Vec3> corners(const std::vector<Vec3>& v, const std::vector<int>& order) {
  std::vector<Vec3> out;
  for (int i : order) out.push_back(v[size_t(i)]);
  return out;
}

test::ReadAll read_gltf(const GltfBuilder& b, const std::string& name = "m.gltf") {
  return test::read_all(test::write_file(name, name.ends_with(".glb") ? b.glb() : b.gltf()));
}

TEST(GltfReader, IndexedTrianglesFromDataUri) {
  GltfBuilder b;
  const int pos = b.positions(kQuad);
  b.mesh({GltfBuilder::primitive(pos, b.indices({0, 1, 2, 0, 2, 3}))});
  const auto r = read_gltf(b);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.header.format, MeshFormat::Gltf);
  EXPECT_EQ(r.header.face_count, 2u);
  EXPECT_FALSE(r.header.has_normals);
  EXPECT_EQ(r.positions, corners(kQuad, {0, 1, 2, 0, 2, 3}));
}

TEST(GltfReader, NonIndexedTrianglesInGlb) {
  GltfBuilder b;
  b.mesh({GltfBuilder::primitive(b.positions(corners(kQuad, {0, 1, 2, 0, 2, 3})))});
  const auto r = read_gltf(b, "m.glb");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.header.encoding, "glb");
  EXPECT_EQ(r.positions, corners(kQuad, {0, 1, 2, 0, 2, 3}));
}

TEST(GltfReader, StripAlternatesWindingAsTheSpecSays) {
  // Triangle i is {v_i, v_(i+1+i%2), v_(i+2-i%2)}: (0,1,2), (1,3,2).
  GltfBuilder b;
  b.mesh({GltfBuilder::primitive(b.positions({kQuad[0], kQuad[1], kQuad[3], kQuad[2]}), -1, 5)});
  const auto r = read_gltf(b);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, corners(kQuad, {0, 1, 3, 1, 2, 3}));
}

TEST(GltfReader, FanTurnsAroundTheFirstVertex) {
  // Triangle i is {v_(i+1), v_(i+2), v_0}, here through an index buffer.
  GltfBuilder b;
  const int pos = b.positions(kQuad);
  b.mesh({GltfBuilder::primitive(pos, b.indices({0, 1, 2, 3}), 6)});
  const auto r = read_gltf(b);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, corners(kQuad, {1, 2, 0, 2, 3, 0}));
}

TEST(GltfReader, NodeHierarchyIsFlattenedAndMirrorsKeepFrontFaces) {
  GltfBuilder b;
  const int mesh = b.mesh({GltfBuilder::primitive(b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}))});
  // Parent: translate (10, 0, 0); child: rotate 90 degrees about z, scale 2.
  // A second root mirrors x (matrix, column-major), so its winding flips back.
  const double h = std::sqrt(0.5);
  b.doc["nodes"] = json::array({{{"translation", {10, 0, 0}}, {"children", {1}}},
                                {{"mesh", mesh}, {"rotation", {0, 0, h, h}}, {"scale", {2, 2, 2}}},
                                {{"mesh", mesh}, {"matrix", {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1}}}});
  b.doc["scenes"] = json::array({{{"nodes", {0, 2}}}});
  b.doc["scene"] = 0;
  const auto r = read_gltf(b);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  ASSERT_EQ(r.triangles(), 2u);
  const std::vector<Vec3> want = {{10, 0, 0}, {10, 2, 0}, {8, 0, 0},   // rotated, scaled, moved
                                  {0, 0, 5}, {0, 1, 5}, {-1, 0, 5}};  // mirrored: corners 1 and 2 swapped
  for (size_t i = 0; i < want.size(); ++i)
    EXPECT_NEAR(glm::distance(r.positions[i], want[i]), 0.0f, 1e-5f) << "corner " << i;
  // One mesh alone, in its own coordinates.
  const auto one = test::read_all(test::scratch_dir() / "m.gltf#meshes[0]");
  ASSERT_TRUE(one.status.is_ok()) << one.status.message();
  EXPECT_EQ(one.positions, (std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}));
}

TEST(GltfReader, QuantizedPositionsAndNormalsAreDequantised) {
  // KHR_mesh_quantization: normalized shorts (node scale 4 undoes /32767),
  // unsigned bytes unnormalized, normalized byte normals (both padded to a
  // 4-byte stride, as the spec asks).
  GltfBuilder b;
  const int pos = b.accessor(std::vector<int16_t>{0, 0, 0, 32767, 0, 0, 0, -32767, 0}, test::kShort, "VEC3", 3, true);
  const int nrm = b.accessor(std::vector<int8_t>{0, 0, 127, 0, 0, 0, 127, 0, 0, 0, -128, 0}, test::kByte, "VEC3", 3, true);
  const int upos = b.accessor(std::vector<uint8_t>{0, 0, 0, 0, 0, 3, 0, 0, 0, 0, 3, 0}, test::kUByte, "VEC3", 3);
  b.doc["bufferViews"][b.doc["accessors"][upos]["bufferView"].get<int>()]["byteStride"] = 4;  // vertex attributes align to 4
  b.doc["bufferViews"][b.doc["accessors"][nrm]["bufferView"].get<int>()]["byteStride"] = 4;
  const int mesh = b.mesh({GltfBuilder::primitive(pos, -1, 4, nrm)});
  const int mesh2 = b.mesh({GltfBuilder::primitive(upos)});
  b.doc["extensionsUsed"] = {"KHR_mesh_quantization"};
  b.doc["extensionsRequired"] = {"KHR_mesh_quantization"};
  b.doc["nodes"] = json::array({{{"mesh", mesh}, {"scale", {4, 4, 4}}}, {{"mesh", mesh2}}});
  b.doc["scenes"] = json::array({{{"nodes", {0}}}});
  const auto r = read_gltf(b);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.positions, (std::vector<Vec3>{{0, 0, 0}, {4, 0, 0}, {0, -4, 0}}));
  ASSERT_TRUE(r.header.has_normals);
  EXPECT_EQ(r.normals, (std::vector<Vec3>{{0, 0, 1}, {0, 0, 1}, {0, 0, -1}}));  // -128/127 clamps to -1
  const auto u = test::read_all(test::scratch_dir() / "m.gltf#meshes[1]");
  ASSERT_TRUE(u.status.is_ok()) << u.status.message();
  EXPECT_EQ(u.positions, (std::vector<Vec3>{{0, 0, 0}, {0, 3, 0}, {0, 0, 3}}));
}

TEST(GltfReader, DracoPrimitiveIsDecoded) {
  IndexedMesh mesh;
  mesh.positions = kQuad;
  mesh.indices = {0, 1, 2, 0, 2, 3};
  DracoOptions opt;
  opt.position_bits = 14;
  auto encoded = encode_draco("quad", mesh, opt);
  ASSERT_TRUE(encoded.is_ok()) << encoded.status().message();
  GltfBuilder b;
  const int view = b.view(encoded->bytes.data(), encoded->bytes.size());
  b.doc["accessors"].push_back({{"componentType", test::kFloat}, {"count", 4}, {"type", "VEC3"},
                                {"min", {0, 0, 0}}, {"max", {1, 1, 0}}});
  b.doc["accessors"].push_back({{"componentType", test::kUInt}, {"count", 6}, {"type", "SCALAR"}});
  json prim = GltfBuilder::primitive(0, 1);
  prim["extensions"]["KHR_draco_mesh_compression"] = {{"bufferView", view}, {"attributes", {{"POSITION", encoded->position_id}}}};
  b.mesh({prim});
  b.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  b.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  const auto r = read_gltf(b, "d.glb");
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.header.face_count, 2u);
  ASSERT_EQ(r.triangles(), 2u);
  // Edgebreaker may reorder triangles and rotate corners: compare as sets.
  for (const Vec3& p : r.positions) {
    float best = 1e9f;
    for (const Vec3& q : kQuad) best = std::min(best, glm::distance(p, q));
    EXPECT_LE(best, float(encoded->report.max_position_error));
  }
}

// A .glb of one triangle whose primitive holds `draco` bytes
// (KHR_draco_mesh_compression, its POSITION the attribute `position_id`),
// read as `name`.
auto read_draco_primitive(const std::string& draco, int position_id, const std::string& name) {
  GltfBuilder b;
  const int view = b.view(draco.data(), draco.size());
  b.doc["accessors"].push_back({{"componentType", test::kFloat}, {"count", 3}, {"type", "VEC3"},
                                {"min", {0, 0, 0}}, {"max", {1, 1, 0}}});
  b.doc["accessors"].push_back({{"componentType", test::kUInt}, {"count", 3}, {"type", "SCALAR"}});
  json prim = GltfBuilder::primitive(0, 1);
  prim["extensions"]["KHR_draco_mesh_compression"] = {{"bufferView", view},
                                                      {"attributes", {{"POSITION", position_id}}}};
  b.mesh({prim});
  b.doc["extensionsUsed"] = {"KHR_draco_mesh_compression"};
  b.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"};
  return read_gltf(b, name);
}

// A Draco primitive whose positions are stored as bools is refused with the
// primitive named: Draco would read each byte as a C++ bool, undefined for
// bytes other than 0 and 1.
TEST(GltfReader, DracoPositionsStoredAsBoolsAreRefused) {
  const test::DracoBytes mesh = test::draco_mesh_with_bools(false);
  ASSERT_FALSE(mesh.bytes.empty());
  const auto r = read_draco_primitive(mesh.bytes, mesh.position_id, "bool.glb");
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("KHR_draco_mesh_compression: the POSITION attribute does not hold numbers"),
            std::string::npos)
      << r.status.message();
}

// A Draco primitive whose header claims more triangles than its bytes can
// hold is refused before Draco allocates for them (draco_io.h,
// check_draco_counts).
TEST(GltfReader, DracoPrimitiveClaimingMoreThanItHoldsIsRefused) {
  const auto r = read_draco_primitive(test::draco_header_claiming(35, 242565077, 200), 0, "claims.glb");
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("KHR_draco_mesh_compression: the Draco header claims 242565077 triangles"),
            std::string::npos)
      << r.status.message();
}

// A Draco primitive of a bitstream before version 2 is refused unread, as a
// .drc file is: Draco allocates for its raw 32-bit counts.
TEST(GltfReader, DracoPrimitiveBeforeVersion2IsRefused) {
  const std::string bytes = std::string("DRACO\x01\x02\x01\x01\x00\x00", 11) + std::string(120, '\x06');
  const auto r = read_draco_primitive(bytes, 0, "old.glb");
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("KHR_draco_mesh_compression: Draco bitstream version 1.2 is not read"),
            std::string::npos)
      << r.status.message();
}

// A sphere as PLY, read, welded, written as .glb through the writer, read
// back: every triangle comes back within the Draco position bound.
TEST(GltfReader, PlyToGlbRoundTripWithinTheQuantisationBound) {
  std::string ply = "ply\nformat ascii 1.0\nelement vertex ";
  std::vector<Vec3> v;
  const int rings = 8, segments = 12;
  for (int r = 0; r <= rings; ++r)
    for (int s = 0; s < segments; ++s) {
      const double t = M_PI * r / rings, p = 2 * M_PI * s / segments;
      v.emplace_back(float(std::sin(t) * std::cos(p) + 100), float(std::cos(t)), float(std::sin(t) * std::sin(p)));
    }
  std::vector<uint32_t> idx;
  for (int r = 1; r < rings - 1; ++r)  // open at the poles: no degenerate triangles
    for (int s = 0; s < segments; ++s) {
      const uint32_t a = uint32_t(r * segments + s), bb = uint32_t(r * segments + (s + 1) % segments);
      const uint32_t c = a + segments, d = bb + segments;
      idx.insert(idx.end(), {a, c, bb, bb, c, d});
    }
  ply += std::to_string(v.size()) + "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(idx.size() / 3) + "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const Vec3& p : v) ply += std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) + "\n";
  for (size_t t = 0; t < idx.size(); t += 3)
    ply += "3 " + std::to_string(idx[t]) + " " + std::to_string(idx[t + 1]) + " " + std::to_string(idx[t + 2]) + "\n";
  const auto in = test::read_all(test::write_file("sphere.ply", ply));
  ASSERT_TRUE(in.status.is_ok()) << in.status.message();
  IndexedMesh mesh;
  for (const Vec3& p : in.positions) {
    auto it = std::find(mesh.positions.begin(), mesh.positions.end(), p);
    mesh.indices.push_back(uint32_t(it - mesh.positions.begin()));
    if (it == mesh.positions.end()) mesh.positions.push_back(p);
  }
  // One Draco primitive, then a part file's three parts as three primitives
  // of one glTF mesh (what `raylod run --export` writes for a large mesh).
  for (const int parts : {1, 3}) {
  DracoOptions opt;
  opt.max_position_error = 1e-4;
  opt.parts = parts;
  const auto glb = test::scratch_dir() / ("sphere-" + std::to_string(parts) + ".glb");
  auto encoded = encode_draco(glb, mesh, opt);
  ASSERT_TRUE(encoded.is_ok()) << encoded.status().message();
  const double bound = encoded->report.max_position_error;
  EXPECT_LE(bound, 1e-4);
  auto split = draco_parts(encoded->bytes.data(), encoded->bytes.size(), glb.string());
  ASSERT_TRUE(split.is_ok()) << split.status().message();
  ASSERT_EQ(split->size(), size_t(parts));
  GlbMesh sphere{"sphere", std::vector<char>((*split)[0].begin(), (*split)[0].end()), {}};
  for (size_t p = 1; p < split->size(); ++p) sphere.more_parts.emplace_back((*split)[p].begin(), (*split)[p].end());
  std::vector<GlbMesh> meshes{sphere};
  auto written = write_glb(glb, meshes, {GlbNode{"sphere", 0, glm::dmat4(1.0)}});
  ASSERT_TRUE(written.is_ok()) << written.status().message();
  const auto out = test::read_all(glb);
  ASSERT_TRUE(out.status.is_ok()) << out.status.message();
  ASSERT_EQ(out.triangles(), in.triangles());
  // Every input triangle has an output triangle with the same corners (in
  // some rotation, same winding) within the bound.
  std::vector<bool> used(out.triangles(), false);
  for (size_t t = 0; t < in.triangles(); ++t) {
    bool found = false;
    for (size_t u = 0; u < out.triangles() && !found; ++u) {
      if (used[u]) continue;
      for (int rot = 0; rot < 3 && !found; ++rot) {
        bool all = true;
        for (int k = 0; k < 3; ++k)
          all = all && glm::distance(Vec3d(in.positions[3 * t + size_t(k)]), Vec3d(out.positions[3 * u + size_t((k + rot) % 3)])) <= bound;
        if (all) found = used[u] = true;
      }
    }
    EXPECT_TRUE(found) << parts << " parts: input triangle " << t << " has no output triangle within " << bound;
  }
  }
}

TEST(GltfReader, PointsAndLinesAreSkippedButNotAlone) {
  GltfBuilder b;
  const int pos = b.positions(kQuad);
  b.mesh({GltfBuilder::primitive(pos, -1, 1), GltfBuilder::primitive(pos, b.indices({0, 1, 2}))});
  const auto r = read_gltf(b);
  ASSERT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.triangles(), 1u);
  GltfBuilder lines;
  lines.mesh({GltfBuilder::primitive(lines.positions(kQuad), -1, 1), GltfBuilder::primitive(0, -1, 0)});
  const std::string e = test::read_error(test::write_file("lines.gltf", lines.gltf()));
  EXPECT_NE(e.find("lines.gltf"), std::string::npos) << e;
  EXPECT_NE(e.find("no triangle primitive"), std::string::npos) << e;
}

// The error of reading `bytes` as NAME, which must name the file and say `what`.
void expect_error(const std::string& name, const std::string& bytes, const std::string& what) {
  const std::string e = test::read_error(test::write_file(name, bytes));
  EXPECT_NE(e.find(name), std::string::npos) << e;
  EXPECT_NE(e.find(what), std::string::npos) << "expected '" << what << "' in: " << e;
}

GltfBuilder triangle_file() {
  GltfBuilder b;
  const int pos = b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  b.mesh({GltfBuilder::primitive(pos, b.indices({0, 1, 2}))});
  return b;
}

TEST(GltfReaderErrors, TruncatedGlbChunks) {
  const std::string glb = triangle_file().glb();
  expect_error("short.glb", glb.substr(0, 10), "truncated GLB");
  expect_error("cut.glb", glb.substr(0, glb.size() - 8), "truncated GLB");
  std::string claims = glb;  // the JSON chunk claims more than the file holds; the header agrees with the size
  const uint32_t huge = 1u << 30;
  std::memcpy(&claims[12], &huge, 4);
  expect_error("claims.glb", claims, "the JSON chunk at offset 12 claims 1073741824 bytes");
}

TEST(GltfReaderErrors, AccessorPastTheEndOfItsBufferView) {
  GltfBuilder b = triangle_file();
  b.doc["accessors"][0]["count"] = 5;
  expect_error("acc.gltf", b.gltf(), "meshes[0].primitives[0]: accessor 0 (POSITION) (count 5, byteOffset 0) ends at byte 60, past the end of bufferView 0 (36 bytes)");
}

TEST(GltfReaderErrors, BufferViewPastTheEndOfItsBuffer) {
  GltfBuilder b = triangle_file();
  b.doc["bufferViews"][1]["byteOffset"] = 1000;
  expect_error("view.glb", b.glb(), "bufferView 1 (bytes 1000 + 12) is past the end of buffer 0");
}

TEST(GltfReaderErrors, IndexOutOfRange) {
  GltfBuilder b;
  const int pos = b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  b.mesh({GltfBuilder::primitive(pos, b.indices({0, 1, 7}))});
  expect_error("index.gltf", b.gltf(), "index 7 (indices element 2) is out of range: POSITION has 3 elements");
}

TEST(GltfReaderErrors, TypesAreNamedAsTheFileWritesThem) {
  GltfBuilder b;
  const int pos = b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  const int idx = b.accessor(std::vector<float>{0, 1, 2}, test::kFloat, "SCALAR", 3);
  b.mesh({GltfBuilder::primitive(pos, idx)});
  expect_error("float_indices.gltf", b.gltf(), "accessor 1 (indices) has type SCALAR with component type FLOAT (5126)");
}

TEST(GltfReaderErrors, MissingAccessorBufferAndExternalFile) {
  GltfBuilder b = triangle_file();
  b.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 9;
  expect_error("noacc.gltf", b.gltf(), "accessor 9 (POSITION) does not exist");
  GltfBuilder ext = triangle_file();
  expect_error("external.gltf", ext.with_buffer("missing.bin").dump(), "missing.bin");
  // The external file present: it reads.
  test::write_file("present.bin", ext.bin);
  const auto r = test::read_all(test::write_file("present.gltf", ext.with_buffer("present.bin").dump()));
  EXPECT_TRUE(r.status.is_ok()) << r.status.message();
  EXPECT_EQ(r.triangles(), 1u);
  // A path that leads out of the glTF file's folder is not followed, though
  // the file is there (it was read).
  std::filesystem::create_directories(test::scratch_dir() / "sub");
  const auto escape = test::write_file("sub/escape.gltf", ext.with_buffer("../present.bin").dump());
  const auto out = test::read_all(escape);
  ASSERT_FALSE(out.status.is_ok());
  EXPECT_NE(out.status.message().find("external files are looked for only in the glTF file's folder"), std::string::npos)
      << out.status.message();
  EXPECT_NE(out.status.message().find("present.bin is outside it"), std::string::npos) << out.status.message();
  // Within it, "./" and a subfolder's "../" are fine.
  test::write_file("sub/inner.bin", ext.bin);
  EXPECT_TRUE(test::read_all(test::write_file("sub/dot.gltf", ext.with_buffer("./inner.bin").dump())).status.is_ok());
  std::filesystem::create_directories(test::scratch_dir() / "sub" / "deeper");
  EXPECT_TRUE(
      test::read_all(test::write_file("sub/up.gltf", ext.with_buffer("deeper/../inner.bin").dump())).status.is_ok());
}

TEST(GltfReaderErrors, NonFiniteAndOutOfRangeCoordinates) {
  GltfBuilder nan;
  nan.mesh({GltfBuilder::primitive(nan.positions({{0, 0, 0}, {NAN, 0, 0}, {0, 1, 0}}))});
  expect_error("nan.gltf", nan.gltf(), "meshes[0].primitives[0]: POSITION element 1 is not finite");
  GltfBuilder big = triangle_file();
  big.doc["nodes"] = json::array({{{"mesh", 0}, {"scale", {1e38, 1e38, 1e38}}, {"translation", {3e38, 0, 0}}}});
  big.doc["scenes"] = json::array({{{"nodes", {0}}}});
  expect_error("big.gltf", big.gltf(), "beyond the float range");
}

TEST(GltfReaderErrors, UnsupportedThingsAreNamed) {
  GltfBuilder sparse = triangle_file();
  sparse.doc["accessors"][0]["sparse"] = {{"count", 1}, {"indices", {{"bufferView", 1}, {"componentType", test::kUInt}}},
                                          {"values", {{"bufferView", 0}}}};
  expect_error("sparse.gltf", sparse.gltf(), "sparse accessors are not supported");
  GltfBuilder meshopt = triangle_file();
  meshopt.doc["extensionsRequired"] = {"EXT_meshopt_compression"};
  meshopt.doc["extensionsUsed"] = {"EXT_meshopt_compression"};
  expect_error("meshopt.gltf", meshopt.gltf(), "'EXT_meshopt_compression' is not supported");
  GltfBuilder mode = triangle_file();
  mode.doc["meshes"][0]["primitives"][0]["mode"] = 9;
  expect_error("mode.gltf", mode.gltf(), "mode 9 is not a glTF primitive mode");
  expect_error("junk.gltf", "{\"asset\": ", "junk.gltf");
  GltfBuilder cycle = triangle_file();
  cycle.doc["nodes"] = json::array({{{"mesh", 0}, {"children", {1}}}, {{"children", {0}}}});
  cycle.doc["scenes"] = json::array({{{"nodes", {0}}}});
  expect_error("cycle.gltf", cycle.gltf(), "cycle");
}

TEST(GltfDescribe, ListsMeshesWithTriangleCountsAndInstances) {
  GltfBuilder b;
  const int pos = b.positions(kQuad);
  b.mesh({GltfBuilder::primitive(pos, b.indices({0, 1, 2, 0, 2, 3}))}, "plate");
  b.mesh({GltfBuilder::primitive(pos, -1, 5), GltfBuilder::primitive(pos, -1, 1)}, "strip");
  b.doc["materials"] = json::array({{{"name", "red"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.1, 0.1, 1}}}}},
                                    {{"pbrMetallicRoughness", {{"metallicFactor", 1.0}, {"roughnessFactor", 0.0}}}}});
  b.doc["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc["meshes"][1]["primitives"][0]["material"] = 1;
  b.doc["nodes"] = json::array({{{"mesh", 0}}, {{"mesh", 1}, {"translation", {0, 0, 2}}}, {{"mesh", 1}}});
  b.doc["scenes"] = json::array({{{"nodes", {0, 1, 2}}}});
  auto s = describe_gltf(test::write_file("two.glb", b.glb()));
  ASSERT_TRUE(s.is_ok()) << s.status().message();
  ASSERT_EQ(s->meshes.size(), 2u);
  EXPECT_EQ(s->meshes[0].name, "plate");
  EXPECT_EQ(s->meshes[0].triangles, 2u);
  EXPECT_EQ(s->meshes[0].instances, 1u);
  EXPECT_EQ(s->meshes[1].triangles, 2u);
  EXPECT_EQ(s->meshes[1].skipped_primitives, 1u);
  EXPECT_EQ(s->meshes[1].instances, 2u);
  ASSERT_EQ(s->instances.size(), 3u);
  EXPECT_EQ(s->instances[1].transform[3][2], 2.0);
  EXPECT_TRUE(s->materials[0].has_base_color);
  EXPECT_FALSE(s->materials[0].mirror);
  EXPECT_TRUE(s->materials[1].mirror);
}

// The files a .gltf's buffers name, resolved beside it and percent-decoded;
// data URIs and a .glb's own chunk name none.
TEST(GltfExternal, BuffersBesideTheFileAreListed) {
  GltfBuilder b;
  b.mesh({GltfBuilder::primitive(b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}))});
  json doc = b.with_buffer("my%20tri.bin");
  doc["buffers"].push_back({{"byteLength", 4}, {"uri", "data:application/octet-stream;base64,AAAAAA=="}});
  doc["buffers"].push_back({{"byteLength", 4}, {"uri", "my%20tri.bin"}});  // the same file again: listed once
  const auto gltf = test::write_file("listed.gltf", doc.dump());
  const auto found = gltf_external_buffers(gltf);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0], gltf.parent_path() / "my tri.bin");
  EXPECT_TRUE(gltf_external_buffers(test::write_file("inline.gltf", b.gltf())).empty());
  EXPECT_TRUE(gltf_external_buffers(test::write_file("own.glb", b.glb())).empty());
  EXPECT_TRUE(gltf_external_buffers(test::write_file("broken.gltf", "{\"buffers\": [")).empty());
}

// Editing the .bin beside a .gltf (same size and modification time, other
// content) makes its store stale, even once a check record vouched for the
// mesh, and the rebuilt store holds the new geometry.
TEST(GltfExternal, EditingTheBinMakesTheStoreStale) {
  Progress::set_enabled(false);
  GltfBuilder b;
  b.mesh({GltfBuilder::primitive(b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}))});
  const auto bin = test::write_file("tri.bin", b.bin);
  const auto gltf = test::write_file("tri.gltf", b.with_buffer("tri.bin").dump());
  const auto store = default_store_path(gltf);
  StoreOptions opt;
  opt.memory_limit = 64 << 20;
  // A check record is written only for files last changed a second before.
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  auto built = build_store(gltf, store, opt);
  ASSERT_TRUE(built.is_ok()) << built.status().message();
  std::string why;
  ASSERT_TRUE(store_is_current(gltf, store, opt, &why)) << why;
  EXPECT_NE(why.find("last content check"), std::string::npos) << why;

  struct stat before {};
  ASSERT_EQ(::stat(bin.c_str(), &before), 0);
  std::string moved = b.bin;
  const float x = 5.0f;
  std::memcpy(&moved[12], &x, 4);  // the second corner's x: 1 -> 5
  test::write_file("tri.bin", moved);
  struct timespec times[2] = {before.st_atim, before.st_mtim};
  ASSERT_EQ(::utimensat(AT_FDCWD, bin.c_str(), times, 0), 0);
  EXPECT_FALSE(store_is_current(gltf, store, opt, &why));
  EXPECT_NE(why.find("content"), std::string::npos) << why;

  auto rebuilt = build_store(gltf, store, opt);
  ASSERT_TRUE(rebuilt.is_ok()) << rebuilt.status().message();
  EXPECT_FALSE(rebuilt->reused);
  auto opened = OctreeStore::open(store);
  ASSERT_TRUE(opened.is_ok()) << opened.status().message();
  EXPECT_FLOAT_EQ(float((*opened)->header().bounds.hi.x), 5.0f);
}

}  // namespace
}  // namespace raylod
