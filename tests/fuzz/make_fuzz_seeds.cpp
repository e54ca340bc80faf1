// Writes the generated part of the fuzz seed corpora: tiny valid files of
// every format the fuzz targets read, one folder per target under the output
// folder (the CMake build folder; data/ holds no PLY, OBJ, Draco, store or
// cut files). Usage: make_fuzz_seeds OUT_DIR
#include <cmath>
#include <cstring>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "streaming/cut_file.h"
#include "streaming/draco_io.h"
#include "streaming/gltf_io.h"
#include "../streaming/gltf_test_util.h"
#include "streaming/mesh_writer.h"
#include "streaming/octree_store.h"

namespace {

using namespace raylod;
namespace fs = std::filesystem;

void write_bytes(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), std::streamsize(bytes.size()));
  if (!f) throw std::runtime_error(path.string() + ": write failed");
}

std::string read_bytes(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void check(const Status& s) {
  if (!s) throw std::runtime_error(s.message());
}

// A bumpy n x n grid of quads as independent triangles with unit normals.
TriangleBatch grid(int n) {
  TriangleBatch b;
  auto at = [n](int i, int j) {
    const float x = float(i) / float(n), z = float(j) / float(n);
    return Vec3(x, 0.1f * std::sin(6 * x) * std::cos(5 * z), z);
  };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Vec3 q[4] = {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)};
      for (int t : {0, 2}) {
        const Vec3 a = q[0], c = q[t == 0 ? 1 : 2], d = q[t == 0 ? 2 : 3];
        const Vec3 nrm = glm::normalize(glm::cross(d - a, c - a));
        for (const Vec3& p : {a, c, d}) {
          b.positions.push_back(p);
          b.normals.push_back(nrm);
        }
      }
    }
  return b;
}

void write_mesh(const fs::path& path, const TriangleBatch& b, bool normals) {
  fs::create_directories(path.parent_path());
  auto w = create_mesh_writer(path, WriterOptions{normals});
  check(w.status());
  check((*w)->write(b));
  check((*w)->finish());
}

template <class T>
void put_be(std::string& s, T v) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  for (size_t i = sizeof(T); i-- > 0;) s.push_back(char(b[i]));
}

}  // namespace

int main(int argc, char** argv) try {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_fuzz_seeds OUT_DIR\n");
    return 2;
  }
  const fs::path out = argv[1];
  const TriangleBatch small = grid(2), larger = grid(8);

  // PLY: binary little endian (the writer), ASCII and big endian by hand, with quads and a pentagon.
  write_mesh(out / "ply" / "grid-normals.ply", small, true);
  write_mesh(out / "ply" / "grid.ply", small, false);
  const std::string head = "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                           "property float nx\nproperty float ny\nproperty float nz\n"
                           "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
  const float v[5][6] = {{0, 0, 0, 0, 0, 1}, {1, 0, 0, 0, 0, 1}, {1, 1, 0, 0, 0, 1}, {0, 1, 0, 0, 0, 1}, {0.5f, 2, 0, 0, 1, 0}};
  std::string ascii = "ply\nformat ascii 1.0\ncomment seed\n" + head;
  std::string be = "ply\nformat binary_big_endian 1.0\n" + head;
  for (const auto& r : v) {
    for (float c : r) {
      ascii += std::to_string(c) + " ";
      put_be(be, c);
    }
    ascii += "\n";
  }
  ascii += "4 0 1 2 3\n5 0 1 2 4 3\n";
  for (std::vector<int> face : {std::vector<int>{0, 1, 2, 3}, std::vector<int>{0, 1, 2, 4, 3}}) {
    be.push_back(char(face.size()));
    for (int i : face) put_be(be, int32_t(i));
  }
  write_bytes(out / "ply" / "polygons.ascii.ply", ascii);
  write_bytes(out / "ply" / "polygons.be.ply", be);

  // STL: binary from the writer and ASCII (data/stl-models adds more).
  write_mesh(out / "stl" / "grid.stl", small, false);
  write_bytes(out / "stl" / "two.ascii.stl",
              "solid seed\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 1 1 0\n endloop\nendfacet\n"
              "facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 1 0\n  vertex 0 1 0\n endloop\nendfacet\nendsolid seed\n");

  // OBJ: positions, texture coordinates, normals, relative indices, a quad, comments, groups.
  write_bytes(out / "obj" / "quads.obj",
              "# seed\no seed\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\nvt 0 0\nvt 1 1\nvn 0 0 1\nvn 0 1 0\n"
              "g a\nf 1/1/1 2/2/1 3/1/1 4/2/2\nf -1//-2 -2//-1 -3//-1\n");
  write_bytes(out / "obj" / "plain.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nf 1 2 3\nf 2 4 3\n");

  // Draco: the simplified-mesh writer's output, with and without normals.
  IndexedMesh indexed;
  for (size_t i = 0; i < larger.positions.size(); ++i) {
    indexed.positions.push_back(larger.positions[i]);
    indexed.normals.push_back(larger.normals[i]);
    indexed.indices.push_back(uint32_t(i));
  }
  fs::create_directories(out / "draco");
  check(write_draco(out / "draco" / "grid-normals.drc", indexed, DracoOptions{}).status());
  indexed.normals.clear();
  DracoOptions coarse;
  coarse.position_bits = 8;
  check(write_draco(out / "draco" / "grid.drc", indexed, coarse).status());
  DracoOptions parts = coarse;  // a part file (draco_io.h) of three bitstreams
  parts.parts = 3;
  check(write_draco(out / "draco" / "grid-parts.drc", indexed, parts).status());

  // glTF: a .glb as raylod writes it (a Draco primitive), a .gltf with a
  // data URI (indexed triangles with normals, a strip, a node hierarchy) and
  // a quantized .glb (KHR_mesh_quantization, a fan).
  {
    fs::create_directories(out / "gltf");
    DracoOptions o;
    auto encoded = encode_draco(out / "gltf" / "draco.glb", indexed, o);
    check(encoded.status());
    check(write_glb(out / "gltf" / "draco.glb", {GlbMesh{"grid", encoded.value().bytes, {}}},
                    {GlbNode{"grid", 0, glm::dmat4(1.0)}}).status());
    test::GltfBuilder b;
    std::vector<Vec3> p(small.positions.begin(), small.positions.end()), n(small.normals.begin(), small.normals.end());
    const int pos = b.positions(p);
    std::vector<float> nf;
    for (const Vec3& v : n) nf.insert(nf.end(), {v.x, v.y, v.z});
    const int nrm = b.accessor(nf, test::kFloat, "VEC3", n.size());
    std::vector<uint16_t> idx;
    for (size_t i = 0; i < p.size(); ++i) idx.push_back(uint16_t(i));
    const int ind = b.accessor(idx, test::kUShort, "SCALAR", idx.size());
    b.mesh({test::GltfBuilder::primitive(pos, ind, 4, nrm), test::GltfBuilder::primitive(pos, -1, 5)}, "grid");
    b.doc["nodes"] = nlohmann::json::array({{{"translation", {1, 2, 3}}, {"children", {1}}},
                                            {{"mesh", 0}, {"rotation", {0, 0.6, 0, 0.8}}, {"scale", {2, 1, 1}}}});
    b.doc["scenes"] = nlohmann::json::array({{{"nodes", {0}}}});
    b.doc["materials"] = nlohmann::json::array({{{"pbrMetallicRoughness", {{"baseColorFactor", {0.5, 0.2, 0.1, 1}}}}}});
    b.doc["meshes"][0]["primitives"][0]["material"] = 0;
    write_bytes(out / "gltf" / "hierarchy.gltf", b.gltf());
    test::GltfBuilder q;
    const int qp = q.accessor(std::vector<int16_t>{0, 0, 0, 0, 32767, 0, 0, 0, 0, 32767, 0, 0, 32767, 32767, 0, 0},
                              test::kShort, "VEC3", 4, true);
    q.doc["bufferViews"][0]["byteStride"] = 8;
    q.mesh({test::GltfBuilder::primitive(qp, -1, 6)});
    q.doc["extensionsUsed"] = {"KHR_mesh_quantization"};
    q.doc["extensionsRequired"] = {"KHR_mesh_quantization"};
    q.doc["nodes"] = nlohmann::json::array({{{"mesh", 0}, {"scale", {10, 10, 10}}}});
    q.doc["scenes"] = nlohmann::json::array({{{"nodes", {0}}}});
    write_bytes(out / "gltf" / "quantized.glb", q.glb());
  }

  // Store: built from a grid PLY with small pages, so that it has several levels and pages.
  // The first byte of a store or cut seed is the target's mode (0 as is, 1 checksums repaired).
  const fs::path work = out / "work";
  write_mesh(work / "grid.ply", larger, true);
  StoreOptions so;
  so.memory_limit = 64 << 20;
  so.max_depth = 4;
  so.page_triangles = 16;
  check(build_store(work / "grid.ply", work / "grid.raylod", so).status());
  const std::string store = read_bytes(work / "grid.raylod");
  write_bytes(out / "store" / "grid-as-is.raylod", std::string(1, '\0') + store);
  write_bytes(out / "store" / "grid-repaired.raylod", std::string(1, '\1') + store);

  // Cut: a few cells at different levels, with counters.
  Cut cut;
  cut.store_hash = 0x1234;
  cut.store_path = "grid.raylod";
  cut.key = "seed";
  cut.rays = 5000;
  cut.seed = 1;
  cut.min_footprint = 0.01f;
  cut.counters = {{"hits", 4000}, {"rays_primary", 5000}};
  cut.cells = {{{2, 1}, 0.02f, 10}, {{2, 5}, 0.03f, 7}, {{3, 0}, 0.f, 0}, {{3, 7}, 0.05f, 1}};
  check(write_cut(work / "seed.cut", cut));
  const std::string cut_bytes = read_bytes(work / "seed.cut");
  write_bytes(out / "cut" / "seed-as-is.cut", std::string(1, '\0') + cut_bytes);
  write_bytes(out / "cut" / "seed-repaired.cut", std::string(1, '\1') + cut_bytes);
  fs::remove_all(work);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "make_fuzz_seeds: %s\n", e.what());
  return 1;
}
