// MemoryBudget::resolve (memory_budget.h).
#include "core/memory_budget.h"

#include "core/system.h"

namespace raylod {

MemoryBudget MemoryBudget::resolve(uint64_t requested) {
  MemoryBudget b;
  b.total = requested ? requested : physical_memory_bytes() / 4;
  b.baseline = current_rss_bytes();
  return b;
}

}  // namespace raylod
