#include "scene/scene.h"

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <map>
#include <sstream>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "core/system.h"
#include "scene/default_scene.h"
#include "streaming/gltf_io.h"
#include "streaming/mesh_reader.h"

namespace raylod {

glm::dmat4 rotate_euler_deg(const glm::dmat4& m, const Vec3d& deg) {
  glm::dmat4 r = glm::rotate(m, glm::radians(deg.z), Vec3d(0, 0, 1));
  r = glm::rotate(r, glm::radians(deg.y), Vec3d(0, 1, 0));
  return glm::rotate(r, glm::radians(deg.x), Vec3d(1, 0, 0));
}

using nlohmann::json;

const char* to_string(MaterialType t) {
  switch (t) {
    case MaterialType::Diffuse: return "diffuse";
    case MaterialType::Glossy: return "glossy";
    case MaterialType::Mirror: return "mirror";
    case MaterialType::Glass: return "glass";
  }
  return "?";
}

bool Scene::traces_specular(const Material& m) const {
  return max_depth > 0 && (m.refracts() || (m.reflects() && m.reflectance > 0));
}

bool Scene::any_reflection() const {
  for (const auto& m : materials) if (m.reflects()) return true;
  return false;
}
bool Scene::any_refraction() const {
  for (const auto& m : materials) if (m.refracts()) return true;
  return false;
}

bool Scene::ground_shows_shadows() const {
  return ground && !lights.empty() && !materials[size_t(ground->material)].reflects();
}

std::string object_context(const Scene& scene, size_t object) {
  return (scene.source.empty() ? std::string() : scene.source.string() + ": ") + "objects[" + std::to_string(object) +
         "]: ";
}

Status replace_first_mesh(Scene& scene, const std::filesystem::path& mesh) {
  std::error_code ec;
  if (std::filesystem::is_directory(mesh, ec)) return Status::error(mesh.string() + ": is a directory, not a mesh file");
  if (!std::filesystem::is_regular_file(mesh, ec)) return Status::error(mesh.string() + ": mesh file not found");
  scene.objects[0].mesh = mesh;
  scene.objects[0].generate.reset();
  return {};
}

namespace {

constexpr double kMaxEyeDistance = 1e18;

// Parsing helpers report the JSON path of what is wrong ("objects[0].material").
struct Parser {
  std::string source;
  Status fail(const std::string& where, const std::string& what) const {
    return Status::error(source + ": " + where + ": " + what);
  }

  Status number(const json& j, const std::string& where, double& out) const {
    if (!j.is_number()) return fail(where, "expected a number");
    out = j.get<double>();
    if (!std::isfinite(out)) return fail(where, "must be finite");
    return {};
  }
  // A number the renderer holds as a float (positions, sizes) although it is
  // parsed as a double.
  Status number_in_float_range(const json& j, const std::string& where, double& out) const {
    RAYLOD_RETURN_IF_ERROR(number(j, where, out));
    if (std::abs(out) > double(std::numeric_limits<float>::max()))
      return fail(where, "is beyond the float range (about 3.4e38)");
    return {};
  }
  Status vec3(const json& j, const std::string& where, Vec3d& out, bool float_range = false) const {
    if (!j.is_array() || j.size() != 3) return fail(where, "expected an array of 3 numbers");
    for (int i = 0; i < 3; ++i) {
      const std::string at = where + "[" + std::to_string(i) + "]";
      RAYLOD_RETURN_IF_ERROR(float_range ? number_in_float_range(j[i], at, out[i]) : number(j[i], at, out[i]));
    }
    return {};
  }
  // A number held as a float (colours, intensities, material constants):
  // beyond the float range it would become infinite.
  Status number_float(const json& j, const std::string& where, float& out) const {
    double v;
    RAYLOD_RETURN_IF_ERROR(number_in_float_range(j, where, v));
    out = float(v);
    return {};
  }
  Status color(const json& j, const std::string& where, Vec3& out) const {
    if (!j.is_array() || j.size() != 3) return fail(where, "expected an array of 3 numbers");
    for (int i = 0; i < 3; ++i)
      RAYLOD_RETURN_IF_ERROR(number_float(j[i], where + "[" + std::to_string(i) + "]", out[i]));
    if (out.x < 0 || out.y < 0 || out.z < 0) return fail(where, "colour components must be >= 0");
    return {};
  }
  Status integer(const json& j, const std::string& where, int64_t lo, int64_t hi, int64_t& out) const {
    if (!j.is_number_integer() && !j.is_number_unsigned()) return fail(where, "expected an integer");
    out = j.get<int64_t>();
    if (out < lo || out > hi)
      return fail(where, "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    return {};
  }
  // Rejects keys the format does not define, so typos do not pass silently.
  Status known_keys(const json& j, const std::string& where, std::initializer_list<const char*> keys) const {
    if (!j.is_object()) return fail(where, "expected an object");
    for (auto it = j.begin(); it != j.end(); ++it) {
      bool ok = false;
      for (const char* k : keys) ok = ok || it.key() == k;
      if (!ok) return fail(where, "unknown key '" + it.key() + "'");
    }
    return {};
  }
};

// A SAX pass that knows the JSON path of every value, for the one error the
// DOM parser reports without a place: a number beyond the double range
// (1e400), which nlohmann reports as out_of_range, not as a parse error.
class PathTracker final : public json::json_sax_t {
 public:
  std::string path = "scene";  // where the parse stopped
  std::string token;           // the text it stopped at
  std::string duplicate;       // the path of a key that appears twice in one object, if any
  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override {
    value();
    frames_.push_back({false, -1, ""});
    return true;
  }
  bool key(string_t& k) override {
    Frame& f = frames_.back();
    f.key = k;
    if (!f.keys.insert(k).second) {  // a repeated key: nlohmann keeps the last silently
      duplicate = place();
      return false;
    }
    return true;
  }
  bool end_object() override {
    frames_.pop_back();
    return true;
  }
  bool start_array(std::size_t) override {
    value();
    frames_.push_back({true, -1, ""});
    return true;
  }
  bool end_array() override {
    frames_.pop_back();
    return true;
  }
  bool parse_error(std::size_t, const std::string& last_token, const json::exception&) override {
    value();  // the value that failed takes the next place in its array
    if (const std::string p = place(); !p.empty()) path = p;
    token = last_token;
    return false;
  }

 private:
  struct Frame {
    bool array;
    int64_t index;    // arrays: the element being read
    std::string key;  // objects: the key being read
    std::set<std::string> keys = {};  // objects: the keys read so far
  };
  std::string place() const {
    std::string p;
    for (const Frame& f : frames_) p += f.array ? "[" + std::to_string(f.index) + "]" : (p.empty() ? "" : ".") + f.key;
    return p;
  }
  bool value() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    return true;
  }
  std::vector<Frame> frames_;
};

// `where` names the camera in messages: "camera" in a scene, "[3]" in a views file.
Status parse_camera(const Parser& p, const json& j, const std::string& where, Camera& cam) {
  const std::string at = where + ".";
  RAYLOD_RETURN_IF_ERROR(p.known_keys(j, where, {"eye", "look_at", "up", "fov_y", "width", "height"}));
  if (!j.contains("eye") || !j.contains("look_at")) return p.fail(where, "needs 'eye' and 'look_at'");
  RAYLOD_RETURN_IF_ERROR(p.vec3(j["eye"], at + "eye", cam.eye));
  RAYLOD_RETURN_IF_ERROR(p.vec3(j["look_at"], at + "look_at", cam.look_at));
  if (j.contains("up")) RAYLOD_RETURN_IF_ERROR(p.vec3(j["up"], at + "up", cam.up));
  if (j.contains("fov_y")) RAYLOD_RETURN_IF_ERROR(p.number(j["fov_y"], at + "fov_y", cam.fov_y_deg));
  int64_t v;
  if (j.contains("width")) { RAYLOD_RETURN_IF_ERROR(p.integer(j["width"], at + "width", 1, 32768, v)); cam.width = int(v); }
  if (j.contains("height")) { RAYLOD_RETURN_IF_ERROR(p.integer(j["height"], at + "height", 1, 32768, v)); cam.height = int(v); }
  if (!(cam.fov_y_deg > 0 && cam.fov_y_deg < 180)) return p.fail(at + "fov_y", "must be in (0, 180) degrees");
  Vec3d view = cam.look_at - cam.eye;
  if (glm::length(view) == 0) return p.fail(where, "eye and look_at coincide");
  // Rays are traced in single precision around the look-at point, and
  // Embree takes ray origins up to about 1.8e18 from it.
  if (!(std::max({std::abs(view.x), std::abs(view.y), std::abs(view.z)}) <= kMaxEyeDistance))
    return p.fail(at + "eye", "is more than 1e18 from look_at (rays are traced in single precision about look_at)");
  if (glm::length(glm::cross(view, cam.up)) <= 1e-9 * glm::length(view) * glm::length(cam.up))
    return p.fail(at + "up", "is zero or parallel to the viewing direction");
  return {};
}

Status parse_material(const Parser& p, const std::string& name, const json& j, Material& m) {
  const std::string where = "materials." + name;
  RAYLOD_RETURN_IF_ERROR(p.known_keys(j, where, {"type", "color", "specular", "shininess", "reflectance", "ior", "tint"}));
  m.name = name;
  if (!j.contains("type") || !j["type"].is_string()) return p.fail(where + ".type", "expected one of diffuse, glossy, mirror, glass");
  const std::string type = j["type"].get<std::string>();
  if (type == "diffuse") m.type = MaterialType::Diffuse;
  else if (type == "glossy") m.type = MaterialType::Glossy;
  else if (type == "mirror") m.type = MaterialType::Mirror;
  else if (type == "glass") m.type = MaterialType::Glass;
  else return p.fail(where + ".type", "'" + type + "' is not one of diffuse, glossy, mirror, glass");
  // Keys another type uses would be ignored here: refused, as typos are.
  for (const auto& [key, owner, used] : {std::tuple{"reflectance", "mirror", m.type == MaterialType::Mirror},
                                         std::tuple{"ior", "glass", m.type == MaterialType::Glass},
                                         std::tuple{"tint", "glass", m.type == MaterialType::Glass}})
    if (j.contains(key) && !used)
      return p.fail(where + "." + key, "is not used by a " + type + " material (only by " + owner + ")");
  if (m.type == MaterialType::Mirror || m.type == MaterialType::Glass) m.color = Vec3(0);
  if (j.contains("color")) RAYLOD_RETURN_IF_ERROR(p.color(j["color"], where + ".color", m.color));
  if (j.contains("specular")) RAYLOD_RETURN_IF_ERROR(p.color(j["specular"], where + ".specular", m.specular));
  if (j.contains("tint")) RAYLOD_RETURN_IF_ERROR(p.color(j["tint"], where + ".tint", m.tint));
  if (j.contains("shininess")) RAYLOD_RETURN_IF_ERROR(p.number_float(j["shininess"], where + ".shininess", m.shininess));
  if (j.contains("reflectance")) RAYLOD_RETURN_IF_ERROR(p.number_float(j["reflectance"], where + ".reflectance", m.reflectance));
  if (j.contains("ior")) RAYLOD_RETURN_IF_ERROR(p.number_float(j["ior"], where + ".ior", m.ior));
  if (!(m.shininess >= 0)) return p.fail(where + ".shininess", "must be >= 0");
  if (!(m.reflectance >= 0 && m.reflectance <= 1)) return p.fail(where + ".reflectance", "must be in [0, 1]");
  if (!(m.ior >= 1.0f && m.ior <= 4.0f)) return p.fail(where + ".ior", "must be in [1, 4]");
  return {};
}

Status parse_transform(const Parser& p, const json& j, const std::string& where, glm::dmat4& out) {
  RAYLOD_RETURN_IF_ERROR(p.known_keys(j, where, {"translate", "scale", "rotate_deg", "matrix"}));
  if (j.contains("matrix")) {
    if (j.size() != 1) return p.fail(where, "'matrix' cannot be combined with translate/scale/rotate_deg");
    const json& m = j["matrix"];
    if (!m.is_array() || m.size() != 16) return p.fail(where + ".matrix", "expected 16 numbers (row-major 4x4)");
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        RAYLOD_RETURN_IF_ERROR(p.number(m[r * 4 + c], where + ".matrix", out[c][r]));
    // Only affine transforms: a last row other than 0 0 0 1 (a column-major
    // matrix pasted here, say) would otherwise be dropped without a word.
    if (out[0][3] != 0 || out[1][3] != 0 || out[2][3] != 0 || out[3][3] != 1)
      return p.fail(where + ".matrix", "the last row must be 0 0 0 1 (an affine transform, row-major: translation in "
                                       "the 4th, 8th and 12th numbers)");
  } else {
    Vec3d t(0), s(1), rdeg(0);
    if (j.contains("translate")) RAYLOD_RETURN_IF_ERROR(p.vec3(j["translate"], where + ".translate", t));
    if (j.contains("scale")) {
      if (j["scale"].is_number()) { double u; RAYLOD_RETURN_IF_ERROR(p.number(j["scale"], where + ".scale", u)); s = Vec3d(u); }
      else RAYLOD_RETURN_IF_ERROR(p.vec3(j["scale"], where + ".scale", s));
    }
    if (j.contains("rotate_deg")) RAYLOD_RETURN_IF_ERROR(p.vec3(j["rotate_deg"], where + ".rotate_deg", rdeg));
    out = glm::scale(rotate_euler_deg(glm::translate(glm::dmat4(1.0), t), rdeg), s);
  }
  // Rays and vertices are floats in the world: a transform whose numbers are
  // beyond their range puts every vertex at infinity.
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r)
      if (std::abs(out[c][r]) > double(std::numeric_limits<float>::max()))
        return p.fail(where, "is beyond the float range (about 3.4e38)");
  // Singular relative to its own scale (a uniform scale of 1e-6, micrometres
  // to metres, is fine): |det| against the product of the column lengths,
  // which is 1 for a rotation times any scale and 0 for a flat transform.
  const glm::dmat3 l(out);
  const double det = glm::determinant(l);
  const double columns = glm::length(l[0]) * glm::length(l[1]) * glm::length(l[2]);
  if (!std::isfinite(det) || !std::isfinite(columns) || !(std::abs(det) > 1e-12 * columns))
    return p.fail(where, "transform is singular");
  return {};
}

// A whole .gltf/.glb file (not one of its meshes, "FILE#meshes[N]").
bool is_whole_gltf(const std::filesystem::path& mesh) {
  const MeshRef ref = parse_mesh_ref(mesh);
  auto format = mesh_format_from_extension(ref.file);
  return ref.gltf_mesh < 0 && format && *format == MeshFormat::Gltf;
}

// The material of an object from a glTF mesh: the glTF material where raylod
// has an equivalent (metallic 1 and roughness 0: a mirror, reflecting the
// mean of baseColorFactor; a baseColorFactor other than white: the colour of
// a diffuse or glossy scene material), else the scene object's material.
int gltf_material(const SceneObject& obj, const std::filesystem::path& file, const GltfSummary& gltf, int index,
                  std::vector<Material>& materials, std::map<std::string, int>& derived) {
  if (index < 0) return obj.material;
  const GltfMaterialInfo& g = gltf.materials[size_t(index)];
  const Material& base = materials[size_t(obj.material)];
  Material m = base;
  if (g.mirror) {
    m = Material{};
    m.type = MaterialType::Mirror;
    m.color = Vec3(0);
    m.reflectance = (g.base_color.x + g.base_color.y + g.base_color.z) / 3.0f;
  } else if (g.has_base_color && (base.type == MaterialType::Diffuse || base.type == MaterialType::Glossy)) {
    m.color = g.base_color;
  } else {
    return obj.material;
  }
  const std::string key = (g.mirror ? std::string() : base.name) + "|" + file.string() + "|" + std::to_string(index);
  if (auto it = derived.find(key); it != derived.end()) return it->second;
  m.name = (g.mirror ? std::string() : base.name + "/") + file.filename().string() + ":" + g.name;
  materials.push_back(m);
  derived[key] = int(materials.size()) - 1;
  return derived[key];
}

// A scene object naming a glTF file becomes one object per node instance of
// a mesh in the file's default scene: mesh "FILE#meshes[N]" (one store per
// glTF mesh, however many nodes use it), transform = the object's transform
// times the node's global transform, material from gltf_material. Meshes
// with no triangle primitive are left out.
Status expand_gltf_object(const Parser& p, const SceneObject& obj, const std::string& where,
                          std::vector<Material>& materials, std::map<std::string, int>& derived,
                          std::vector<SceneObject>& out) {
  auto described = describe_gltf(obj.mesh);
  if (!described) return p.fail(where + ".mesh", described.status().message());
  const GltfSummary& gltf = *described;
  size_t added = 0;
  for (const GltfInstance& inst : gltf.instances) {
    const GltfMeshInfo& mesh = gltf.meshes[size_t(inst.mesh)];
    if (mesh.triangle_primitives == 0) continue;
    SceneObject o = obj;
    o.mesh = gltf_mesh_path(obj.mesh, inst.mesh);
    o.transform = obj.transform * inst.transform;
    const double det = glm::determinant(glm::dmat3(o.transform));
    if (!std::isfinite(det) || std::abs(det) < 1e-18)
      return p.fail(where + ".mesh", obj.mesh.string() + ": " + inst.node + ": the transform is singular");
    o.material = gltf_material(obj, obj.mesh, gltf, mesh.material, materials, derived);
    out.push_back(o);
    ++added;
  }
  if (added == 0) return p.fail(where + ".mesh", obj.mesh.string() + ": the default scene places no mesh with triangles");
  return {};
}

Status parse_light(const Parser& p, const json& j, const std::string& where, Light& l) {
  RAYLOD_RETURN_IF_ERROR(p.known_keys(j, where, {"type", "position", "direction", "color", "intensity"}));
  const std::string type = j.contains("type") && j["type"].is_string() ? j["type"].get<std::string>() : "";
  if (type == "point") {
    l.type = LightType::Point;
    if (!j.contains("position")) return p.fail(where, "a point light needs 'position'");
    if (j.contains("direction")) return p.fail(where + ".direction", "is not used by a point light (it shines every way)");
    // The renderer holds it as floats.
    RAYLOD_RETURN_IF_ERROR(p.vec3(j["position"], where + ".position", l.position, /*float_range=*/true));
  } else if (type == "directional") {
    l.type = LightType::Directional;
    if (!j.contains("direction")) return p.fail(where, "a directional light needs 'direction'");
    if (j.contains("position")) return p.fail(where + ".position", "is not used by a directional light (it has none)");
    RAYLOD_RETURN_IF_ERROR(p.vec3(j["direction"], where + ".direction", l.direction));
    if (glm::length(l.direction) == 0) return p.fail(where + ".direction", "must not be zero");
    l.direction = glm::normalize(l.direction);
  } else {
    return p.fail(where + ".type", "expected 'point' or 'directional'");
  }
  if (j.contains("color")) RAYLOD_RETURN_IF_ERROR(p.color(j["color"], where + ".color", l.color));
  if (j.contains("intensity")) {
    RAYLOD_RETURN_IF_ERROR(p.number_float(j["intensity"], where + ".intensity", l.intensity));
    if (l.intensity < 0) return p.fail(where + ".intensity", "must be >= 0");
  }
  return {};
}

// Parses JSON text; errors name the source, and for a number out of the
// double range the place (`root` when it is at the top).
Status parse_json(const Parser& p, const std::string& text, const std::string& root, json& j) {
  try {
    j = json::parse(text);
  } catch (const json::parse_error& e) {
    return Status::error(p.source + ": not valid JSON: " + e.what());
  } catch (const json::exception& e) {
    // Valid syntax the parser still cannot hold (id 406: a number such as
    // 1e400 overflows a double); a second, SAX pass finds where it is.
    PathTracker where;
    where.path = root;
    (void)json::sax_parse(text, &where);
    if (e.id == 406)
      return p.fail(where.path, "the number " + where.token + " is out of range (beyond the largest double, about 1.8e308)");
    return p.fail(where.path, std::string("cannot be read: ") + e.what());
  }
  // A key given twice in one object: the DOM keeps the last without a word,
  // so a SAX pass looks for it (a scene is small).
  PathTracker keys;
  (void)json::sax_parse(text, &keys);
  if (!keys.duplicate.empty())
    return p.fail(keys.duplicate, "is given twice");
  return {};
}

}  // namespace

StatusOr<Scene> parse_scene(const std::string& text, const std::filesystem::path& base_dir,
                            const std::string& source_name, bool first_mesh_replaced) {
  Parser p{source_name};
  json j;
  RAYLOD_RETURN_IF_ERROR(parse_json(p, text, "scene", j));
  RAYLOD_RETURN_IF_ERROR(p.known_keys(j, "scene", {"camera", "materials", "objects", "ground", "lights", "background",
                                                  "spp", "max_depth", "seed", "crease_angle", "comment"}));
  Scene scene;
  if (!j.contains("camera")) return p.fail("scene", "missing 'camera'");
  RAYLOD_RETURN_IF_ERROR(parse_camera(p, j["camera"], "camera", scene.camera));

  std::map<std::string, int> material_index;
  if (!j.contains("materials") || !j["materials"].is_object() || j["materials"].empty())
    return p.fail("materials", "expected an object with at least one named material");
  for (auto it = j["materials"].begin(); it != j["materials"].end(); ++it) {
    Material m;
    RAYLOD_RETURN_IF_ERROR(parse_material(p, it.key(), it.value(), m));
    material_index[m.name] = int(scene.materials.size());
    scene.materials.push_back(m);
  }
  auto lookup_material = [&](const json& jm, const std::string& where, int& out) -> Status {
    if (!jm.is_string()) return p.fail(where, "expected a material name");
    auto found = material_index.find(jm.get<std::string>());
    if (found == material_index.end()) return p.fail(where, "no material named '" + jm.get<std::string>() + "'");
    out = found->second;
    return {};
  };

  std::map<std::string, int> gltf_materials;  // derived materials, by scene material and glTF file and material
  if (!j.contains("objects") || !j["objects"].is_array() || j["objects"].empty())
    return p.fail("objects", "expected an array with at least one object");
  for (size_t i = 0; i < j["objects"].size(); ++i) {
    const json& jo = j["objects"][i];
    const std::string where = "objects[" + std::to_string(i) + "]";
    RAYLOD_RETURN_IF_ERROR(p.known_keys(jo, where, {"mesh", "material", "transform"}));
    SceneObject obj;
    if (!jo.contains("mesh")) return p.fail(where, "missing 'mesh'");
    const json& jm = jo["mesh"];
    if (jm.is_string()) {
      std::filesystem::path mp = jm.get<std::string>();
      if (mp.is_relative()) mp = base_dir / mp;
      std::error_code ec;
      if (i == 0 && first_mesh_replaced && !std::filesystem::exists(parse_mesh_ref(mp).file, ec)) {
        // Replaced by the command's --mesh: never read, so it need not exist.
        obj.mesh = mp;
      } else if (Status st = check_regular_file(parse_mesh_ref(mp).file); !st) {
        if (!std::filesystem::exists(parse_mesh_ref(mp).file, ec)) return p.fail(where + ".mesh", "file not found: " + mp.string());
        return p.fail(where + ".mesh", st.message());  // "m.ply: is a named pipe (FIFO), not a regular file"
      }
      obj.mesh = mp;
    } else if (jm.is_object()) {
      RAYLOD_RETURN_IF_ERROR(p.known_keys(jm, where + ".mesh", {"generate", "triangles"}));
      GeneratedMesh g;
      if (!jm.contains("generate") || !jm["generate"].is_string()) return p.fail(where + ".mesh.generate", "expected 'teapot' or 'bottle'");
      g.generator = jm["generate"].get<std::string>();
      if (g.generator != "teapot" && g.generator != "bottle") return p.fail(where + ".mesh.generate", "'" + g.generator + "' is not 'teapot' or 'bottle'");
      int64_t n = 100000;
      if (jm.contains("triangles")) RAYLOD_RETURN_IF_ERROR(p.integer(jm["triangles"], where + ".mesh.triangles", 100, 100000000, n));
      g.triangles = uint64_t(n);
      obj.generate = g;
    } else {
      return p.fail(where + ".mesh", "expected a file name or {\"generate\": ...}");
    }
    if (!jo.contains("material")) return p.fail(where, "missing 'material'");
    RAYLOD_RETURN_IF_ERROR(lookup_material(jo["material"], where + ".material", obj.material));
    if (jo.contains("transform")) RAYLOD_RETURN_IF_ERROR(parse_transform(p, jo["transform"], where + ".transform", obj.transform));
    std::error_code ec;
    if (!obj.mesh.empty() && is_whole_gltf(obj.mesh) && std::filesystem::exists(obj.mesh, ec)) {
      RAYLOD_RETURN_IF_ERROR(expand_gltf_object(p, obj, where, scene.materials, gltf_materials, scene.objects));
      continue;
    }
    scene.objects.push_back(obj);
  }

  if (j.contains("ground")) {
    const json& jg = j["ground"];
    RAYLOD_RETURN_IF_ERROR(p.known_keys(jg, "ground", {"height", "size", "material"}));
    Ground g;
    if (jg.contains("height")) RAYLOD_RETURN_IF_ERROR(p.number_in_float_range(jg["height"], "ground.height", g.height));
    if (jg.contains("size")) RAYLOD_RETURN_IF_ERROR(p.number_in_float_range(jg["size"], "ground.size", g.size));
    if (!(g.size > 0)) return p.fail("ground.size", "must be > 0");
    if (!jg.contains("material")) return p.fail("ground", "missing 'material'");
    RAYLOD_RETURN_IF_ERROR(lookup_material(jg["material"], "ground.material", g.material));
    scene.ground = g;
  }

  if (j.contains("lights")) {
    if (!j["lights"].is_array()) return p.fail("lights", "expected an array");
    for (size_t i = 0; i < j["lights"].size(); ++i) {
      Light l;
      RAYLOD_RETURN_IF_ERROR(parse_light(p, j["lights"][i], "lights[" + std::to_string(i) + "]", l));
      // A light of intensity 0 or colour black lights nothing and casts no
      // shadow: left out, so that neither the render nor the probe traces
      // shadow rays for it or holds cells for its shadows.
      if (l.intensity == 0 || (l.color.r == 0 && l.color.g == 0 && l.color.b == 0)) continue;
      scene.lights.push_back(l);
    }
  }
  if (j.contains("background")) RAYLOD_RETURN_IF_ERROR(p.color(j["background"], "background", scene.background));
  int64_t v;
  if (j.contains("spp")) { RAYLOD_RETURN_IF_ERROR(p.integer(j["spp"], "spp", 1, 4096, v)); scene.spp = int(v); }
  if (j.contains("max_depth")) { RAYLOD_RETURN_IF_ERROR(p.integer(j["max_depth"], "max_depth", 0, 64, v)); scene.max_depth = int(v); }
  if (j.contains("seed")) { RAYLOD_RETURN_IF_ERROR(p.integer(j["seed"], "seed", 0, INT64_MAX, v)); scene.seed = uint64_t(v); }
  if (j.contains("crease_angle")) {
    double deg;
    RAYLOD_RETURN_IF_ERROR(p.number(j["crease_angle"], "crease_angle", deg));
    if (!(deg >= 0 && deg <= 180)) return p.fail("crease_angle", "must be between 0 and 180 degrees");
    scene.crease_angle_deg = deg;
  }
  scene.render_origin = render_origin_for(scene.camera.look_at);
  return scene;
}

Vec3d render_origin_for(const Vec3d& look_at) {
  if (!is_finite(look_at)) return Vec3d(0);
  return Vec3d(std::round(look_at.x), std::round(look_at.y), std::round(look_at.z));
}

StatusOr<Scene> load_scene(const std::filesystem::path& path, bool first_mesh_replaced) {
  if (Status st = check_regular_file(path); !st) return st;  // a FIFO would block the read
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::error(path.string() + ": cannot open scene file");
  std::stringstream ss;
  ss << in.rdbuf();
  auto dir = path.parent_path();
  auto scene = parse_scene(ss.str(), dir.empty() ? std::filesystem::path(".") : dir, path.string(), first_mesh_replaced);
  if (scene) scene->source = path;
  return scene;
}

StatusOr<std::vector<Camera>> parse_views(const std::string& json_text, const Camera& defaults,
                                          const std::string& source_name) {
  Parser p{source_name};
  json j;
  RAYLOD_RETURN_IF_ERROR(parse_json(p, json_text, "views", j));
  if (!j.is_array() || j.empty()) return Status::error(source_name + ": expected a non-empty JSON array of cameras");
  if (j.size() > size_t(kMaxViews))
    return Status::error(source_name + ": " + std::to_string(j.size()) + " cameras, more than the " +
                         std::to_string(kMaxViews) + " a run renders");
  std::vector<Camera> views;
  for (size_t i = 0; i < j.size(); ++i) {
    Camera cam = defaults;
    RAYLOD_RETURN_IF_ERROR(parse_camera(p, j[i], "[" + std::to_string(i) + "]", cam));
    views.push_back(cam);
  }
  return views;
}

StatusOr<std::vector<Camera>> load_views(const std::filesystem::path& path, const Camera& defaults) {
  if (Status st = check_regular_file(path); !st) return st;
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::error(path.string() + ": cannot open views file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_views(ss.str(), defaults, path.string());
}

const std::string& default_scene_json() {
  static const std::string text = embedded::kDefaultSceneJson;
  return text;
}

StatusOr<Scene> default_scene() { return parse_scene(default_scene_json(), ".", "<default scene>"); }

}  // namespace raylod
