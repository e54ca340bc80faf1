// The image codec (render/image_codec.h) is loaded only where an image is
// read or written: commands without images run without it, and a render
// that cannot load it fails before any work, naming where it looked, and
// writes nothing.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "run_command.h"
#include "test_tmp.h"

namespace {

using raylod::test::CommandResult;

CommandResult run(const std::string& env, const std::string& args) {
  return raylod::test::run_command(env + " " + std::string(RAYLOD_EXE) + " " + args);
}

const std::string kMissing = "RAYLOD_IMAGE_CODEC=/nonexistent/libraylod_oiio.so";

TEST(ImageCodec, TheProgramDoesNotLoadOpenImageIOAtStart) {
  // The dynamic loader lists every library it maps.
  const CommandResult r = run("LD_DEBUG=libs", "--version");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("libtbb"), std::string::npos) << "LD_DEBUG listed nothing:\n" << r.out.substr(0, 2000);
  EXPECT_EQ(r.out.find("libOpenImageIO"), std::string::npos);
}

// Each test its own folder: the build's store must not be in the render's
// folder, which that test checks is left empty.
TEST(ImageCodec, CommandsWithoutImagesRunWithoutIt) {
  const raylod::test::ScratchDir scratch("image-codec-commands");
  const auto& dir = scratch.path;
  const std::string stl = std::string(RAYLOD_DATA_DIR) + "/abc/abc5.stl";
  const CommandResult info = run(kMissing, "info " + stl);
  EXPECT_EQ(info.status, 0) << info.out;
  const CommandResult build = run(kMissing, "build " + stl + " -o " + (dir / "abc5.raylod").string() + " -q");
  EXPECT_EQ(build.status, 0) << build.out;
  EXPECT_TRUE(std::filesystem::exists(dir / "abc5.raylod"));
}

TEST(ImageCodec, ARenderWithoutItFailsNamingWhereItLookedAndWritesNothing) {
  const raylod::test::ScratchDir scratch("image-codec-render");
  const auto& dir = scratch.path;
  const auto out = dir / "frame.png";
  const CommandResult r = run(kMissing, "render --width 16 --height 12 -o " + out.string() + " -q");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("image codec"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("/nonexistent/libraylod_oiio.so"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_TRUE(std::filesystem::is_empty(dir));
}

TEST(ImageCodec, AFileThatIsNotTheModuleIsAnErrorNamingIt) {
  const raylod::test::ScratchDir scratch("image-codec-fake");
  const auto& dir = scratch.path;
  const auto fake = dir / "libraylod_oiio.so";
  std::ofstream(fake) << "not a shared library\n";
  const auto out = dir / "frame.png";
  const CommandResult r =
      run("RAYLOD_IMAGE_CODEC=" + fake.string(), "render --width 16 --height 12 -o " + out.string() + " -q");
  EXPECT_NE(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("cannot load the image codec " + fake.string()), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
