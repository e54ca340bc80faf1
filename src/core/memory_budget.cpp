// MemoryBudget::resolve (memory_budget.h).
#include "core/memory_budget.h"

#include "core/system.h"

namespace raylod {

uint64_t MemoryBudget::default_total() { return physical_memory_bytes() / 4; }

MemoryBudget MemoryBudget::resolve(std::optional<uint64_t> requested) {
  return measured(requested ? *requested : default_total());
}

MemoryBudget MemoryBudget::measured(uint64_t total) {
  MemoryBudget b;
  b.total = total;
  b.baseline = current_rss_bytes();
  return b;
}

}  // namespace raylod
