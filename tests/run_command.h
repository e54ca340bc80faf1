// Runs a shell command for the CLI tests: its exit status and its output,
// standard error included.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace raylod::test {

struct CommandResult {
  int status = -1;  // exit status, -1 if it did not exit normally
  std::string out;  // stdout and stderr
};

inline CommandResult run_command(const std::string& cmd) {
  CommandResult r;
  std::FILE* p = ::popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = ::pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

// `raylod ARGS`: appends its output to `out`, returns its exit status.
inline int run_raylod(const std::string& args, std::string& out) {
  CommandResult r = run_command(std::string(RAYLOD_EXE) + " " + args);
  out += r.out;
  return r.status;
}

}  // namespace raylod::test
