// Options outside their range are refused before any work, naming the
// option, the same way in every command that takes them.
#include <gtest/gtest.h>

#include <string>

#include "run_command.h"

namespace raylod {
namespace {

TEST(OptionRanges, ZeroSizesSamplesAndErrorsAreRefused) {
  struct Case {
    std::string args, expect;
  };
  const Case cases[] = {
      {"report --width 0 -o unused-report", "--width must be between 1 and 32768"},
      {"report --height 0 -o unused-report", "--height must be between 1 and 32768"},
      {"report --spp 0 -o unused-report", "--spp must be between 1 and 4096"},
      {"report --default-scale 0 -o unused-report", "--default-scale must be positive"},
      {"render --spp 0 -o unused.png", "--spp must be between 1 and 4096"},
      {"simplify missing.raylod missing.cut -o unused.drc --position-error 0", "--position-error must be positive"},
      {"simplify missing.raylod missing.cut -o unused.drc --position-error -1", "--position-error must be positive"},
      {"probe --criterion diagonal --tolerance 2 -o unused.cut", "--tolerance bounds the deviation criterion"},
      {"run --criterion diagonal --angle-tolerance 4 -o unused.png", "--angle-tolerance bounds the deviation criterion"},
      {"run --cache '' -o unused.png", "--cache: an empty folder name"},
      {"report --scales 8,16,8 -o unused-report", "--scales: '8' is given twice"},
      {"probe --unseen-cells yes -o unused.cut", "--unseen-cells: unknown value 'yes' (on, frustum or off)"},
      {"run --unseen-cells 1 -o unused.png", "--unseen-cells: unknown value '1' (on, frustum or off)"},
      {"probe --unreached-angle 0 -o unused.cut", "--unreached-angle must be a finite multiple of --angle-tolerance"},
      {"run --unreached-angle -1 -o unused.png", "--unreached-angle must be a finite multiple of --angle-tolerance"},
      {"run --criterion diagonal --unreached-angle 4 -o unused.png", "--unreached-angle bounds the deviation criterion"},
      {"render --aov '' -o unused.png", "--aov: no AOV named; give one or more of depth, normal, triangle-id"},
      {"run --width 0 -o unused.png", "--width must be between 1 and 32768"},
      {"run --orbit 100001 -o unused_#.png", "--orbit must be between 1 and 100000"},
  };
  for (const Case& c : cases) {
    std::string out;
    EXPECT_NE(test::run_raylod(c.args, out), 0) << c.args << "\n" << out;
    EXPECT_NE(out.find(c.expect), std::string::npos) << c.args << "\n" << out;
  }
}

}  // namespace
}  // namespace raylod
