// The JSON scene format (documented in README.md, "Scene files").
//
// {
//   "camera": {"eye": [x,y,z], "look_at": [x,y,z], "up": [0,1,0],
//              "fov_y": 40, "width": 1280, "height": 960},
//   "materials": {"name": {"type": "diffuse"|"glossy"|"mirror"|"glass",
//                          "color": [r,g,b], "specular": [r,g,b], "shininess": 50,
//                          "reflectance": 1.0, "ior": 1.5, "tint": [r,g,b]}},
//   "objects": [{"mesh": "teapot.ply" | {"generate": "teapot", "triangles": 1000000},
//                "material": "name", "transform": {"translate": [..], "scale": s | [..],
//                "rotate_deg": [..xyz Euler..]} | "matrix": [16 numbers, row-major]}],
//   "ground": {"height": 0, "size": 40, "material": "name"},
//   "lights": [{"type": "point", "position": [..], "color": [..], "intensity": 100},
//              {"type": "directional", "direction": [..], "color": [..], "intensity": 1}],
//   "background": [r,g,b], "spp": 4, "max_depth": 5, "seed": 1
// }
// Relative mesh paths resolve against the scene file's directory.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/math.h"
#include "core/status.h"
#include "geometry/crease_normals.h"

namespace raylod {

struct Camera {
  Vec3d eye{0, 0, 5};
  Vec3d look_at{0, 0, 0};
  Vec3d up{0, 1, 0};
  double fov_y_deg = 40;
  int width = 640;
  int height = 480;
};

enum class MaterialType { Diffuse, Glossy, Mirror, Glass };
const char* to_string(MaterialType t);

struct Material {
  std::string name;
  MaterialType type = MaterialType::Diffuse;
  Vec3 color{0.8f};        // diffuse albedo
  Vec3 specular{0.0f};     // Phong specular colour (glossy)
  float shininess = 50;    // Phong exponent (glossy)
  float reflectance = 1;   // mirror reflectance
  float ior = 1.5f;        // glass index of refraction
  Vec3 tint{1.0f};         // glass transmission tint
  bool reflects() const { return type == MaterialType::Mirror || type == MaterialType::Glass; }
  bool refracts() const { return type == MaterialType::Glass; }
};

// A mesh to generate on first use (the embedded default scene), cached by
// (generator, triangle count).
struct GeneratedMesh {
  std::string generator;   // "teapot" or "bottle"
  uint64_t triangles = 0;
};

struct SceneObject {
  std::filesystem::path mesh;             // resolved path (empty if generated)
  std::optional<GeneratedMesh> generate;  // set when the mesh is generated
  glm::dmat4 transform{1.0};              // object to world
  int material = 0;                        // index into Scene::materials
};

enum class LightType { Point, Directional };
struct Light {
  LightType type = LightType::Point;
  Vec3d position{0};     // point
  Vec3d direction{0, -1, 0};  // directional: direction light travels
  Vec3 color{1.0f};
  float intensity = 1;
};

// An optional ground plane (y = height), a square of side `size` centred under
// the camera's look-at point; two triangles, never simplified.
struct Ground {
  double height = 0;
  double size = 40;
  int material = 0;
};

struct Scene {
  std::filesystem::path source;  // the scene file (empty for the embedded default)
  Camera camera;
  std::vector<Material> materials;
  std::vector<SceneObject> objects;
  std::vector<Light> lights;
  std::optional<Ground> ground;
  Vec3 background{0.0f};
  int spp = 1;
  int max_depth = 5;
  uint64_t seed = 1;
  // Shading normals for meshes without their own (geometry/crease_normals.h):
  // facets meeting at more than this many degrees are shaded as a crease.
  double crease_angle_deg = kDefaultCreaseAngleDeg;
  // The renderer's frame (render/renderer.h, in_render_frame): it subtracts
  // this point, in double, from every world position before Embree sees
  // floats, so a scene far from zero keeps its detail: the camera's look-at
  // point rounded to integers (render_origin_for). Set by parse_scene;
  // views of the scene (copies with another camera) keep it.
  Vec3d render_origin{0};

  // Whether the renderer ever traces a reflected or refracted ray from a
  // surface of material m: glass, or a mirror of some reflectance, with
  // max_depth above 0. What the cut holds for mirrors and glass (their
  // normals' turn, exact normals, fold passes) applies only then: a mirror
  // of reflectance 0 or a scene of max_depth 0 shades like any other.
  bool traces_specular(const Material& m) const;
  bool any_reflection() const;
  bool any_refraction() const;
  // Whether shadows can show on the ground: there is a ground, it does not
  // reflect (a mirror floor shows what it reflects, not shadows), and some
  // light casts them.
  bool ground_shows_shadows() const;
};

// A transform's rotate_deg (XYZ Euler angles in degrees) applied to m: m
// times the rotation about Z, then Y, then X (X applied to a point first).
glm::dmat4 rotate_euler_deg(const glm::dmat4& m, const Vec3d& deg);

// The renderer's frame for a camera looking at `look_at`: that point
// rounded to integers, at any distance from zero. (Only from 4096 on, as a
// reader's local origin, left a 0.2-unit part 100 to 4000 units out with
// jagged edges and self-shadowing: 47.1 to 27.5 dB against the same part at
// zero.) Non-finite: (0, 0, 0).
Vec3d render_origin_for(const Vec3d& look_at);

// Parses a scene from JSON text; base_dir resolves relative mesh paths and
// source_name is used in error messages. Checks referenced mesh files exist,
// except the first object's when first_mesh_replaced (a command's --mesh
// stands in for it): a scene whose own mesh is not on this machine can then
// still be rendered with another.
StatusOr<Scene> parse_scene(const std::string& json_text, const std::filesystem::path& base_dir,
                            const std::string& source_name, bool first_mesh_replaced = false);
StatusOr<Scene> load_scene(const std::filesystem::path& path, bool first_mesh_replaced = false);
// `--mesh FILE` of render and run: FILE (a regular file) in place of the
// first object's mesh, which is then never generated.
Status replace_first_mesh(Scene& scene, const std::filesystem::path& mesh);
// Where an error about one of the scene's objects happened, as messages
// name it: "SCENE.json: objects[2]: " ("objects[2]: " for a scene with no file).
std::string object_context(const Scene& scene, size_t object);
// A views file (`raylod run --views`): a JSON array of cameras with the
// scene's camera fields; the fields an element leaves out (up, fov_y, width,
// height) are taken from `defaults` (the scene's camera). Errors name the
// source and the element ("views.json: [3].eye: expected an array of 3 numbers").
// At most kMaxViews cameras (as `run --orbit N` takes).
inline constexpr int kMaxViews = 100000;
StatusOr<std::vector<Camera>> parse_views(const std::string& json_text, const Camera& defaults,
                                          const std::string& source_name);
StatusOr<std::vector<Camera>> load_views(const std::filesystem::path& path, const Camera& defaults);
// The default scene compiled into the binary (data/default_scene.json).
StatusOr<Scene> default_scene();
const std::string& default_scene_json();

}  // namespace raylod
