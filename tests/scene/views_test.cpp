// View sequences: the --views file format (exact cases, defaults from the
// scene's camera, errors naming the file and the element) and --orbit's
// cameras.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "scene/orbit.h"
#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

Camera scene_camera() {
  Camera c;
  c.eye = Vec3d(0, 2, 5);
  c.look_at = Vec3d(0, 2, 0);
  c.up = Vec3d(0, 1, 0);
  c.fov_y_deg = 30;
  c.width = 64;
  c.height = 48;
  return c;
}

void expect_camera(const Camera& got, const Camera& want) {
  EXPECT_EQ(got.eye, want.eye);
  EXPECT_EQ(got.look_at, want.look_at);
  EXPECT_EQ(got.up, want.up);
  EXPECT_EQ(got.fov_y_deg, want.fov_y_deg);
  EXPECT_EQ(got.width, want.width);
  EXPECT_EQ(got.height, want.height);
}

TEST(Views, ParsesEveryFieldAndDefaultsTheRestToTheScenesCamera) {
  auto views = parse_views(R"([
    {"eye": [1, 2, 3], "look_at": [0, 0, 0]},
    {"eye": [4, 5, 6], "look_at": [1, 1, 1], "up": [0, 0, 1], "fov_y": 60, "width": 32, "height": 16}
  ])", scene_camera(), "views.json");
  ASSERT_TRUE(views.is_ok()) << views.status().message();
  ASSERT_EQ(views->size(), 2u);
  Camera a = scene_camera();  // eye and look_at given, the rest the scene's
  a.eye = Vec3d(1, 2, 3);
  a.look_at = Vec3d(0, 0, 0);
  expect_camera((*views)[0], a);
  const Camera b{Vec3d(4, 5, 6), Vec3d(1, 1, 1), Vec3d(0, 0, 1), 60, 32, 16};
  expect_camera((*views)[1], b);
}

TEST(Views, ErrorsNameTheFileAndTheElement) {
  const Camera c = scene_camera();
  auto error = [&](const std::string& text) {
    auto v = parse_views(text, c, "views.json");
    EXPECT_FALSE(v.is_ok()) << text;
    return v.is_ok() ? std::string() : v.status().message();
  };
  const std::string ok = R"({"eye": [0, 0, 5], "look_at": [0, 0, 0]})";
  EXPECT_EQ(error("[" + ok + "," + ok + "," + ok + R"(, {"eye": [1, 2], "look_at": [0, 0, 0]}])"),
            "views.json: [3].eye: expected an array of 3 numbers");
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5]}])"), "views.json: [0]: needs 'eye' and 'look_at'");
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov": 40}])"), "views.json: [0]: unknown key 'fov'");
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5], "look_at": [0, "a", 0]}])"), "views.json: [0].look_at[1]: expected a number");
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5], "look_at": [0, 0, 0], "width": 0}])"),
            "views.json: [0].width: must be between 1 and 32768");
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5], "look_at": [0, 0, 0], "fov_y": 180}])"),
            "views.json: [0].fov_y: must be in (0, 180) degrees");
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5], "look_at": [0, 0, 5]}])"), "views.json: [0]: eye and look_at coincide");
  EXPECT_EQ(error(R"([{"eye": [0, 5, 0], "look_at": [0, 0, 0]}])"),
            "views.json: [0].up: is zero or parallel to the viewing direction");
  EXPECT_EQ(error(R"([3])"), "views.json: [0]: expected an object");
  EXPECT_EQ(error(R"([])"), "views.json: expected a non-empty JSON array of cameras");
  {  // as many as --orbit takes, and no more
    std::string many = "[";
    for (int i = 0; i <= kMaxViews; ++i) many += (i ? ",{}" : "{}");
    many += "]";
    EXPECT_EQ(error(many), "views.json: 100001 cameras, more than the 100000 a run renders");
  }
  EXPECT_EQ(error(R"({"eye": [0, 0, 5], "look_at": [0, 0, 0]})"), "views.json: expected a non-empty JSON array of cameras");
  EXPECT_EQ(error("[{").rfind("views.json: not valid JSON: ", 0), 0u);
  EXPECT_EQ(error(R"([{"eye": [0, 0, 5], "look_at": [0, 0, 0]}, {"eye": [1e400, 0, 5], "look_at": [0, 0, 0]}])"),
            "views.json: [1].eye[0]: the number 1e400 is out of range (beyond the largest double, about 1.8e308)");
}

TEST(Views, LoadsAFileAndNamesAMissingOne) {
  const std::filesystem::path dir = test::scratch_dir("views-test");
  const std::filesystem::path file = dir / "v.json";
  std::ofstream(file) << R"([{"eye": [0, 0, 5], "look_at": [0, 0, 0]}])";
  auto v = load_views(file, scene_camera());
  ASSERT_TRUE(v.is_ok()) << v.status().message();
  EXPECT_EQ(v->size(), 1u);
  auto missing = load_views(dir / "none.json", scene_camera());
  ASSERT_FALSE(missing.is_ok());
  EXPECT_NE(missing.status().message().find("none.json"), std::string::npos) << missing.status().message();
}

void expect_near(const Vec3d& got, const Vec3d& want) {
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], want[k], 1e-12) << "component " << k;
}

TEST(Orbit, FourViewsAQuarterTurnApartAtTheEyesRadiusAndHeight) {
  Camera c = scene_camera();
  c.eye = Vec3d(1, 5, 4);  // 3 above look_at (1, 2, 0), radius 4
  c.look_at = Vec3d(1, 2, 0);
  auto views = orbit_cameras(c, 4);
  ASSERT_TRUE(views.is_ok()) << views.status().message();
  ASSERT_EQ(views->size(), 4u);
  EXPECT_EQ((*views)[0].eye, c.eye);  // starts exactly at the scene's eye
  expect_near((*views)[1].eye, Vec3d(5, 5, 0));
  expect_near((*views)[2].eye, Vec3d(1, 5, -4));
  expect_near((*views)[3].eye, Vec3d(-3, 5, 0));
  for (const Camera& v : *views) {
    Camera want = c;  // all but the eye as the scene's
    want.eye = v.eye;
    expect_camera(v, want);
  }
}

TEST(Orbit, TiltedUpVectorOrbitsInItsPlane) {
  Camera c = scene_camera();
  c.look_at = Vec3d(0);
  c.up = Vec3d(0, 0, 2);  // not normalised
  c.eye = Vec3d(2, 0, 1);
  auto views = orbit_cameras(c, 4);
  ASSERT_TRUE(views.is_ok());
  expect_near((*views)[1].eye, Vec3d(0, 2, 1));
  expect_near((*views)[2].eye, Vec3d(-2, 0, 1));
}

TEST(Orbit, RejectsNoViewsAndAnEyeOnTheAxis) {
  EXPECT_FALSE(orbit_cameras(scene_camera(), 0).is_ok());
  Camera c = scene_camera();
  c.eye = Vec3d(0, 7, 0);
  c.look_at = Vec3d(0, 2, 0);
  c.up = Vec3d(0, 0, 1);  // the eye is off the z axis through look_at: a circle
  EXPECT_TRUE(orbit_cameras(c, 3).is_ok());
  c.up = Vec3d(0, 1, 0);
  auto bad = orbit_cameras(c, 3);
  ASSERT_FALSE(bad.is_ok());
  EXPECT_NE(bad.status().message().find("no circle"), std::string::npos);
}

}  // namespace
}  // namespace raylod
