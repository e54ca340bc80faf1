// ambient_parallelism (parallelism.h).
#include "core/parallelism.h"

#include <algorithm>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

namespace raylod {

int ambient_parallelism() {
  const size_t global = tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  const int arena = tbb::this_task_arena::max_concurrency();
  return std::max(1, std::min(int(std::min<size_t>(global, 1u << 20)), arena));
}

}  // namespace raylod
