// Scratch directories for tests. ctest runs every test case as its own
// process, two at a time, so a directory shared by name between processes
// would race: each process gets its own (the pid is part of the name).
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace raylod::test {

// $RAYLOD_TEST_TMP (set by ctest to build/test-tmp) or the system temp dir,
// then "<name>-<pid>"; created if missing, kept (not emptied) if present.
inline std::filesystem::path scratch_dir(const std::string& name) {
  const char* env = std::getenv("RAYLOD_TEST_TMP");
  std::filesystem::path root = env && *env ? std::filesystem::path(env) : std::filesystem::temp_directory_path() / "raylod-test";
  std::filesystem::path dir = root / (name + "-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace raylod::test
