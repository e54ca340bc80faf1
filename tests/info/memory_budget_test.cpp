// One meaning of a memory size: the command line resolves --memory-limit once
// (its default, a quarter of physical memory, becomes a number there) and
// passes it down; inside the library 0 means no limit. The end-to-end cases
// run the raylod executable (this folder's tests may).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/memory_budget.h"
#include "core/system.h"
#include "streaming/octree_store.h"
#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

int run(const std::string& args, std::string& out) { return test::run_raylod(args, out); }

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(MemoryBudget, TheDefaultIsAQuarterOfPhysicalMemory) {
  const uint64_t quarter = physical_memory_bytes() / 4;
  EXPECT_EQ(MemoryBudget::default_total(), quarter);
  EXPECT_EQ(MemoryBudget::resolve(std::nullopt).total, quarter);
  EXPECT_EQ(MemoryBudget::resolve(quarter).total, quarter);
  EXPECT_EQ(MemoryBudget::resolve(uint64_t(1) << 30).total, uint64_t(1) << 30);
  EXPECT_GT(MemoryBudget::resolve(std::nullopt).baseline, 0u);
}

// What the stages may use does not follow the process's resident size,
// which wanders by megabytes from run to run, with the thread count and
// under mpirun: a cut coarsened to fit must come out the same every time.
TEST(MemoryBudget, WhatTheStagesMayUseDoesNotDependOnWhatIsResident) {
  const uint64_t limit = uint64_t(512) << 20;
  const uint64_t before = MemoryBudget::of(limit).working();
  std::vector<char> held(size_t(64) << 20, 1);  // 64 MiB resident more
  EXPECT_EQ(MemoryBudget::of(limit).working(), before) << int(held[held.size() / 2]);
  EXPECT_EQ(MemoryBudget::resolve(limit).working(), before);
  EXPECT_EQ(before, limit - kProgramBytes);
}

TEST(MemoryBudget, ZeroMeansNoLimit) {
  const MemoryBudget none = MemoryBudget::of(0);
  EXPECT_FALSE(none.limited());
  EXPECT_EQ(none.working(), 0u);  // no limit for simplify and render
  EXPECT_EQ(none.page_cache(uint64_t(1) << 40, uint64_t(1) << 40), UINT64_MAX);
  // A limit below what is already resident leaves nothing, which is not "no limit".
  const MemoryBudget tiny = MemoryBudget::of(1);
  EXPECT_TRUE(tiny.limited());
  EXPECT_EQ(tiny.working(), 1u);
  EXPECT_EQ(tiny.page_cache(1 << 20, 0), 0u);
}

TEST(MemoryBudget, TheCommandLineDefaultAndAnExplicitQuarterBuildTheSameStore) {
  const fs::path dir = test::scratch_dir("memory-budget");
  const fs::path mesh = dir / "tri.obj";
  std::ofstream(mesh) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n";
  const uint64_t quarter = physical_memory_bytes() / 4;
  const fs::path by_default = dir / "default.raylod", explicit_quarter = dir / "quarter.raylod";
  std::string out;
  ASSERT_EQ(run("build -q " + mesh.string() + " -o " + by_default.string(), out), 0) << out;
  ASSERT_EQ(run("build -q " + mesh.string() + " -o " + explicit_quarter.string() + " --memory-limit " +
                    std::to_string(quarter), out), 0) << out;
  for (const fs::path& p : {by_default, explicit_quarter}) {
    auto store = OctreeStore::open(p);
    ASSERT_TRUE(store.is_ok()) << store.status().message();
    EXPECT_EQ((*store)->header().options.memory_limit, quarter) << p;  // a number, resolved by the command
  }
  EXPECT_TRUE(read_bytes(by_default) == read_bytes(explicit_quarter));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace raylod
