// Scratch directories for tests. ctest runs every test case as its own
// process, two at a time, so a directory shared by name between processes
// would race: each process gets its own (the pid is part of the name).
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>

namespace raylod::test {

// The scratch directories this process made, removed when it exits (after
// every test has run, pass or fail), and the default root with them if it is
// left empty.
struct ScratchRegistry {
  std::set<std::filesystem::path> dirs;
  std::filesystem::path default_root;
  ~ScratchRegistry() {
    std::error_code ec;
    for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
    if (!default_root.empty()) std::filesystem::remove(default_root, ec);  // only if empty
  }
};
inline ScratchRegistry& scratch_registry() {
  static ScratchRegistry registry;
  return registry;
}

// $RAYLOD_TEST_TMP (set by ctest to build/test-tmp) or the system temp dir's
// raylod-test, then "<name>-<pid>"; created if missing, kept (not emptied)
// if present, and removed when the process exits.
inline std::filesystem::path scratch_dir(const std::string& name) {
  const char* env = std::getenv("RAYLOD_TEST_TMP");
  const bool own_root = !(env && *env);
  std::filesystem::path root = own_root ? std::filesystem::temp_directory_path() / "raylod-test" : std::filesystem::path(env);
  std::filesystem::path dir = root / (name + "-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ScratchRegistry& registry = scratch_registry();
  registry.dirs.insert(dir);
  if (own_root) registry.default_root = root;
  return dir;
}

// A scratch directory (scratch_dir(name)) removed when it goes out of scope:
// at the end of the test that made it, pass or fail.
struct ScratchDir {
  std::filesystem::path path;
  explicit ScratchDir(const std::string& name) : path(scratch_dir(name)) {}
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
};

}  // namespace raylod::test
