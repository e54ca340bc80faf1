// Temporaries of atomic writes left by dead processes (kill -9 during a
// store build's final write) are removed by the next write to the same
// destination; those of live processes are not touched.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/system.h"
#include "streaming/octree_store.h"
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

// A destination name too long to take the temporary's suffix within 255
// bytes (a valid name of 236 bytes and more failed with "File name too
// long" after all the work): its temporaries take a shortened stem, and
// those of dead processes are still found and removed.
TEST(StaleTemporaries, ALongDestinationNameGetsAShortTemporary) {
  const std::filesystem::path dir = test::scratch_dir("stale-long");
  for (const size_t length : {size_t(100), size_t(127), size_t(128), size_t(200), size_t(255)}) {
    const std::string name = std::string(length - 4, 'a') + ".png";
    const std::filesystem::path dest = dir / name;
    const std::string stem = temporary_stem(name);
    EXPECT_EQ(stem == name, length <= 127) << length;
    EXPECT_LE(stem.size(), 127u);
    EXPECT_EQ(temporary_stem(name), stem) << "the same for every writer and cleaner";
    EXPECT_NE(temporary_stem(std::string(length - 4, 'b') + ".png"), stem);
    const std::string dead = stem + ".tmp-" + std::to_string(dead_pid()) + "@" +
                             process_tag().substr(process_tag().find('@') + 1) + "-0-1";
    ASSERT_LE(dead.size(), 255u);
    std::ofstream(dir / dead) << "partial";
    ASSERT_TRUE(std::filesystem::exists(dir / dead)) << length;
    {
      AtomicOutput out(dest);
      EXPECT_LE(out.temp_path().filename().string().size(), 255u);
      std::ofstream(out.temp_path()) << "image";
      ASSERT_TRUE(out.commit().is_ok()) << length;
    }
    EXPECT_TRUE(std::filesystem::exists(dest)) << length;
    EXPECT_FALSE(std::filesystem::exists(dir / dead)) << length;
  }
  size_t left = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left += e.path().string().find(".tmp-") != std::string::npos;
  EXPECT_EQ(left, 0u);
  std::filesystem::remove_all(dir);
}

// A store build killed while it wrote leaves its temporary, and the store
// it was to replace stays current: the next check of that store (a run, a
// `raylod build` that reuses it) removes the dead process's temporary.
TEST(StaleTemporaries, AReusedStoreTakesAKilledBuildsTemporaryAway) {
  const std::filesystem::path dir = test::scratch_dir("stale-temporaries");
  const std::filesystem::path mesh = dir / "tri.obj", store = dir / "tri.raylod";
  std::ofstream(mesh) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  StoreOptions options;
  options.memory_limit = uint64_t(64) << 20;
  ASSERT_TRUE(build_store(mesh, store, options).is_ok());
  const std::filesystem::path left = dir / ("tri.raylod.tmp-" + std::to_string(dead_pid()) + "-0-5");
  std::ofstream(left) << "half a store";
  auto again = build_store(mesh, store, options);
  ASSERT_TRUE(again.is_ok()) << again.status().message();
  EXPECT_TRUE(again->reused) << again->reason;
  EXPECT_FALSE(std::filesystem::exists(left));
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

TEST(StaleTemporaries, NamesCarryTheMachineAndOtherMachinesAreNeverJudged) {
  // Under mpirun several machines write to one shared folder: a pid of
  // another machine that is not running here says nothing about its process.
  const std::string dead = std::to_string(dead_pid());
  const std::string here = process_tag().substr(process_tag().find('@') + 1);
  EXPECT_EQ(process_tag(), std::to_string(::getpid()) + "@" + here);
  EXPECT_EQ(here.find('-'), std::string::npos);
  EXPECT_TRUE(is_dead_process_temporary("v_01.png.tmp-" + dead + "@" + here + "-0-12"));
  EXPECT_FALSE(is_dead_process_temporary("v_01.png.tmp-" + dead + "@other" + here + "-0-12"));
  EXPECT_FALSE(is_dead_process_temporary("v_01.png.tmp-" + dead + "@" + here));
  EXPECT_FALSE(is_dead_process_temporary("v_01.png.tmp-" + std::to_string(::getpid()) + "@" + here + "-0-12"));

  const std::filesystem::path dir = test::scratch_dir("stale-temporaries-hosts");
  const std::filesystem::path dest = dir / "v_01.png";
  const std::string other = dest.filename().string() + ".tmp-" + dead + "@other" + here + "-0-1";
  const std::string mine = dest.filename().string() + ".tmp-" + dead + "@" + here + "-0-2";
  for (const std::string& f : {other, mine}) std::ofstream(dir / f) << "partial";
  {
    AtomicOutput out(dest);
    EXPECT_NE(out.temp_path().filename().string().find(".tmp-" + process_tag() + "-"), std::string::npos);
    std::ofstream(out.temp_path()) << "image";
    ASSERT_TRUE(out.commit().is_ok());
  }
  EXPECT_TRUE(std::filesystem::exists(dir / other)) << "another machine's temporary was removed";
  EXPECT_FALSE(std::filesystem::exists(dir / mine));
  std::filesystem::remove_all(dir);
}

// mpirun ends the other ranks of a failed job with SIGTERM: a rank that was
// writing an image removes its temporary before it dies; what it committed
// stays.
TEST(StaleTemporaries, TerminatedProcessRemovesItsLiveTemporaries) {
  const std::filesystem::path dir = test::scratch_dir("sigterm-temporaries");
  EXPECT_EXIT(
      {
        AtomicOutput done(dir / "v_00.png");
        std::ofstream(done.temp_path()) << "image";
        if (!done.commit().is_ok()) std::_Exit(1);
        AtomicOutput live(dir / "v_01.png");
        std::ofstream(live.temp_path()) << "partial";
        std::raise(SIGTERM);
        std::_Exit(2);
      },
      testing::KilledBySignal(SIGTERM), "");
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"v_00.png"});
  std::filesystem::remove_all(dir);
}

// A file of the process's own that it removes itself (a staged simplified
// mesh in the cache folder, pipeline.h's ScratchFiles) goes with SIGTERM as
// the temporaries do, while it is registered; one given back stays.
TEST(StaleTemporaries, TerminatedProcessRemovesItsRegisteredScratchFiles) {
  const std::filesystem::path dir = test::scratch_dir("sigterm-scratch");
  EXPECT_EXIT(
      {
        std::ofstream(dir / "staged.drc") << "mesh";
        std::ofstream(dir / "kept.drc") << "mesh";
        int staged = register_scratch_file(dir / "staged.drc");
        int kept = register_scratch_file(dir / "kept.drc");
        if (staged < 0 || kept < 0) std::_Exit(1);
        release_scratch_file(kept);
        if (kept != -1) std::_Exit(3);
        std::raise(SIGTERM);
        std::_Exit(2);
      },
      testing::KilledBySignal(SIGTERM), "");
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"kept.drc"});
  std::filesystem::remove_all(dir);
}

TEST(StaleTemporaries, RunRemovesMeshesStagedInTheTempFolderByKilledRuns) {
  // run --no-cache stages its simplified mesh in the system temp folder; a
  // run killed before it removed it leaves it there, and the next run clears
  // it (never a live process's).
  const std::filesystem::path dir = test::scratch_dir("staged-in-tmp");
  const std::filesystem::path tmp = dir / "tmp";
  std::filesystem::create_directories(tmp);
  const std::string dead = std::to_string(dead_pid()), live = std::to_string(::getppid());
  const std::string dead_file = "simplified-" + dead + "-0.drc.tmp-" + dead + "-1-7.drc";
  const std::string live_file = "simplified-" + live + "-0.drc.tmp-" + live + "-1-7.drc";
  for (const std::string& f : {dead_file, live_file}) std::ofstream(tmp / f) << "partial";
  std::ofstream(dir / "tetra.ply") << "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                      "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
                                      "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  std::ofstream(dir / "scene.json")
      << R"({"camera": {"eye": [2, 1.5, 3], "look_at": [0.3, 0.3, 0.3], "fov_y": 40, "width": 32, "height": 24},
           "materials": {"m": {"type": "diffuse"}}, "objects": [{"mesh": "tetra.ply", "material": "m"}],
           "lights": [{"type": "point", "position": [3, 4, 2], "intensity": 30}], "spp": 1})";
  const std::string cmd = "TMPDIR='" + tmp.string() + "' '" + std::string(RAYLOD_EXE) + "' run '" +
                          (dir / "scene.json").string() + "' --no-cache -q --rays 100 -o '" + (dir / "x.png").string() +
                          "' > /dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_FALSE(std::filesystem::exists(tmp / dead_file));
  EXPECT_TRUE(std::filesystem::exists(tmp / live_file));
  std::filesystem::remove_all(dir);
}

// AtomicDirectory (a folder of outputs written whole or not at all): the
// folder it replaces goes whole, one never committed is removed, and a dead
// process's temporary folder goes with the next one to the same destination.
TEST(StaleTemporaries, AtomicDirectoryReplacesWholeOrNotAtAll) {
  test::ScratchDir scratch("atomic-directory");
  const std::filesystem::path dir = scratch.path, dest = dir / "rep";
  auto names = [&](const std::filesystem::path& d) {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(d)) out.push_back(e.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
  };
  std::filesystem::create_directories(dest / "meshes");
  std::ofstream(dest / "old.png") << "old";
  std::ofstream(dest / "meshes" / "old.drc") << "old";
  const std::string dead = "rep.tmp-" + std::to_string(dead_pid()) + "@" + process_tag().substr(process_tag().find('@') + 1) + "-0-1";
  const std::string live = "rep.tmp-" + std::to_string(::getppid()) + "-0-2";
  std::filesystem::create_directories(dir / dead / "meshes");
  std::ofstream(dir / dead / "meshes" / "half.drc") << "partial";
  std::filesystem::create_directories(dir / live);
  {
    AtomicDirectory never(dest);
    ASSERT_TRUE(never.create().is_ok());
    EXPECT_EQ(never.temp_path().parent_path(), dir);
    EXPECT_NE(never.temp_path().filename().string().find("rep.tmp-" + process_tag() + "-"), std::string::npos);
    std::ofstream(never.temp_path() / "new.png") << "new";
  }
  EXPECT_FALSE(std::filesystem::exists(dir / dead)) << "a dead process's folder was kept";
  EXPECT_EQ(names(dir), (std::vector<std::string>{"rep", live})) << "the uncommitted folder was kept";
  EXPECT_EQ(names(dest), (std::vector<std::string>{"meshes", "old.png"}));
  {
    AtomicDirectory next(dest);
    ASSERT_TRUE(next.create().is_ok());
    std::filesystem::create_directories(next.temp_path() / "meshes");
    std::ofstream(next.temp_path() / "new.png") << "new";
    ASSERT_TRUE(next.commit().is_ok());
  }
  EXPECT_EQ(names(dir), (std::vector<std::string>{"rep", live}));
  EXPECT_EQ(names(dest), (std::vector<std::string>{"meshes", "new.png"}));
  EXPECT_TRUE(std::filesystem::is_empty(dest / "meshes"));
  // Into a destination that is not there yet.
  {
    AtomicDirectory fresh(dir / "fresh");
    ASSERT_TRUE(fresh.create().is_ok());
    std::ofstream(fresh.temp_path() / "a") << "a";
    ASSERT_TRUE(fresh.commit().is_ok());
  }
  EXPECT_EQ(names(dir / "fresh"), std::vector<std::string>{"a"});
}

// A process ended by SIGTERM (or SIGINT) while it fills a temporary folder
// removes it, with everything in it, before it dies.
TEST(StaleTemporaries, TerminatedProcessRemovesItsTemporaryFolder) {
  test::ScratchDir scratch("sigterm-folder");
  const std::filesystem::path dir = scratch.path;
  std::filesystem::create_directories(dir / "rep");
  std::ofstream(dir / "rep" / "REPORT.md") << "old";
  EXPECT_EXIT(
      {
        AtomicDirectory staged(dir / "rep");
        if (!staged.create().is_ok()) std::_Exit(1);
        std::filesystem::create_directories(staged.temp_path() / "meshes" / "deeper");
        for (int i = 0; i < 300; ++i) std::ofstream(staged.temp_path() / ("f" + std::to_string(i) + ".png")) << i;
        std::ofstream(staged.temp_path() / "meshes" / "deeper" / "x.drc") << "x";
        AtomicOutput live(staged.temp_path() / "REPORT.md");
        std::ofstream(live.temp_path()) << "partial";
        std::raise(SIGTERM);
        std::_Exit(2);
      },
      testing::KilledBySignal(SIGTERM), "");
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(dir)) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"rep"});
  std::ifstream md(dir / "rep" / "REPORT.md");
  std::string text;
  std::getline(md, text);
  EXPECT_EQ(text, "old");
}

}  // namespace
}  // namespace raylod
