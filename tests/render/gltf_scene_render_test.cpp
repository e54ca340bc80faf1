// A scene naming a multi-mesh glTF (node hierarchy, a mesh used twice, a
// base-colour material and a mirror material) expands to one object per node
// instance and renders like the equivalent scene file written by hand with
// PLY meshes, transforms and materials.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include <glm/gtc/matrix_transform.hpp>

#include "render_test_util.h"
#include "streaming/gltf_test_util.h"

namespace raylod {
namespace {

using nlohmann::json;

// A closed box and an octahedron, wound outward.
std::vector<Vec3> box_soup() {
  const Vec3 v[8] = {{-0.5f, -0.5f, -0.5f}, {0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, -0.5f}, {-0.5f, 0.5f, -0.5f},
                     {-0.5f, -0.5f, 0.5f},  {0.5f, -0.5f, 0.5f},  {0.5f, 0.5f, 0.5f},  {-0.5f, 0.5f, 0.5f}};
  const int f[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
                        {3, 6, 2}, {3, 7, 6}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
  std::vector<Vec3> out;
  for (const auto& t : f)
    for (int k = 0; k < 3; ++k) out.push_back(v[t[k]]);
  return out;
}
std::vector<Vec3> octahedron_soup() {
  const Vec3 x(0.5f, 0, 0), y(0, 0.5f, 0), z(0, 0, 0.5f);
  std::vector<Vec3> out;
  for (int sx = -1; sx <= 1; sx += 2)
    for (int sy = -1; sy <= 1; sy += 2)
      for (int sz = -1; sz <= 1; sz += 2) {
        Vec3 a = float(sx) * x, b = float(sy) * y, c = float(sz) * z;
        if (sx * sy * sz < 0) std::swap(b, c);
        out.insert(out.end(), {a, b, c});
      }
  return out;
}

void write_ply(const std::filesystem::path& path, const std::vector<Vec3>& soup) {
  std::ofstream out(path);
  out << "ply\nformat ascii 1.0\nelement vertex " << soup.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nelement face " << soup.size() / 3
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  char line[128];
  for (const Vec3& p : soup) {
    std::snprintf(line, sizeof line, "%.9g %.9g %.9g\n", double(p.x), double(p.y), double(p.z));
    out << line;
  }
  for (size_t t = 0; t < soup.size(); t += 3) out << "3 " << t << " " << t + 1 << " " << t + 2 << "\n";
}

const char* kCommon = R"("camera": {"eye": [0, 2.5, 5], "look_at": [0, 0.5, 0], "fov_y": 40, "width": 96, "height": 72},
  "ground": {"height": 0, "size": 20, "material": "floor"},
  "lights": [{"type": "point", "position": [3, 6, 4], "intensity": 60}],
  "background": [0.55, 0.65, 0.8], "spp": 2, "max_depth": 3, "seed": 3, "crease_angle": 20)";

TEST(GltfScene, MultiMeshGlbRendersLikeTheEquivalentSceneFile) {
  const auto dir = testing::test_tmp("gltf-scene");
  test::GltfBuilder b;
  const std::vector<Vec3> box = box_soup(), octa = octahedron_soup();
  b.mesh({test::GltfBuilder::primitive(b.positions(box))}, "box");
  b.mesh({test::GltfBuilder::primitive(b.positions(octa))}, "octahedron");
  b.doc["meshes"][0]["primitives"][0]["material"] = 0;
  b.doc["meshes"][1]["primitives"][0]["material"] = 1;
  b.doc["materials"] = json::array({{{"name", "red"}, {"pbrMetallicRoughness", {{"baseColorFactor", {0.8, 0.1, 0.1, 1}}}}},
                                    {{"name", "chrome"}, {"pbrMetallicRoughness", {{"metallicFactor", 1.0}, {"roughnessFactor", 0.0}}}}});
  const double s45 = std::sqrt(0.5);
  // Parent: move and turn 90 degrees about y; child: the box at scale 0.8.
  // The octahedron twice: beside it, and smaller behind.
  b.doc["nodes"] = json::array({{{"translation", {-1, 0.5, 0}}, {"rotation", {0, s45, 0, s45}}, {"children", {1}}},
                                {{"mesh", 0}, {"scale", {0.8, 0.8, 0.8}}},
                                {{"mesh", 1}, {"translation", {1, 0.7, 0}}},
                                {{"mesh", 1}, {"translation", {0, 0.5, -1.5}}, {"scale", {0.5, 0.5, 0.5}}}});
  b.doc["scenes"] = json::array({{{"nodes", {0, 2, 3}}}});
  b.doc["scene"] = 0;
  {
    std::ofstream(dir / "parts.glb", std::ios::binary) << b.glb();
  }
  write_ply(dir / "box.ply", box);
  write_ply(dir / "octahedron.ply", octa);
  std::ofstream(dir / "gltf.json") << "{" << kCommon << R"(,
    "materials": {"grey": {"type": "diffuse", "color": [0.7, 0.7, 0.7]}, "floor": {"type": "diffuse", "color": [0.6, 0.6, 0.55]}},
    "objects": [{"mesh": "parts.glb", "material": "grey"}]})";
  std::ofstream(dir / "hand.json") << "{" << kCommon << R"(,
    "materials": {"red": {"type": "diffuse", "color": [0.8, 0.1, 0.1]}, "chrome": {"type": "mirror", "reflectance": 1},
                  "floor": {"type": "diffuse", "color": [0.6, 0.6, 0.55]}},
    "objects": [{"mesh": "box.ply", "material": "red", "transform": {"translate": [-1, 0.5, 0], "rotate_deg": [0, 90, 0], "scale": 0.8}},
                {"mesh": "octahedron.ply", "material": "chrome", "transform": {"translate": [1, 0.7, 0]}},
                {"mesh": "octahedron.ply", "material": "chrome", "transform": {"translate": [0, 0.5, -1.5], "scale": 0.5}}]})";

  auto from_gltf = load_scene(dir / "gltf.json");
  ASSERT_TRUE(from_gltf.is_ok()) << from_gltf.status().message();
  ASSERT_EQ(from_gltf->objects.size(), 3u);
  EXPECT_EQ(from_gltf->objects[0].mesh.filename().string(), "parts.glb#meshes[0]");
  EXPECT_EQ(from_gltf->objects[2].mesh, from_gltf->objects[1].mesh);  // one mesh, two instances
  EXPECT_EQ(from_gltf->materials[size_t(from_gltf->objects[0].material)].color, Vec3(0.8f, 0.1f, 0.1f));
  EXPECT_EQ(from_gltf->materials[size_t(from_gltf->objects[1].material)].type, MaterialType::Mirror);
  auto by_hand = load_scene(dir / "hand.json");
  ASSERT_TRUE(by_hand.is_ok()) << by_hand.status().message();

  auto a = render(*from_gltf, testing::quiet_options());
  ASSERT_TRUE(a.is_ok()) << a.status().message();
  auto r = render(*by_hand, testing::quiet_options());
  ASSERT_TRUE(r.is_ok()) << r.status().message();
  const Image& ia = a->color;
  const Image& ir = r->color;
  ASSERT_EQ(ia.pixels.size(), ir.pixels.size());
  size_t differ = 0, lit = 0;
  for (size_t i = 0; i < ia.pixels.size(); ++i) {
    if (std::fabs(ia.pixels[i] - ir.pixels[i]) > 1.0f / 255.0f) ++differ;
    if (ia.pixels[i] != ir.pixels[i]) ++lit;
  }
  if (differ > 0) {
    EXPECT_TRUE(write_image(dir / "gltf.png", ia).is_ok());
    EXPECT_TRUE(write_image(dir / "hand.png", ir).is_ok());
  }
  // The transforms agree to rounding (quaternion against Euler angles), so
  // at most a few silhouette samples may land differently.
  EXPECT_LE(differ, ia.pixels.size() / 500) << differ << " channel values differ by more than 1/255 (" << lit
                                            << " differ at all)";
  // And the scene is not empty: the objects cover part of the image.
  auto bare = load_scene(dir / "hand.json");
  bare->objects.resize(1);
  bare->objects[0].transform = glm::translate(glm::dmat4(1.0), glm::dvec3(0, -100, 0));  // out of sight
  auto empty = render(*bare, testing::quiet_options());
  ASSERT_TRUE(empty.is_ok()) << empty.status().message();
  size_t changed = 0;
  for (size_t i = 0; i < ia.pixels.size(); ++i) changed += std::fabs(ia.pixels[i] - empty->color.pixels[i]) > 0.05f;
  EXPECT_GT(changed, ia.pixels.size() / 20);
}

}  // namespace
}  // namespace raylod
