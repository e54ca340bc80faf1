#include "scene/mesh_framing.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

namespace raylod {
namespace {

// The default scene's (data/default_scene.json) camera and point light,
// relative to its look-at point: the framing keeps their directions and
// scales their distances.
const Vec3d kViewDirection = glm::normalize(Vec3d(6.3, 3.5, 8.5));
const double kDefaultEyeDistance = glm::length(Vec3d(6.3, 3.5, 8.5));
const Vec3d kLightOffset(5.8, 8.7, 6.0);
const double kDefaultLightIntensity = 160;

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = char(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// The scene format's matrix for rotate_deg (rotate_euler_deg), exact: quarter
// turns are permutations, where cos(90 degrees) rounds to 6e-17, not 0.
glm::dmat4 rotation_matrix(const Vec3d& deg) {
  glm::dmat4 m = rotate_euler_deg(glm::dmat4(1.0), deg);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (std::abs(m[c][r] - std::round(m[c][r])) < 1e-12) m[c][r] = std::round(m[c][r]);
  return m;
}

using Json = nlohmann::ordered_json;

Json vec(const Vec3d& v) { return Json::array({v.x, v.y, v.z}); }

// Indented objects, arrays of plain values on one line: a scene file as
// people write them (data/*.json).
void write_json(const Json& j, int indent, std::string& out) {
  const std::string pad(size_t(indent) * 2, ' ');
  if (j.is_object()) {
    out += "{\n";
    size_t i = 0;
    for (auto it = j.begin(); it != j.end(); ++it, ++i) {
      out += pad + "  " + Json(it.key()).dump() + ": ";
      write_json(it.value(), indent + 1, out);
      out += i + 1 < j.size() ? ",\n" : "\n";
    }
    out += pad + "}";
  } else if (j.is_array() && std::any_of(j.begin(), j.end(), [](const Json& e) { return e.is_structured(); })) {
    out += "[\n";
    for (size_t i = 0; i < j.size(); ++i) {
      out += pad + "  ";
      write_json(j[i], indent + 1, out);
      out += i + 1 < j.size() ? ",\n" : "\n";
    }
    out += pad + "]";
  } else if (j.is_array()) {
    out += "[";
    for (size_t i = 0; i < j.size(); ++i) out += (i ? ", " : "") + j[i].dump();
    out += "]";
  } else {
    out += j.dump();
  }
}

}  // namespace

StatusOr<UpAxis> parse_up_axis(std::string_view text) {
  const std::string t = lower(text);
  if (t == "x" || t == "+x") return UpAxis::PosX;
  if (t == "-x") return UpAxis::NegX;
  if (t == "y" || t == "+y") return UpAxis::PosY;
  if (t == "-y") return UpAxis::NegY;
  if (t == "z" || t == "+z") return UpAxis::PosZ;
  if (t == "-z") return UpAxis::NegZ;
  return Status::error("--up: '" + std::string(text) + "' is not an axis (x, y, z, -x, -y or -z)");
}

const char* to_string(UpAxis up) {
  switch (up) {
    case UpAxis::PosX: return "+x";
    case UpAxis::NegX: return "-x";
    case UpAxis::PosY: return "+y";
    case UpAxis::NegY: return "-y";
    case UpAxis::PosZ: return "+z";
    case UpAxis::NegZ: return "-z";
  }
  return "?";
}

Vec3d up_rotation_deg(UpAxis up) {
  switch (up) {
    case UpAxis::PosX: return Vec3d(0, 0, 90);    // about Z: x -> y
    case UpAxis::NegX: return Vec3d(0, 0, -90);   // -x -> y
    case UpAxis::PosY: return Vec3d(0);
    case UpAxis::NegY: return Vec3d(180, 0, 0);   // about X: -y -> y
    case UpAxis::PosZ: return Vec3d(-90, 0, 0);   // about X: z -> y
    case UpAxis::NegZ: return Vec3d(90, 0, 0);    // -z -> y
  }
  return Vec3d(0);
}

StatusOr<MeshFraming> frame_mesh(const Bbox& bounds, const FramingOptions& options) {
  if (bounds.empty()) return Status::error("the mesh has no triangles to frame");
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(bounds.lo[a]) || !std::isfinite(bounds.hi[a]))
      return Status::error("the mesh's bounds are not finite");
  if (!(options.width > 0 && options.height > 0)) return Status::error("the image size must be positive");
  if (!(options.fov_y_deg > 0 && options.fov_y_deg < 180)) return Status::error("fov_y must be in (0, 180) degrees");
  if (!(options.fill > 0 && options.fill <= 1)) return Status::error("fill must be in (0, 1]");

  MeshFraming f;
  f.rotate_deg = up_rotation_deg(options.up);
  const std::array<Vec3d, 8> corners = world_corners(rotation_matrix(f.rotate_deg), bounds);
  for (const Vec3d& c : corners) f.bounds.expand(c);
  const double diag = f.bounds.diagonal();
  // Relative to where the mesh is: a part far from the origin is still a
  // part, but one whose extent rounds away is a point.
  const double where = std::max({std::abs(f.bounds.lo.x), std::abs(f.bounds.lo.y), std::abs(f.bounds.lo.z),
                                 std::abs(f.bounds.hi.x), std::abs(f.bounds.hi.y), std::abs(f.bounds.hi.z)});
  // (Relative alone: a mesh 1e-15 across at the origin is not a point, it
  // is outside the framed sizes below.)
  if (!(diag > 1e-12 * where)) {
    char hint[200] = "";
    if (where > 0 && std::isfinite(where))
      std::snprintf(hint, sizeof hint,
                    " (single-precision coordinates %.3g from the origin are %.3g apart: a mesh stored as float "
                    "there loses any smaller detail)",
                    where, float_spacing_at(where));
    return Status::error(std::string("the mesh is a single point: nothing to frame") + hint);
  }
  // Rays are traced in single precision about the look-at point, with
  // offsets and a ground plane that scale with the scene; outside this range
  // the ground or a light's contribution is lost (measured: a triangle of
  // side 1e-10 renders darker, 1e-12 without its ground, 1e13 with the
  // ground cutting it; 1e-9 to 3e12 render as at 1).
  if (!(diag >= kMinFramedDiagonal && diag <= kMaxFramedDiagonal)) {
    char text[320];
    std::snprintf(text, sizeof text,
                  "the mesh is %.3g units across; raylod scene frames meshes from %.0e to %.0e units across "
                  "(single-precision rays lose the ground or the lights beyond it): convert it to other units",
                  diag, kMinFramedDiagonal, kMaxFramedDiagonal);
    return Status::error(text);
  }

  const Vec3d c = f.bounds.center();
  const Vec3d w = kViewDirection;  // from the look-at point towards the eye
  const Vec3d right = glm::normalize(glm::cross(-w, Vec3d(0, 1, 0)));
  const Vec3d up = glm::cross(right, -w);
  const double ty = std::tan(glm::radians(0.5 * options.fov_y_deg));
  const double tx = ty * double(options.width) / double(options.height);
  // Every corner q inside the frame: |q.right| <= fill tx (d - q.w), the same
  // upwards; and the eye outside the bounds by a margin.
  double d = 0;
  for (const Vec3d& p : corners) {
    const Vec3d q = p - c;
    const double depth = glm::dot(q, w);
    d = std::max({d, depth + std::abs(glm::dot(q, right)) / (options.fill * tx),
                  depth + std::abs(glm::dot(q, up)) / (options.fill * ty), depth + 0.05 * diag});
  }
  f.camera.look_at = c;
  f.camera.eye = c + d * w;
  f.camera.up = Vec3d(0, 1, 0);
  f.camera.fov_y_deg = options.fov_y_deg;
  f.camera.width = options.width;
  f.camera.height = options.height;

  f.ground_height = f.bounds.lo.y - 1e-3 * diag;
  f.ground_size = 200 * diag;
  const double s = d / kDefaultEyeDistance;
  f.light_position = c + s * kLightOffset;
  f.light_intensity = kDefaultLightIntensity * s * s;
  return f;
}

StatusOr<MaterialPreset> parse_material_preset(std::string_view text) {
  const std::string t = lower(text);
  if (t == "glossy") return MaterialPreset::Glossy;
  if (t == "diffuse") return MaterialPreset::Diffuse;
  if (t == "mirror") return MaterialPreset::Mirror;
  if (t == "glass") return MaterialPreset::Glass;
  return Status::error("--material: '" + std::string(text) + "' is not one of glossy, diffuse, mirror, glass");
}

std::string scene_json_for_mesh(const std::string& mesh_path, const MeshFraming& f, MaterialPreset material,
                                int spp, const std::string& comment) {
  using json = Json;
  json j;
  j["comment"] = comment;
  j["camera"] = {{"eye", vec(f.camera.eye)},         {"look_at", vec(f.camera.look_at)},
                 {"up", vec(f.camera.up)},           {"fov_y", f.camera.fov_y_deg},
                 {"width", f.camera.width},          {"height", f.camera.height}};
  json part;
  int max_depth = 5;
  switch (material) {
    case MaterialPreset::Glossy:
      part = {{"type", "glossy"}, {"color", {0.55, 0.56, 0.58}}, {"specular", {0.4, 0.4, 0.4}}, {"shininess", 60}};
      break;
    case MaterialPreset::Diffuse: part = {{"type", "diffuse"}, {"color", {0.6, 0.6, 0.62}}}; break;
    case MaterialPreset::Mirror: part = {{"type", "mirror"}, {"reflectance", 0.85}}; break;
    case MaterialPreset::Glass:
      part = {{"type", "glass"}, {"ior", 1.5}, {"tint", {0.92, 0.97, 1.0}}};
      max_depth = 8;  // through both walls of a hollow part and back out
      break;
  }
  j["materials"] = {{"part", part}, {"floor", {{"type", "diffuse"}, {"color", {0.70, 0.70, 0.68}}}}};
  json object = {{"mesh", mesh_path}, {"material", "part"}};
  if (f.rotate_deg != Vec3d(0)) object["transform"] = {{"rotate_deg", vec(f.rotate_deg)}};
  j["objects"] = json::array({object});
  j["ground"] = {{"height", f.ground_height}, {"size", f.ground_size}, {"material", "floor"}};
  j["lights"] = json::array({
      {{"type", "point"}, {"position", vec(f.light_position)}, {"color", {1, 0.97, 0.92}},
       {"intensity", f.light_intensity}},
      {{"type", "directional"}, {"direction", {0.4, -1, -0.6}}, {"color", {0.6, 0.7, 1.0}}, {"intensity", 0.35}},
  });
  j["background"] = {0.62, 0.72, 0.85};
  j["spp"] = spp;
  j["max_depth"] = max_depth;
  j["seed"] = 1;
  std::string out;
  write_json(j, 0, out);
  return out + "\n";
}

double float_spacing_at(double x) { return std::ldexp(1.0, std::ilogb(x) - 23); }

std::string size_problem(const Bbox& bounds) {
  if (bounds.empty()) return "";
  const double diag = bounds.diagonal();
  if (!(diag > 0) || (diag >= kMinFramedDiagonal && diag <= kMaxFramedDiagonal)) return "";
  char text[256];
  std::snprintf(text, sizeof text,
                "is %.3g units across in the world; raylod renders meshes from %.0e to %.0e units across "
                "(single-precision rays lose the ground or the lights beyond it): scale the scene",
                diag, kMinFramedDiagonal, kMaxFramedDiagonal);
  return text;
}

std::string placement_problem(const Scene& scene, const Bbox& bounds) {
  if (bounds.empty()) return "";
  char text[256];
  if (scene.ground && bounds.hi.y <= scene.ground->height) {
    std::snprintf(text, sizeof text, "lies at or under the ground plane (its top at y = %.6g, the ground at y = %.6g)",
                  bounds.hi.y, scene.ground->height);
    return text;
  }
  // The pinhole projection of the bounds' corners (scene/scene.h's camera:
  // look_at - eye forward, fov_y vertical).
  const Camera& cam = scene.camera;
  const Vec3d forward = glm::normalize(cam.look_at - cam.eye);
  const Vec3d right = glm::normalize(glm::cross(forward, cam.up));
  const Vec3d up = glm::cross(right, forward);
  const double ty = std::tan(glm::radians(0.5 * cam.fov_y_deg)), tx = ty * cam.width / cam.height;
  Bbox frame;  // in pixels
  int behind = 0;
  const std::array<Vec3d, 8> corners = world_corners(glm::dmat4(1.0), bounds);
  for (const Vec3d& p : corners) {
    const Vec3d d = p - cam.eye;
    const double depth = glm::dot(d, forward);
    if (!(depth > 0)) {
      ++behind;
      continue;
    }
    frame.expand(Vec3d((1 + glm::dot(d, right) / depth / tx) * 0.5 * cam.width,
                       (1 - glm::dot(d, up) / depth / ty) * 0.5 * cam.height, 0));
  }
  // Wholly behind the eye's plane: nothing of it is in view. Partly behind
  // (around the eye): no size to judge.
  if (behind == int(corners.size())) return "is behind the camera";
  if (behind > 0) return "";
  if (frame.hi.x < 0 || frame.lo.x > cam.width || frame.hi.y < 0 || frame.lo.y > cam.height)
    return "is outside the camera's view";
  const double w = frame.hi.x - frame.lo.x, h = frame.hi.y - frame.lo.y;
  if (std::max(w, h) < 0.1 * cam.height) {
    std::snprintf(text, sizeof text, "covers at most %.0f x %.0f pixels of the %d x %d view", std::ceil(w),
                  std::ceil(h), cam.width, cam.height);
    return text;
  }
  return "";
}

}  // namespace raylod
