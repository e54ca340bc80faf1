// MemoryBudget::resolve (memory_budget.h).
#include "core/memory_budget.h"

#include "core/system.h"

namespace raylod {

uint64_t MemoryBudget::default_total() { return physical_memory_bytes() / 4; }

MemoryBudget MemoryBudget::resolve(std::optional<uint64_t> requested) {
  return of(requested ? *requested : default_total());
}

MemoryBudget MemoryBudget::of(uint64_t total) {
  MemoryBudget b;
  b.total = total;
  b.baseline = kProgramBytes;
  return b;
}

}  // namespace raylod
