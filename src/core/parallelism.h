// The parallelism a stage runs with. The process sets it once: `raylod`'s
// main() creates the one tbb::global_control from --threads (benchmarks do
// the same); library stages create neither a global_control nor a task arena
// of their own, so a caller's tbb::task_arena also bounds them (tests run a
// stage in task_arena(1) against the default arena to check determinism).
#pragma once

namespace raylod {

// What a parallel algorithm started here may use: the smaller of the
// process-wide limit (tbb::global_control::max_allowed_parallelism) and the
// concurrency of the task arena the caller runs in.
int ambient_parallelism();

}  // namespace raylod
