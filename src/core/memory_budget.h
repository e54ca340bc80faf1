// One memory budget per command: --memory-limit resolved once, and the share
// each stage of `raylod run` (and probe, report) may use.
//
//   total      --memory-limit, resolved once by the command line: the value
//              given, else default_total(), a quarter of physical memory.
//              Inside the library 0 means no limit, here and in every
//              options struct with a memory_limit (and cache_bytes).
//   baseline   what the process holds before any stage starts (code, the
//              libraries' data, the runtime): kProgramBytes, a fixed
//              allowance, not the resident size measured when the budget is
//              made, which wanders by megabytes from run to run, with the
//              thread count and under mpirun: a cut coarsened to fit the
//              limit must not depend on it (same inputs, same image). It
//              counts against total.
//   build      the store build plans within total (its own plan reserves
//              the reader, the batches in flight and a base for the rest;
//              octree_build.cpp), so a store depends on total alone.
//   probe      the stores' node tables stay resident; the page cache gets
//              half of what total leaves after everything then resident and
//              a reserve for the test rays' hit records (the other half
//              absorbs the pages in flight and allocator slack).
//   simplify,  run one after the other, after the probe's pages are freed;
//   render     each may use working() = total - baseline, and the cut is
//              coarsened until both estimates fit: simplify's beside the
//              node tables (still resident), counting the Draco encoder,
//              which holds about as much again as the mesh it encodes;
//              render's after the node tables are freed.
// Every stage checks its estimate before it allocates, so the resident peak
// stays near total; the estimates are measured averages (bench_render,
// bench_simplify, bench_draco_memory), not hard bounds.
#pragma once

#include <cstdint>
#include <optional>

namespace raylod {

// The least --memory-limit any command accepts (the store build's plan
// needs this much for its reader and batches; the process itself holds
// about 140 MiB before a stage starts, so real limits are far larger).
inline constexpr uint64_t kMinMemoryLimit = uint64_t(1) << 20;

// The program's own resident size at the start of a run, as the budget
// counts it: 128 to 132 MiB measured on Debian 12 (one process or a rank
// under mpirun, 1 or 2 threads, small and 2M-triangle scenes), with a margin.
inline constexpr uint64_t kProgramBytes = uint64_t(144) << 20;

struct MemoryBudget {
  uint64_t total = 0;     // bytes; 0 = no limit
  uint64_t baseline = 0;  // the program's own bytes (kProgramBytes)

  // The command line's default --memory-limit: a quarter of physical memory.
  static uint64_t default_total();
  // --memory-limit at the command line boundary: the size given, or
  // default_total() when the option is absent (nullopt). Commands call this
  // once and pass `total` down.
  static MemoryBudget resolve(std::optional<uint64_t> requested);
  // A budget of `total` bytes (0 = no limit), baseline kProgramBytes: what a
  // library stage makes of the limit it was given.
  static MemoryBudget of(uint64_t total);

  bool limited() const { return total != 0; }
  // What the stages after the build may use: total - baseline, at least 1
  // byte (nothing fits) under a limit; 0 (no limit) without one.
  uint64_t working() const {
    if (!limited()) return 0;
    return total > baseline ? total - baseline : 1;
  }
  // The probe's page cache, given what is resident once the stores are open
  // and the bytes reserved for hit records: 0 if nothing is left under a
  // limit, UINT64_MAX (every page may stay) without one.
  uint64_t page_cache(uint64_t resident, uint64_t reserve) const {
    if (!limited()) return UINT64_MAX;
    return total > resident + reserve ? (total - resident - reserve) / 2 : 0;
  }
};

}  // namespace raylod
