// Scene files: the embedded default parses, relative paths resolve against the
// scene file, and malformed scenes fail with messages that say what is wrong.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() { return test::scratch_dir("scene-test"); }

const char* kMinimal = R"({
  "camera": {"eye": [0, 1, 5], "look_at": [0, 0, 0], "fov_y": 40, "width": 64, "height": 48},
  "materials": {"red": {"type": "diffuse", "color": [0.8, 0.1, 0.1]},
                "glass": {"type": "glass", "ior": 1.5, "tint": [0.9, 1, 0.9]}},
  "objects": [{"mesh": {"generate": "teapot", "triangles": 5000}, "material": "red",
               "transform": {"translate": [1, 2, 3], "scale": 2}}],
  "lights": [{"type": "point", "position": [0, 5, 0], "intensity": 10},
             {"type": "directional", "direction": [0, -2, 0]}],
  "spp": 2, "max_depth": 3, "seed": 7
})";

TEST(Scene, DefaultSceneParses) {
  auto scene = default_scene();
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  EXPECT_EQ(scene->camera.width, 1280);
  EXPECT_EQ(scene->camera.height, 960);
  ASSERT_EQ(scene->objects.size(), 1u);
  ASSERT_TRUE(scene->objects[0].generate.has_value());
  EXPECT_EQ(scene->objects[0].generate->generator, "teapot");
  EXPECT_TRUE(scene->ground.has_value());
  EXPECT_FALSE(scene->lights.empty());
}

TEST(Scene, ParsesAllFields) {
  auto scene = parse_scene(kMinimal, ".", "minimal.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  EXPECT_EQ(scene->spp, 2);
  EXPECT_EQ(scene->max_depth, 3);
  EXPECT_EQ(scene->seed, 7u);
  ASSERT_EQ(scene->materials.size(), 2u);
  EXPECT_TRUE(scene->any_refraction());
  EXPECT_TRUE(scene->any_reflection());
  const auto& t = scene->objects[0].transform;
  // Scale 2 then translate (1, 2, 3): the origin maps to the translation.
  glm::dvec4 o = t * glm::dvec4(0, 0, 0, 1);
  EXPECT_DOUBLE_EQ(o.x, 1);
  EXPECT_DOUBLE_EQ(o.z, 3);
  glm::dvec4 x = t * glm::dvec4(1, 0, 0, 1);
  EXPECT_DOUBLE_EQ(x.x, 3);
  ASSERT_EQ(scene->lights.size(), 2u);
  EXPECT_NEAR(glm::length(scene->lights[1].direction), 1.0, 1e-12);
}

TEST(Scene, DiffuseOnlySceneCallsForNoSpecularRays) {
  std::string text = kMinimal;
  const std::string glass = "\"glass\": {\"type\": \"glass\", \"ior\": 1.5, \"tint\": [0.9, 1, 0.9]}";
  ASSERT_NE(text.find(glass), std::string::npos);
  text.replace(text.find(glass), glass.size(), "\"glass\": {\"type\": \"glossy\"}");
  auto scene = parse_scene(text, ".", "s.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  EXPECT_FALSE(scene->any_refraction());
  EXPECT_FALSE(scene->any_reflection());
}

// A light that adds nothing (intensity 0, or colour black) is left out:
// the render traced a shadow ray per hit for it and the probe held cells
// for its shadows, for the same image as without it.
TEST(Scene, ALightThatAddsNothingIsLeftOut) {
  std::string text = kMinimal;
  const std::string point = R"("intensity": 10})";
  ASSERT_NE(text.find(point), std::string::npos);
  for (const std::string& nothing : {std::string(R"("intensity": 0})"), std::string(R"("intensity": 10, "color": [0, 0, 0]})")}) {
    std::string t = text;
    t.replace(t.find(point), point.size(), nothing);
    auto scene = parse_scene(t, ".", "s.json");
    ASSERT_TRUE(scene.is_ok()) << scene.status().message();
    ASSERT_EQ(scene->lights.size(), 1u) << nothing;
    EXPECT_EQ(scene->lights[0].type, LightType::Directional);
  }
}

TEST(Scene, RelativeMeshPathResolvesAgainstSceneFile) {
  fs::path dir = temp_dir() / "sub";
  fs::create_directories(dir);
  std::ofstream(dir / "m.ply") << "ply\n";
  std::ofstream(dir / "s.json") << R"({"camera": {"eye": [0,0,5], "look_at": [0,0,0]},
    "materials": {"m": {"type": "mirror"}}, "objects": [{"mesh": "m.ply", "material": "m"}]})";
  auto scene = load_scene(dir / "s.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  EXPECT_EQ(fs::canonical(scene->objects[0].mesh), fs::canonical(dir / "m.ply"));
  fs::remove_all(temp_dir());
}

TEST(Scene, AUniformMicrometreScaleIsNotSingular) {
  // |det| = 1e-18 here: singular only relative to the columns' lengths.
  std::string text = kMinimal;
  const std::string from = "\"scale\": 2";
  text.replace(text.find(from), from.size(), "\"scale\": 1e-6");
  auto scene = parse_scene(text, ".", "micro.json");
  ASSERT_TRUE(scene.is_ok()) << scene.status().message();
  EXPECT_DOUBLE_EQ(scene->objects[0].transform[0][0], 1e-6);
}

struct BadCase {
  const char* name;
  std::string from, to;  // replace `from` in kMinimal by `to`
  const char* expected;  // substring of the error
};

// Short names in test listings (ctest shows the parameter).
void PrintTo(const BadCase& c, std::ostream* os) { *os << c.name; }

class BadScene : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadScene, FailsWithClearMessage) {
  const BadCase& c = GetParam();
  std::string text = kMinimal;
  auto pos = text.find(c.from);
  ASSERT_NE(pos, std::string::npos) << c.from;
  text.replace(pos, c.from.size(), c.to);
  auto scene = parse_scene(text, ".", "bad.json");
  ASSERT_FALSE(scene.is_ok()) << c.name;
  EXPECT_NE(scene.status().message().find("bad.json"), std::string::npos) << scene.status().message();
  EXPECT_NE(scene.status().message().find(c.expected), std::string::npos) << scene.status().message();
}

INSTANTIATE_TEST_SUITE_P(
    Cases, BadScene,
    ::testing::Values(
        BadCase{"syntax", "\"spp\": 2,", "\"spp\": 2,,", "not valid JSON"},
        BadCase{"missing_mesh", "{\"generate\": \"teapot\", \"triangles\": 5000}", "\"nope/missing.ply\"", "file not found"},
        BadCase{"unknown_material", "\"material\": \"red\"", "\"material\": \"blue\"", "no material named 'blue'"},
        BadCase{"bad_type", "\"type\": \"diffuse\"", "\"type\": \"plastic\"", "'plastic' is not one of"},
        BadCase{"fov", "\"fov_y\": 40", "\"fov_y\": 190", "fov_y"},
        BadCase{"eye_equals_target", "\"eye\": [0, 1, 5]", "\"eye\": [0, 0, 0]", "coincide"},
        BadCase{"vec_size", "\"look_at\": [0, 0, 0]", "\"look_at\": [0, 0]", "array of 3 numbers"},
        BadCase{"typo_key", "\"spp\": 2", "\"sppp\": 2", "unknown key 'sppp'"},
        BadCase{"negative_color", "[0.8, 0.1, 0.1]", "[0.8, -0.1, 0.1]", ">= 0"},
        BadCase{"ior", "\"ior\": 1.5", "\"ior\": 0.5", "ior"},
        BadCase{"light_type", "\"type\": \"point\"", "\"type\": \"spot\"", "'point' or 'directional'"},
        BadCase{"zero_direction", "[0, -2, 0]", "[0, 0, 0]", "must not be zero"},
        BadCase{"singular_transform", "\"scale\": 2", "\"scale\": 0", "singular"},
        BadCase{"spp_range", "\"spp\": 2", "\"spp\": 0", "spp"},
        BadCase{"generator", "\"generate\": \"teapot\"", "\"generate\": \"cow\"", "'cow'"},
        // Numbers past the double range: the file and the JSON path, not "internal error".
        BadCase{"number_overflow", "\"scale\": 2", "\"scale\": 1e400",
                "bad.json: objects[0].transform.scale: the number 1e400 is out of range"},
        BadCase{"number_overflow_in_array", "\"translate\": [1, 2, 3]", "\"translate\": [1, -1e999, 3]",
                "bad.json: objects[0].transform.translate[1]: the number -1e999 is out of range"},
        BadCase{"number_overflow_in_material", "\"ior\": 1.5", "\"ior\": 2e308", "materials.glass.ior: the number 2e308"},
        BadCase{"number_overflow_at_top_level", "\"seed\": 7", "\"seed\": 1E+400", "bad.json: seed: the number 1E+400"},
        // Numbers held as floats: beyond the float range they would turn infinite.
        BadCase{"float_overflow_intensity", "\"intensity\": 10", "\"intensity\": 1e39",
                "bad.json: lights[0].intensity: is beyond the float range"},
        BadCase{"float_overflow_color", "[0.8, 0.1, 0.1]", "[0.8, 1e39, 0.1]",
                "bad.json: materials.red.color[1]: is beyond the float range"},
        BadCase{"float_overflow_ior", "\"ior\": 1.5", "\"ior\": -1e39", "materials.glass.ior: is beyond the float range"},
        // Positions and sizes the renderer holds as floats: a transform or a
        // ground beyond that range would put the object or the ground at
        // infinity (it vanished without a word).
        BadCase{"float_overflow_translate", "\"translate\": [1, 2, 3]", "\"translate\": [1e39, 2, 3]",
                "bad.json: objects[0].transform: is beyond the float range"},
        BadCase{"float_overflow_scale", "\"scale\": 2", "\"scale\": 1e39", "objects[0].transform: is beyond the float range"},
        BadCase{"float_overflow_light_position", "\"position\": [0, 5, 0]", "\"position\": [0, 1e39, 0]",
                "bad.json: lights[0].position[1]: is beyond the float range"},
        BadCase{"float_overflow_ground_size", "\"spp\": 2,", "\"ground\": {\"size\": 1e39, \"material\": \"red\"}, \"spp\": 2,",
                "bad.json: ground.size: is beyond the float range"},
        BadCase{"float_overflow_ground_height", "\"spp\": 2,",
                "\"ground\": {\"height\": -4e38, \"material\": \"red\"}, \"spp\": 2,",
                "bad.json: ground.height: is beyond the float range"},
        // nlohmann keeps the last of two equal keys without a word.
        BadCase{"duplicate_key", "\"spp\": 2,", "\"spp\": 2, \"spp\": 3,", "bad.json: spp: is given twice"},
        BadCase{"duplicate_nested_key", "\"fov_y\": 40", "\"fov_y\": 40, \"fov_y\": 50",
                "bad.json: camera.fov_y: is given twice"},
        BadCase{"duplicate_key_in_array", "\"intensity\": 10", "\"intensity\": 10, \"intensity\": 1",
                "bad.json: lights[0].intensity: is given twice"},
        // A column-major matrix pasted by mistake: its translation would be dropped.
        BadCase{"non_affine_matrix", "\"translate\": [1, 2, 3], \"scale\": 2",
                "\"matrix\": [1, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0.2, 0, 0, 1]", "the last row must be 0 0 0 1"},
        BadCase{"flat_transform", "\"scale\": 2", "\"scale\": [1, 1, 0]", "singular"},
        // Keys another type uses would be ignored: refused, naming the key.
        BadCase{"tint_on_diffuse", "\"color\": [0.8, 0.1, 0.1]}", "\"color\": [0.8, 0.1, 0.1], \"tint\": [1, 1, 1]}",
                "materials.red.tint: is not used by a diffuse material (only by glass)"},
        BadCase{"reflectance_on_glass", "\"ior\": 1.5,", "\"ior\": 1.5, \"reflectance\": 0.5,",
                "materials.glass.reflectance: is not used by a glass material (only by mirror)"},
        BadCase{"ior_on_diffuse", "\"color\": [0.8, 0.1, 0.1]}", "\"color\": [0.8, 0.1, 0.1], \"ior\": 1.3}",
                "materials.red.ior: is not used by a diffuse material"},
        BadCase{"position_on_directional", "\"direction\": [0, -2, 0]", "\"direction\": [0, -2, 0], \"position\": [1, 2, 3]",
                "lights[1].position: is not used by a directional light"},
        BadCase{"direction_on_point", "\"position\": [0, 5, 0]", "\"position\": [0, 5, 0], \"direction\": [0, -1, 0]",
                "lights[0].direction: is not used by a point light"},
        // Embree refuses ray origins beyond about 1.8e18 (it asserted before).
        BadCase{"eye_too_far", "\"eye\": [0, 1, 5]", "\"eye\": [2e18, 1, 5]",
                "camera.eye: is more than 1e18 from look_at"}),
    [](const auto& test_case) { return std::string(test_case.param.name); });

TEST(Scene, AFirstMeshReplacedByTheCommandNeedNotExist) {
  // `--mesh` stands in for the first object's mesh: a scene written on
  // another machine renders with a local mesh. Every other mesh must exist.
  const std::string text = R"({"camera": {"eye": [0,0,5], "look_at": [0,0,0]},
    "materials": {"m": {"type": "diffuse"}},
    "objects": [{"mesh": "gone.ply", "material": "m"}, {"mesh": "SECOND", "material": "m"}]})";
  fs::path dir = temp_dir() / "replaced";
  fs::create_directories(dir);
  std::ofstream(dir / "here.ply") << "ply\n";
  auto with_second = [&](const std::string& second) {
    std::string t = text;
    t.replace(t.find("SECOND"), 6, second);
    return t;
  };
  auto missing = parse_scene(with_second("here.ply"), dir, "s.json");
  ASSERT_FALSE(missing.is_ok());
  EXPECT_NE(missing.status().message().find("objects[0].mesh: file not found"), std::string::npos)
      << missing.status().message();
  auto replaced = parse_scene(with_second("here.ply"), dir, "s.json", /*first_mesh_replaced=*/true);
  ASSERT_TRUE(replaced.is_ok()) << replaced.status().message();
  EXPECT_EQ(replaced->objects.size(), 2u);
  EXPECT_EQ(replaced->objects[0].mesh, dir / "gone.ply");
  auto second_missing = parse_scene(with_second("gone2.ply"), dir, "s.json", true);
  ASSERT_FALSE(second_missing.is_ok());
  EXPECT_NE(second_missing.status().message().find("objects[1].mesh: file not found"), std::string::npos)
      << second_missing.status().message();
  fs::remove_all(temp_dir());
}

TEST(Scene, MissingFileIsAnError) {
  auto scene = load_scene("/nonexistent/scene.json");
  ASSERT_FALSE(scene.is_ok());
  EXPECT_NE(scene.status().message().find("/nonexistent/scene.json"), std::string::npos);
}

}  // namespace
}  // namespace raylod
