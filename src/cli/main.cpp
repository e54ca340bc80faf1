// raylod: out-of-core ray tracing of huge meshes with view-dependent
// simplification (Miyashita, Kanai and Kishinami; see README.md).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <optional>
#include <string>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <tbb/global_control.h>

#include "cli/cli.h"
#include "core/cluster.h"
#include "core/system.h"

namespace {

// The order a user meets the stages in, then the rest alphabetically.
int rank(const char* name) {
  const char* order[] = {"run", "build", "probe", "simplify", "render", "report", "info", "gen"};
  for (int i = 0; i < 8; ++i) if (std::strcmp(order[i], name) == 0) return i;
  return 100;
}

void print_help() {
  std::printf("usage: raylod <command> [options]   (raylod <command> --help for details)\n\n"
              "Ray traces huge triangle meshes out of core, simplifying them where the\n"
              "rays cannot resolve the detail (ray differentials + octree vertex clustering).\n\ncommands:\n");
  auto cmds = raylod::cli::commands();
  std::sort(cmds.begin(), cmds.end(), [](const auto& a, const auto& b) {
    return rank(a.name) != rank(b.name) ? rank(a.name) < rank(b.name) : std::strcmp(a.name, b.name) < 0;
  });
  for (const auto& c : cmds) std::printf("  %-10s %s\n", c.name, c.summary);
}

}  // namespace

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // Stages allocate and free large short-lived buffers (store pages in the
  // probe's cache, batches): a fixed mmap threshold returns them to the OS
  // instead of letting glibc raise the threshold after the first large free
  // and keep a fragmented heap, which keeps resident memory within
  // --memory-limit.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
#endif
  if (const char* feature = raylod::missing_cpu_feature()) {
    std::fprintf(stderr,
                 "raylod: this build uses %s instructions, which this CPU lacks; rebuild with\n"
                 "  cmake -S . -B build -DRAYLOD_X86_LEVEL=\"\"   (the compiler's default level)\n",
                 feature);
    return 1;
  }
  // Under mpirun, MPI for the whole command (core/cluster.h); otherwise nothing.
  raylod::cluster::Session cluster(argc, argv);
  // Every rank runs the same command line (cluster::same_command_line),
  // checked before anything can end a rank early: a rank started with
  // --help or --version beside ranks rendering is this error, not a job
  // that mpirun ends for a rank that left without MPI.
  if (const raylod::Status same = raylod::cluster::same_command_line(argc, argv); !same.is_ok()) {
    if (raylod::cluster::is_root()) std::fprintf(raylod::cluster::error_output(), "raylod: error: %s\n", same.message().c_str());
    return 1;
  }
  // `raylod help COMMAND` is `raylod COMMAND --help`.
  if (argc >= 3 && !std::strcmp(argv[1], "help")) {
    if (argc == 3)
      for (const auto& c : raylod::cli::commands())
        if (!std::strcmp(c.name, argv[2])) {
          char help_flag[] = "--help";
          char* args[] = {argv[2], help_flag, nullptr};
          return c.run(2, args);
        }
    std::fprintf(stderr, "raylod: help: unknown command '%s' (see raylod --help)\n", argv[2]);
    return 2;
  }
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "help")) {
    print_help();
    return argc < 2 ? 2 : 0;
  }
  if (!std::strcmp(argv[1], "--version")) {
    std::printf("raylod %s\n", RAYLOD_VERSION);
    return 0;
  }
  for (const auto& c : raylod::cli::commands()) {
    if (std::strcmp(c.name, argv[1]) == 0) {
      try {
        // The thread count is set here, once for the whole command: every
        // stage uses the ambient parallelism (core/parallelism.h).
        auto threads = raylod::cli::threads_from_argv(argc - 1, argv + 1);
        if (!threads.is_ok()) return raylod::cli::fail(c.name, threads.status());
        std::optional<tbb::global_control> parallelism;
        if (*threads > 0) parallelism.emplace(tbb::global_control::max_allowed_parallelism, size_t(*threads));
        return c.run(argc - 1, argv + 1);
      } catch (const std::exception& e) {
        // Under mpirun the other ranks may be waiting for this one: end the job.
        if (raylod::cluster::active())
          raylod::cluster::abort_job(std::string("raylod ") + c.name + ": internal error on rank " +
                                     std::to_string(raylod::cluster::rank()) + ": " + e.what(), 3);
        std::fprintf(stderr, "raylod %s: internal error: %s\n", c.name, e.what());
        return 3;
      }
    }
  }
  std::fprintf(stderr, "raylod: unknown command '%s' (see raylod --help)\n", argv[1]);
  return 2;
}
