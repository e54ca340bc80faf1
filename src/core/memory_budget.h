// One memory budget per command: --memory-limit resolved once, and the share
// each stage of `raylod run` (and probe, report) may use.
//
//   total      --memory-limit; 0 means a quarter of physical memory.
//   baseline   what the process holds before any stage starts (code, the
//              libraries' data, the runtime: about 140 MiB here), measured
//              when the budget is resolved; it counts against total.
//   build      the store build plans within total (its own plan reserves
//              the reader, the batches in flight and a base for the rest;
//              octree_build.cpp), so a store depends on total alone.
//   probe      the stores' node tables stay resident; the page cache gets
//              half of what total leaves after everything then resident and
//              a reserve for the test rays' hit records (the other half
//              absorbs the pages in flight and allocator slack).
//   simplify,  run one after the other, after the probe's pages are freed;
//   render     each may use working() = total - baseline, and the cut is
//              coarsened until both estimates fit.
// Every stage checks its estimate before it allocates, so the resident peak
// stays near total; the estimates are measured averages (bench_render,
// bench_simplify), not hard bounds.
#pragma once

#include <cstdint>

namespace raylod {

struct MemoryBudget {
  uint64_t total = 0;
  uint64_t baseline = 0;

  // From --memory-limit (0 = a quarter of physical memory); baseline = the
  // resident size now.
  static MemoryBudget resolve(uint64_t requested);

  // What the stages after the build may use: total - baseline (0 if none).
  uint64_t working() const { return total > baseline ? total - baseline : 0; }
  // The probe's page cache, given what is resident once the stores are open
  // and the bytes reserved for hit records; 0 if nothing is left.
  uint64_t page_cache(uint64_t resident, uint64_t reserve) const {
    return total > resident + reserve ? (total - resident - reserve) / 2 : 0;
  }
};

}  // namespace raylod
