// The instruction level raylod is compiled for (CMake's RAYLOD_X86_LEVEL,
// x86-64-v2 by default) against the CPU running it: the machine that builds
// and tests raylod must run it, and the executable must start here.
#include <gtest/gtest.h>

#include <string>

#include "core/system.h"
#include "run_command.h"

namespace raylod {
namespace {

TEST(CpuLevel, TheBuildingMachineHasEveryFeatureTheBuildUses) {
  const char* missing = missing_cpu_feature();
  EXPECT_EQ(missing, nullptr) << "this CPU lacks " << missing;
}

#if defined(__x86_64__) && defined(RAYLOD_EXPECT_SSE4_2)
// A default build is compiled for x86-64-v2: the rounding the store build
// relies on for its speed is one instruction (README, "The store").
TEST(CpuLevel, TheDefaultLevelIsCompiledIn) {
#if !defined(__SSE4_2__) || !defined(__POPCNT__)
  FAIL() << "RAYLOD_X86_LEVEL asks for x86-64-v2 but SSE4.2/POPCNT code is not enabled";
#endif
}
#endif

TEST(CpuLevel, TheExecutableStarts) {
  std::string out;
  EXPECT_EQ(test::run_raylod("--version", out), 0) << out;
  EXPECT_NE(out.find("raylod "), std::string::npos) << out;
}

// `raylod help COMMAND` is the command's help; an unknown one is an error,
// as `raylod COMMAND` is.
TEST(Cli, HelpForACommandAndForAnUnknownOne) {
  std::string out;
  EXPECT_EQ(test::run_raylod("help probe", out), 0) << out;
  EXPECT_NE(out.find("usage: raylod probe"), std::string::npos) << out;
  EXPECT_EQ(test::run_raylod("help nosuch", out), 2) << out;
  EXPECT_NE(out.find("unknown command 'nosuch'"), std::string::npos) << out;
  EXPECT_EQ(test::run_raylod("nosuch", out), 2) << out;
}

}  // namespace
}  // namespace raylod
