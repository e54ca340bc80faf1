// A scene around one mesh (scene/mesh_framing.h): the camera frames the
// bounds, the up axis becomes +Y as the scene format rotates it, the ground
// lies just below the mesh, the light scales with the camera; and `raylod
// scene` writes a scene that loads and renders, or a clear error and no file.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>

#include "run_command.h"
#include "streaming/gltf_test_util.h"
#include "scene/mesh_framing.h"
#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() { return test::scratch_dir("mesh-framing-test"); }

std::array<Vec3d, 8> corners_of(const Bbox& b) {
  std::array<Vec3d, 8> c;
  for (int i = 0; i < 8; ++i)
    c[size_t(i)] = Vec3d((i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z);
  return c;
}

// Where p lands in the camera's frame, as fractions of the half-width and
// half-height (x, y), and its depth (z): a pinhole camera's projection.
Vec3d frame_position(const Camera& cam, const Vec3d& p) {
  const Vec3d forward = glm::normalize(cam.look_at - cam.eye);
  const Vec3d right = glm::normalize(glm::cross(forward, cam.up));
  const Vec3d up = glm::cross(right, forward);
  const double ty = std::tan(cam.fov_y_deg * M_PI / 360.0), tx = ty * cam.width / cam.height;
  const Vec3d d = p - cam.eye;
  const double depth = glm::dot(d, forward);
  return Vec3d(glm::dot(d, right) / depth / tx, glm::dot(d, up) / depth / ty, depth);
}

TEST(MeshFraming, EveryCornerIsInTheFrameAndTheTightestTouchesTheFill) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> size(0.01, 50), where(-1e4, 1e4);
  for (int trial = 0; trial < 200; ++trial) {
    Bbox b;
    b.lo = Vec3d(where(rng), where(rng), where(rng));
    b.hi = b.lo + Vec3d(size(rng), size(rng), size(rng));
    FramingOptions o;
    o.up = UpAxis(trial % 6);
    o.width = trial % 2 ? 1280 : 300;
    o.height = trial % 3 ? 960 : 700;
    auto f = frame_mesh(b, o);
    ASSERT_TRUE(f.is_ok()) << f.status().message();
    const Camera& cam = f->camera;
    double widest = 0;
    for (const Vec3d& c : corners_of(f->bounds)) {
      const Vec3d s = frame_position(cam, c);
      ASSERT_GT(s.z, 0) << "a corner behind the eye, trial " << trial;
      EXPECT_LE(std::abs(s.x), o.fill + 1e-9) << trial;
      EXPECT_LE(std::abs(s.y), o.fill + 1e-9) << trial;
      widest = std::max({widest, std::abs(s.x), std::abs(s.y)});
    }
    EXPECT_GT(widest, o.fill - 1e-6) << "framed looser than it has to be, trial " << trial;
    EXPECT_FALSE(f->bounds.contains(f->camera.eye));
    EXPECT_NEAR(glm::length(f->camera.look_at - f->bounds.center()), 0.0, 1e-9 * (1 + glm::length(b.lo)));
  }
}

TEST(MeshFraming, TheUpAxisBecomesPlusYAsTheSceneFormatRotatesIt) {
  const Bbox b{Vec3d(1, 2, 3), Vec3d(2, 4, 6)};
  std::ofstream(temp_dir() / "part.stl") << "";  // the scene loader checks that the mesh is there
  const std::array<std::pair<UpAxis, Vec3d>, 6> axes{{{UpAxis::PosX, Vec3d(1, 0, 0)},
                                                      {UpAxis::NegX, Vec3d(-1, 0, 0)},
                                                      {UpAxis::PosY, Vec3d(0, 1, 0)},
                                                      {UpAxis::NegY, Vec3d(0, -1, 0)},
                                                      {UpAxis::PosZ, Vec3d(0, 0, 1)},
                                                      {UpAxis::NegZ, Vec3d(0, 0, -1)}}};
  for (const auto& [up, axis] : axes) {
    FramingOptions o;
    o.up = up;
    auto f = frame_mesh(b, o);
    ASSERT_TRUE(f.is_ok());
    const fs::path file = temp_dir() / (std::string("up") + to_string(up) + ".json");
    std::ofstream(file) << scene_json_for_mesh("part.stl", *f, MaterialPreset::Glossy, 4, "test");
    auto scene = load_scene(file);
    ASSERT_TRUE(scene.is_ok()) << scene.status().message();
    ASSERT_EQ(scene->objects.size(), 1u);
    const glm::dmat4& m = scene->objects[0].transform;
    const Vec3d turned = Vec3d(m * glm::dvec4(axis, 0.0));
    EXPECT_NEAR(glm::length(turned - Vec3d(0, 1, 0)), 0.0, 1e-12) << to_string(up);
    // The framing's bounds are the mesh's as the scene places it.
    Bbox placed;
    for (const Vec3d& c : corners_of(b)) placed.expand(Vec3d(m * glm::dvec4(c, 1.0)));
    EXPECT_NEAR(glm::length(placed.lo - f->bounds.lo), 0.0, 1e-12) << to_string(up);
    EXPECT_NEAR(glm::length(placed.hi - f->bounds.hi), 0.0, 1e-12) << to_string(up);
    EXPECT_EQ(scene->objects[0].mesh, temp_dir() / "part.stl");
    EXPECT_EQ(scene->spp, 4);
  }
}

TEST(MeshFraming, TheGroundLiesJustBelowTheLowestPointAndReachesTheHorizon) {
  for (const Bbox& b : {Bbox{Vec3d(0), Vec3d(1)}, Bbox{Vec3d(-5, -300, 2), Vec3d(5, -299.5, 9)},
                        Bbox{Vec3d(1e7, 1e7, 1e7), Vec3d(1e7 + 1e-3, 1e7 + 2e-3, 1e7 + 1e-3)}}) {
    auto f = frame_mesh(b, {});
    ASSERT_TRUE(f.is_ok()) << f.status().message();
    const double gap = f->bounds.lo.y - f->ground_height, diag = f->bounds.diagonal();
    EXPECT_GT(gap, 0.0);  // never on a face of the mesh
    EXPECT_LE(gap, 1.001e-3 * diag);
    EXPECT_GE(f->ground_size, 100 * diag);
  }
}

TEST(MeshFraming, TheLightScalesWithTheCamera) {
  const Bbox small{Vec3d(0), Vec3d(1, 2, 3)}, big{Vec3d(0), Vec3d(10, 20, 30)};
  auto a = frame_mesh(small, {}), b = frame_mesh(big, {});
  ASSERT_TRUE(a.is_ok() && b.is_ok());
  const double da = glm::length(a->camera.eye - a->camera.look_at), db = glm::length(b->camera.eye - b->camera.look_at);
  EXPECT_NEAR(db / da, 10.0, 1e-9);
  EXPECT_NEAR(b->light_intensity / a->light_intensity, 100.0, 1e-6);
  EXPECT_NEAR(glm::length(b->light_position - b->camera.look_at) / glm::length(a->light_position - a->camera.look_at),
              10.0, 1e-9);
  // The point light is above the mesh and lights the side the camera sees.
  EXPECT_GT(a->light_position.y, a->bounds.hi.y);
  EXPECT_GT(glm::dot(a->light_position - a->camera.look_at, a->camera.eye - a->camera.look_at), 0.0);
}

TEST(MeshFraming, NothingToFrameIsAnError) {
  EXPECT_FALSE(frame_mesh(Bbox{}, {}).is_ok());
  EXPECT_FALSE(frame_mesh(Bbox{Vec3d(1, 2, 3), Vec3d(1, 2, 3)}, {}).is_ok());
  EXPECT_FALSE(frame_mesh(Bbox{Vec3d(0), Vec3d(NAN, 1, 1)}, {}).is_ok());
  EXPECT_FALSE(frame_mesh(Bbox{Vec3d(0), Vec3d(1, INFINITY, 1)}, {}).is_ok());
  // Too small or too large for single-precision rays: an error that says so.
  for (double side : {1e-12, 1e-9, 1e13, 1e18}) {
    auto f = frame_mesh(Bbox{Vec3d(0), Vec3d(side, side, 0)}, {});
    EXPECT_FALSE(f.is_ok()) << side;
    if (!f.is_ok()) {
      EXPECT_NE(f.status().message().find("units across"), std::string::npos) << f.status().message();
    }
  }
  // A tiny mesh at the origin is tiny, not a point.
  const auto tiny = frame_mesh(Bbox{Vec3d(0), Vec3d(1e-15, 1e-15, 1e-15)}, {});
  ASSERT_FALSE(tiny.is_ok());
  EXPECT_NE(tiny.status().message().find("is 1.73e-15 units across"), std::string::npos) << tiny.status().message();
  // A point far from the origin: single precision's step there is named
  // (2^-4 at 1e6), a likely cause (a float32 file of a small part far out).
  const std::string point = frame_mesh(Bbox{Vec3d(1e6), Vec3d(1e6 + 1e-7)}, {}).status().message();
  EXPECT_NE(point.find("single point"), std::string::npos) << point;
  EXPECT_NE(point.find("are 0.0625 apart"), std::string::npos) << point;
  EXPECT_TRUE(frame_mesh(Bbox{Vec3d(0), Vec3d(1e-8, 1e-8, 0)}, {}).is_ok());
  EXPECT_TRUE(frame_mesh(Bbox{Vec3d(0), Vec3d(5e11, 5e11, 0)}, {}).is_ok());
  FramingOptions o;
  o.fill = 0;
  EXPECT_FALSE(frame_mesh(Bbox{Vec3d(0), Vec3d(1)}, o).is_ok());
  EXPECT_FALSE(parse_up_axis("w").is_ok());
  auto z = parse_up_axis("Z"), mx = parse_up_axis("-x");
  ASSERT_TRUE(z.is_ok() && mx.is_ok());
  EXPECT_EQ(*z, UpAxis::PosZ);
  EXPECT_EQ(*mx, UpAxis::NegX);
  EXPECT_FALSE(parse_material_preset("chrome").is_ok());
}

TEST(MeshFraming, ASizeOutsideWhatRaysResolveIsNamed) {
  EXPECT_EQ(size_problem(Bbox{}), "");
  EXPECT_EQ(size_problem(Bbox{Vec3d(2), Vec3d(2)}), "");  // a point has no size to judge
  EXPECT_EQ(size_problem(Bbox{Vec3d(0), Vec3d(1e-8, 0, 0)}), "");
  EXPECT_EQ(size_problem(Bbox{Vec3d(-5e11, 0, 0), Vec3d(5e11, 0, 0)}), "");
  for (double side : {1e-15, 1e-9, 2e12, 1e20}) {
    const std::string p = size_problem(Bbox{Vec3d(0), Vec3d(side, 0, 0)});
    EXPECT_EQ(p.rfind("is ", 0), 0u) << p;
    EXPECT_NE(p.find("units across in the world"), std::string::npos) << p;
    EXPECT_NE(p.find("scale the scene"), std::string::npos) << p;
  }
}

TEST(MeshFraming, APlacementProblemIsNamedAndAFramedMeshHasNone) {
  Scene scene;
  scene.camera.eye = Vec3d(0, 2, 10);
  scene.camera.look_at = Vec3d(0, 1, 0);
  scene.camera.fov_y_deg = 40;
  scene.camera.width = 800;
  scene.camera.height = 600;
  scene.ground = Ground{0.0, 100.0, 0};
  EXPECT_EQ(placement_problem(scene, Bbox{Vec3d(-1, 0, -1), Vec3d(1, 2, 1)}), "");
  EXPECT_NE(placement_problem(scene, Bbox{Vec3d(-1, -1, -1), Vec3d(1, 0, 1)}).find("under the ground plane"),
            std::string::npos);
  EXPECT_NE(placement_problem(scene, Bbox{Vec3d(0, 1, 0), Vec3d(0.01, 1.01, 0.01)}).find("covers at most"),
            std::string::npos);
  EXPECT_EQ(placement_problem(scene, Bbox{Vec3d(50, 1, 0), Vec3d(52, 3, 2)}), "is outside the camera's view");
  EXPECT_EQ(placement_problem(scene, Bbox{Vec3d(-1, 0, 9), Vec3d(1, 3, 11)}), "");  // around the eye: not judged
  // Wholly behind the eye (it looks down -z from z = 10): every corner's
  // depth is negative, which was taken for "around the eye".
  EXPECT_EQ(placement_problem(scene, Bbox{Vec3d(-1, 0, 12), Vec3d(1, 3, 14)}), "is behind the camera");
  EXPECT_EQ(placement_problem(scene, Bbox{Vec3d(1e5, 0, 1e5), Vec3d(1e5 + 1, 1, 1e5 + 1)}), "is behind the camera");
  // Whatever frame_mesh makes of a box, the box is shown.
  auto f = frame_mesh(Bbox{Vec3d(3, 4, 5), Vec3d(3.5, 4.1, 5.02)}, {});
  ASSERT_TRUE(f.is_ok());
  Scene framed;
  framed.camera = f->camera;
  framed.ground = Ground{f->ground_height, f->ground_size, 0};
  EXPECT_EQ(placement_problem(framed, f->bounds), "");
}

// A binary STL of an axis-aligned box, `lo` to `hi` (12 triangles, outward).
void write_box_stl(const fs::path& path, const Vec3d& lo, const Vec3d& hi) {
  std::ofstream f(path, std::ios::binary);
  char header[80] = {};
  f.write(header, 80);
  const uint32_t n = 12;
  f.write(reinterpret_cast<const char*>(&n), 4);
  auto corner = [&](int i) {
    return Vec3((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
  };
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    for (const auto& t : {std::array<int, 3>{q[0], q[1], q[2]}, std::array<int, 3>{q[0], q[2], q[3]}}) {
      float rec[12] = {};
      for (int k = 0; k < 3; ++k) {
        const Vec3 p = corner(t[size_t(k)]);
        rec[3 + 3 * k] = p.x;
        rec[4 + 3 * k] = p.y;
        rec[5 + 3 * k] = p.z;
      }
      f.write(reinterpret_cast<const char*>(rec), 48);
      const uint16_t attr = 0;
      f.write(reinterpret_cast<const char*>(&attr), 2);
    }
}

TEST(SceneCommand, WritesASceneThatFramesTheMeshAndRenders) {
  const fs::path dir = temp_dir() / "cli";
  fs::create_directories(dir / "parts");
  // A Z-up plate far from the origin, in its own folder below the scene's.
  write_box_stl(dir / "parts" / "plate.stl", Vec3d(5000, 7000, 100), Vec3d(5040, 7010, 102));
  std::string out;
  ASSERT_EQ(test::run_raylod("scene '" + (dir / "parts" / "plate.stl").string() + "' --up z --width 80 --height 60 --spp 1 -o '" +
                                 (dir / "plate.json").string() + "'",
                             out),
            0)
      << out;
  auto scene = load_scene(dir / "plate.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  // Named relative to the scene, so that the folder can move as a whole.
  std::ifstream text(dir / "plate.json");
  const std::string json((std::istreambuf_iterator<char>(text)), std::istreambuf_iterator<char>());
  EXPECT_NE(json.find("\"mesh\": \"parts/plate.stl\""), std::string::npos) << json;
  ASSERT_TRUE(scene->ground.has_value());
  const glm::dmat4& m = scene->objects[0].transform;
  Bbox placed;
  for (const Vec3d& c : corners_of(Bbox{Vec3d(5000, 7000, 100), Vec3d(5040, 7010, 102)}))
    placed.expand(Vec3d(m * glm::dvec4(c, 1.0)));
  EXPECT_NEAR(placed.extent().y, 2.0, 1e-9);  // the plate lies flat
  EXPECT_LT(scene->ground->height, placed.lo.y);
  EXPECT_EQ(scene->camera.width, 80);
  EXPECT_EQ(scene->spp, 1);
  ASSERT_EQ(test::run_raylod("render '" + (dir / "plate.json").string() + "' -q -o '" + (dir / "plate.png").string() + "'",
                             out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(dir / "plate.png"));
}

TEST(SceneCommand, ASceneWrittenThroughASymlinkLoadsThroughTheLinkAndItsTarget) {
  // -o a link into another folder: the file lands there (the link stays), and
  // is read through both names, so the mesh is named absolutely. Naming it
  // relative to the link's folder made the write's own load check fail.
  const fs::path dir = temp_dir() / "scene-link";
  fs::create_directories(dir / "sub");
  write_box_stl(dir / "box.stl", Vec3d(0, 0, 0), Vec3d(1, 1, 1));
  fs::create_symlink("sub/scene.json", dir / "link.json");
  std::string out;
  ASSERT_EQ(test::run_raylod("scene '" + (dir / "box.stl").string() + "' --width 32 --height 24 --spp 1 -q -o '" +
                                 (dir / "link.json").string() + "'",
                             out),
            0)
      << out;
  EXPECT_TRUE(fs::is_symlink(dir / "link.json"));
  for (const fs::path& name : {dir / "link.json", dir / "sub" / "scene.json"}) {
    auto scene = load_scene(name);
    ASSERT_TRUE(scene.is_ok()) << name << ": " << scene.status().message();
    EXPECT_TRUE(fs::equivalent(scene->objects[0].mesh, dir / "box.stl")) << name;
  }
}

TEST(SceneCommand, RunWithAMeshItsSceneDoesNotShowSaysSoAndPointsHere) {
  const fs::path dir = temp_dir() / "placement";
  fs::create_directories(dir);
  // Against the default scene (camera on a 3-unit teapot, ground at y = 0):
  // a plate under the ground, a 2 cm cube in view, a part the size of the
  // teapot.
  write_box_stl(dir / "under.stl", Vec3d(0, -0.25, 0), Vec3d(0.6, 0, 0.03));
  write_box_stl(dir / "tiny.stl", Vec3d(0, 1, 0), Vec3d(0.02, 1.02, 0.02));
  write_box_stl(dir / "fits.stl", Vec3d(-1.5, 0.01, -1), Vec3d(1.5, 2.5, 1));
  auto run = [&](const std::string& mesh) {
    std::string out;
    EXPECT_EQ(test::run_raylod("run --mesh '" + (dir / mesh).string() + "' --rays 200 --no-cache -o '" +
                                   (dir / (mesh + ".png")).string() + "'",
                               out),
              0)
        << out;
    return out;
  };
  const std::string under = run("under.stl");
  EXPECT_NE(under.find("lies at or under the ground plane"), std::string::npos) << under;
  EXPECT_NE(under.find("raylod scene"), std::string::npos) << under;
  const std::string tiny = run("tiny.stl");
  EXPECT_NE(tiny.find("covers at most"), std::string::npos) << tiny;
  const std::string fits = run("fits.stl");
  EXPECT_EQ(fits.find("raylod scene"), std::string::npos) << fits;
  // Far smaller than single-precision rays resolve: said by run and render.
  write_box_stl(dir / "speck.stl", Vec3d(0, 1e-10, 0), Vec3d(1e-10, 2e-10, 1e-10));
  const std::string speck = run("speck.stl");
  EXPECT_NE(speck.find("speck.stl is "), std::string::npos) << speck;
  // Once, of the mesh: not again of the simplified mesh's temporary file.
  EXPECT_EQ(speck.find("units across in the world"), speck.rfind("units across in the world")) << speck;
  EXPECT_EQ(speck.find(".tmp-"), std::string::npos) << speck;
  std::string rendered;
  EXPECT_EQ(test::run_raylod("render --mesh '" + (dir / "speck.stl").string() + "' --spp 1 -o '" +
                                 (dir / "speck-full.png").string() + "'",
                             rendered),
            0)
      << rendered;
  EXPECT_NE(rendered.find("speck.stl is "), std::string::npos) << rendered;
  EXPECT_NE(rendered.find("units across in the world"), std::string::npos) << rendered;
  EXPECT_EQ(fits.find("units across"), std::string::npos) << fits;
  // Behind the default camera (eye at +x +z, looking towards the origin).
  write_box_stl(dir / "behind.stl", Vec3d(40, 1, 40), Vec3d(41, 2, 41));
  const std::string behind = run("behind.stl");
  EXPECT_NE(behind.find("is behind the camera"), std::string::npos) << behind;
}

TEST(SceneCommand, AnObjectItsTransformPutsBeyondTheFloatRangeIsRefusedByRunRenderAndProbe) {
  // A transform within the float range that puts the mesh beyond it: the
  // object vanished from `run`'s image while `render` refused it (and
  // `probe` traced it and wrote a cut).
  const fs::path dir = temp_dir() / "overflow";
  fs::create_directories(dir);
  write_box_stl(dir / "box.stl", Vec3d(0, 0, 0), Vec3d(4, 4, 4));
  std::ofstream(dir / "s.json") << R"({"camera": {"eye": [20, 5, 20], "look_at": [0, 0, 0], "width": 32, "height": 24},
    "materials": {"m": {"type": "diffuse", "color": [0.5, 0.5, 0.5]}},
    "objects": [{"mesh": "box.stl", "material": "m", "transform": {"scale": 1e38}}]})";
  for (const std::string command : {"render", "run"}) {
    std::string out;
    EXPECT_EQ(test::run_raylod(command + " '" + (dir / "s.json").string() + (command == "run" ? "' --no-cache" : "'") + " -o '" +
                                   (dir / (command + ".png")).string() + "'",
                               out),
              1)
        << out;
    EXPECT_NE(out.find("s.json: objects[0]: "), std::string::npos) << out;
    EXPECT_NE(out.find("beyond the float range"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(dir / (command + ".png"))) << command;
  }
  std::string out;
  EXPECT_EQ(test::run_raylod("probe '" + (dir / "s.json").string() + "' -o '" + (dir / "p.cut").string() + "'", out), 1)
      << out;
  EXPECT_NE(out.find("s.json: objects[0]: the object's transform puts"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "p.cut"));
}

TEST(SceneCommand, AGltfFileIsFramedAsItsNodesPlaceItsMeshes) {
  // One unit square placed twice: at x = 10, and scaled by 2 at the origin.
  const fs::path dir = temp_dir() / "gltf";
  fs::create_directories(dir);
  test::GltfBuilder b;
  const int pos = b.positions({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}});
  const int mesh = b.mesh({test::GltfBuilder::primitive(pos, b.indices({0, 1, 2, 0, 2, 3}))});
  b.doc["nodes"] = nlohmann::json::array({{{"mesh", mesh}, {"translation", {10, 0, 0}}},
                                          {{"mesh", mesh}, {"scale", {2, 2, 2}}}});
  b.doc["scenes"] = nlohmann::json::array({{{"nodes", {0, 1}}}});
  b.doc["scene"] = 0;
  std::ofstream(dir / "two.gltf") << b.gltf();
  std::string out;
  ASSERT_EQ(test::run_raylod("scene '" + (dir / "two.gltf").string() + "' -o '" + (dir / "two.json").string() + "'",
                             out),
            0)
      << out;
  auto scene = load_scene(dir / "two.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  ASSERT_EQ(scene->objects.size(), 2u);  // one per node
  // The bounds of both placements, x 0 to 11, y 0 to 2.
  EXPECT_NEAR(glm::length(scene->camera.look_at - Vec3d(5.5, 1, 0)), 0.0, 1e-9);
  ASSERT_TRUE(scene->ground.has_value());
  EXPECT_LT(scene->ground->height, 0.0);
  EXPECT_NE(out.find("4 triangles"), std::string::npos) << out;
}

TEST(SceneCommand, BadInputIsAClearErrorAndWritesNothing) {
  const fs::path dir = temp_dir() / "bad";
  fs::create_directories(dir);
  std::string out;
  const fs::path scene = dir / "s.json";
  EXPECT_NE(test::run_raylod("scene '" + (dir / "missing.stl").string() + "' -o '" + scene.string() + "'", out), 0);
  EXPECT_NE(out.find("missing.stl"), std::string::npos) << out;
  std::ofstream(dir / "broken.stl") << "solid x\nfacet normal 0 0 1\n";
  out.clear();
  EXPECT_NE(test::run_raylod("scene '" + (dir / "broken.stl").string() + "' -o '" + scene.string() + "'", out), 0);
  EXPECT_NE(out.find("broken.stl"), std::string::npos) << out;
  write_box_stl(dir / "box.stl", Vec3d(0), Vec3d(1));
  out.clear();
  EXPECT_NE(test::run_raylod("scene '" + (dir / "box.stl").string() + "' --up w -o '" + scene.string() + "'", out), 0);
  EXPECT_NE(out.find("--up"), std::string::npos) << out;
  out.clear();
  EXPECT_NE(test::run_raylod("scene '" + (dir / "box.stl").string() + "' -o '" + (dir / "box.stl").string() + "'", out), 0);
  EXPECT_FALSE(fs::exists(scene));
  // Only the inputs are left: no scene and no temporary.
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 2u);
  EXPECT_EQ(fs::file_size(dir / "box.stl"), 84u + 12u * 50u);
}

}  // namespace
}  // namespace raylod
