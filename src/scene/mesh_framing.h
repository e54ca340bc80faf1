// A scene around one mesh, for a mesh that comes without one (a CAD export,
// a scan): `raylod scene MESH` writes it as a scene file to edit and run.
//
// The mesh keeps its own units and position; only a rotation is applied,
// which brings the file's up axis to +Y (CAD exports are often Z-up). The
// camera looks at the centre of the rotated bounds from the default scene's
// direction (above and to the front right) at the distance where every
// corner of the bounds falls inside `fill` of the frame's half-width and
// half-height. The ground lies just below the lowest point (a thousandth of
// the diagonal: never on a face of the mesh, where coincident surfaces would
// fight), and the point light sits where the default scene's sits relative
// to its camera, scaled with the camera's distance and its intensity with
// that distance squared, so the mesh is lit as the teapot is at any size.
#pragma once

#include <string>
#include <string_view>

#include "core/math.h"
#include "core/status.h"
#include "scene/scene.h"

namespace raylod {

enum class UpAxis { PosX, NegX, PosY, NegY, PosZ, NegZ };
// "x", "-x", "y", "+y", "-y", "z", "-z" (case-insensitive); an error quoting the text otherwise.
StatusOr<UpAxis> parse_up_axis(std::string_view text);
const char* to_string(UpAxis up);

// The object rotation (the scene format's rotate_deg, one axis) that turns
// `up` into +Y.
Vec3d up_rotation_deg(UpAxis up);

struct FramingOptions {
  UpAxis up = UpAxis::PosY;
  int width = 1280, height = 960;
  double fov_y_deg = 34;
  double fill = 0.85;  // the bounds' corners within this fraction of the half-frame
};

struct MeshFraming {
  Vec3d rotate_deg{0};   // object transform
  Bbox bounds;           // the mesh's bounds after that rotation (world)
  Camera camera;
  double ground_height = 0, ground_size = 0;
  Vec3d light_position{0};
  double light_intensity = 0;
};

// The sizes (bounding-box diagonals) frame_mesh frames: a measured range
// with margin (mesh_framing.cpp).
inline constexpr double kMinFramedDiagonal = 1e-8, kMaxFramedDiagonal = 1e12;

// `bounds`: the mesh's, in its file's coordinates (summarize_mesh); an error
// if empty, not finite, a single point, or outside the framed sizes.
StatusOr<MeshFraming> frame_mesh(const Bbox& bounds, const FramingOptions& options);

enum class MaterialPreset { Glossy, Diffuse, Mirror, Glass };
StatusOr<MaterialPreset> parse_material_preset(std::string_view text);

// The scene file's text (JSON) for `mesh_path` (as it is to be written in
// the file) framed as `framing` says, in `material`, with `spp` samples per
// pixel.
std::string scene_json_for_mesh(const std::string& mesh_path, const MeshFraming& framing, MaterialPreset material,
                                int spp, const std::string& comment);

// Whether a mesh with world bounds `bounds` is of a size raylod renders
// faithfully (kMinFramedDiagonal to kMaxFramedDiagonal across): empty if it
// is, or a point (no size), else what is wrong, for a warning ("is 1.73e-15
// units across in the world; ..."). `render` and `run` warn with it.
std::string size_problem(const Bbox& bounds);
// The spacing of single-precision numbers near x (finite, non-zero): the
// detail a float coordinate that far from the origin keeps (0.0625 at 1e6).
double float_spacing_at(double x);

// Whether a scene shows a mesh placed in it with world bounds `bounds`: empty
// if it does, else what is wrong, for a warning ("lies at or under the ground
// plane (its top at y = 0, the ground at y = 0)", "covers at most 12 x 3
// pixels of the 1280 x 960 view", "is outside the camera's view"). Used where
// a mesh replaces the first object of a scene made for another (run --mesh),
// whose camera and ground may not suit it.
std::string placement_problem(const Scene& scene, const Bbox& bounds);

}  // namespace raylod
