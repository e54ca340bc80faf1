// A CAD export with one stray coordinate (a vertex 1e8 out, beside a part a
// few units across): the store's position grid follows the bounding box, so
// it becomes too coarse for the part and every triangle loses a corner. The
// build says so, with the box that set the grid; `run` names the grid when
// the part simplifies to nothing. A mesh without strays gets no warning.
// Runs the raylod executable (this folder's tests may).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

// A 20 x 20 grid of unit squares in two triangles each, and with `stray`
// one more triangle reaching out to x = 1e8.
void write_part(const fs::path& p, bool stray) {
  std::ofstream f(p);
  for (int j = 0; j <= 20; ++j)
    for (int i = 0; i <= 20; ++i) f << "v " << i << " " << j << " " << 0.1 * ((i * j) % 3) << "\n";
  for (int j = 0; j < 20; ++j)
    for (int i = 0; i < 20; ++i) {
      const int a = j * 21 + i + 1, b = a + 1, c = a + 21, d = c + 1;
      f << "f " << a << " " << b << " " << d << "\nf " << a << " " << d << " " << c << "\n";
    }
  if (stray) f << "v 1e8 0 0\nf 1 2 " << 21 * 21 + 1 << "\n";
}

TEST(StrayVertex, TheBuildSaysTheGridIsTooCoarseAndWhy) {
  test::ScratchDir scratch("stray-vertex");
  write_part(scratch.path / "clean.obj", false);
  write_part(scratch.path / "stray.obj", true);
  std::string out;
  ASSERT_EQ(test::run_raylod("build " + (scratch.path / "clean.obj").string() + " -o " +
                                 (scratch.path / "clean.raylod").string(),
                             out),
            0)
      << out;
  EXPECT_EQ(out.find("warning"), std::string::npos) << out;
  ASSERT_EQ(test::run_raylod("build " + (scratch.path / "stray.obj").string() + " -o " +
                                 (scratch.path / "stray.raylod").string(),
                             out),
            0)
      << out;
  EXPECT_NE(out.find("raylod build: warning: 801 of 801 triangles lose a corner to the store's position grid"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("to (1e+08, 20, 0.2), 1e+08 across)"), std::string::npos) << out;
}

}  // namespace
}  // namespace raylod
