// Temporaries of atomic writes left by dead processes (kill -9 during a
// store build's final write) are removed by the next write to the same
// destination; those of live processes are not touched.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "core/system.h"
#include "test_tmp.h"

namespace raylod {
namespace {

pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return pid;
}

TEST(StaleTemporaries, DeadProcessesTemporariesAreRemovedLiveOnesKept) {
  const std::filesystem::path dir = test::scratch_dir("stale-temporaries");
  const std::filesystem::path dest = dir / "mesh.ply.raylod";
  const std::string dead = dest.filename().string() + ".tmp-" + std::to_string(dead_pid()) + "-0-123";
  const std::string live = dest.filename().string() + ".tmp-" + std::to_string(::getppid()) + "-0-456";
  const std::string mine = dest.filename().string() + ".tmp-" + std::to_string(::getpid()) + "-99-789";
  const std::string other = "other.raylod.tmp-" + std::to_string(dead_pid()) + "-0-1";
  for (const std::string& f : {dead, live, mine, other}) std::ofstream(dir / f) << "partial";
  {
    AtomicOutput out(dest);
    std::ofstream(out.temp_path()) << "store";
    ASSERT_TRUE(out.commit().is_ok());
  }
  EXPECT_FALSE(std::filesystem::exists(dir / dead));
  EXPECT_TRUE(std::filesystem::exists(dir / live));
  EXPECT_TRUE(std::filesystem::exists(dir / mine));
  EXPECT_TRUE(std::filesystem::exists(dir / other)) << "another destination's temporaries are its own business";
  EXPECT_TRUE(std::filesystem::exists(dest));
  std::filesystem::remove_all(dir);
}

TEST(StaleTemporaries, DeadProcessTemporaryByName) {
  const std::string dead = std::to_string(dead_pid());
  const std::string live = std::to_string(::getppid());
  EXPECT_TRUE(is_dead_process_temporary("k.cut.tmp-" + dead + "-0-12"));
  // A staged file and the Draco writer's temporary of it: the first .tmp- names the process.
  EXPECT_TRUE(is_dead_process_temporary("simplified-" + dead + "-0.drc.tmp-" + dead + "-1-7.drc"));
  EXPECT_TRUE(is_dead_process_temporary("simplified-" + dead + "-0.drc.tmp-" + dead + "-1-7.drc.tmp-" + dead + "-2-9"));
  EXPECT_FALSE(is_dead_process_temporary("k.cut.tmp-" + live + "-0-12"));
  EXPECT_FALSE(is_dead_process_temporary("k.cut.tmp-" + std::to_string(::getpid()) + "-0-12"));
  EXPECT_FALSE(is_dead_process_temporary("k.drc.tmp-insert"));
  EXPECT_FALSE(is_dead_process_temporary("k.drc"));
  EXPECT_FALSE(is_dead_process_temporary(".tmp-" + dead + "-0-1"));
}

}  // namespace
}  // namespace raylod
