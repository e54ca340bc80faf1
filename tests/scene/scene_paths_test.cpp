// Scene files whose mesh paths (or the scene path itself) are not regular
// files: the error says what the path really is (a directory, a named pipe)
// instead of "file not found", and a named pipe never blocks the load.
#include <gtest/gtest.h>

#include "fifo_guard.h"
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>

#include "scene/scene.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class ScenePaths : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::scratch_dir("scene-paths"); }
  void TearDown() override { fs::remove_all(dir_); }

  // A scene in dir_ whose one object's mesh is `mesh`.
  fs::path scene_with_mesh(const std::string& mesh) {
    const fs::path p = dir_ / "s.json";
    std::ofstream(p) << R"({"camera": {"eye": [0,0,5], "look_at": [0,0,0]},
      "materials": {"m": {"type": "diffuse"}}, "objects": [{"mesh": ")" << mesh << R"(", "material": "m"}]})";
    return p;
  }
  std::string load_error(const fs::path& scene) {
    auto s = load_scene(scene);
    return s.is_ok() ? std::string() : s.status().message();
  }

  fs::path dir_;
};

using test::without_blocking;

TEST_F(ScenePaths, MeshThatIsADirectory) {
  fs::create_directories(dir_ / "parts.ply");
  const std::string msg = load_error(scene_with_mesh("parts.ply"));
  EXPECT_NE(msg.find("s.json: objects[0].mesh: "), std::string::npos) << msg;
  EXPECT_NE(msg.find("parts.ply: is a directory"), std::string::npos) << msg;
  EXPECT_EQ(msg.find("file not found"), std::string::npos) << msg;
}

TEST_F(ScenePaths, MeshThatIsANamedPipe) {
  ASSERT_EQ(::mkfifo((dir_ / "pipe.ply").c_str(), 0600), 0);
  const std::string msg = load_error(scene_with_mesh("pipe.ply"));
  EXPECT_NE(msg.find("s.json: objects[0].mesh: "), std::string::npos) << msg;
  EXPECT_NE(msg.find("pipe.ply: is a named pipe (FIFO), not a regular file"), std::string::npos) << msg;
}

TEST_F(ScenePaths, MeshThatIsACharacterDevice) {
  const std::string msg = load_error(scene_with_mesh("/dev/null"));
  EXPECT_NE(msg.find("objects[0].mesh: /dev/null: is a character device"), std::string::npos) << msg;
}

TEST_F(ScenePaths, MissingMeshIsStillFileNotFound) {
  const std::string msg = load_error(scene_with_mesh("gone.ply"));
  EXPECT_NE(msg.find("objects[0].mesh: file not found: "), std::string::npos) << msg;
}

TEST_F(ScenePaths, SceneFileThatIsANamedPipeDoesNotBlock) {
  const fs::path fifo = dir_ / "scene.json";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string msg = without_blocking(fifo, [&] { return load_error(fifo); });
  EXPECT_NE(msg.find("scene.json: is a named pipe (FIFO), not a regular file"), std::string::npos) << msg;
}

}  // namespace
}  // namespace raylod
