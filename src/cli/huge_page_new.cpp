// The raylod program's global operator new: large blocks ask the kernel for
// transparent huge pages.
//
// raylod's stages allocate large buffers (pages, the collapse's triangle
// lists, the simplified mesh, Draco's encoder tables) and touch each byte
// once or twice. Where the kernel gives huge pages only to memory that asks
// (/sys/kernel/mm/transparent_hugepage/enabled "madvise", Debian's default),
// every first touch of a 4 KiB page is a fault, and in a virtual machine a
// costly one: the 100M glass view's simplify took 519,000 faults in 13.1 s
// without the advice and 136,000 in 10.2 s with it (README, "The store").
// So a block of kHugePageAdviceMinimum or more is advised (madvise
// MADV_HUGEPAGE) over the 2 MiB pages it wholly covers. The block still
// comes from malloc and goes back to free (the deletes below), so nothing
// else changes; where the kernel says "never" or "always" the advice
// changes nothing, and RAYLOD_HUGE_PAGES=0 turns it off.
// core/system.h's ScopedSmallPages still turns huge pages off where they
// cost more than they save (Embree's BVH build).
//
// Not under AddressSanitizer (huge_page_new.h).
#include "cli/huge_page_new.h"

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <new>

#if RAYLOD_HUGE_PAGE_NEW

namespace {

using raylod::kHugePageAdviceMinimum;
using raylod::kHugePageBytes;

// RAYLOD_HUGE_PAGES=0 in the environment: no advice (to measure without).
bool advise() noexcept {
  static const bool on = [] {
    const char* v = std::getenv("RAYLOD_HUGE_PAGES");
    return !(v && v[0] == '0' && v[1] == 0);
  }();
  return on;
}

void* allocate(std::size_t bytes) noexcept {
  void* p = std::malloc(bytes ? bytes : 1);
  if (p && bytes >= kHugePageAdviceMinimum && advise()) {
    const std::uintptr_t lo = (reinterpret_cast<std::uintptr_t>(p) + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
    const std::uintptr_t hi = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~(kHugePageBytes - 1);
    if (hi > lo) {
      const int saved = errno;  // advice: its failure is harmless, and errno stays the caller's
      ::madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
      errno = saved;
    }
  }
  return p;
}

// As the standard's operator new: the new-handler until it gives up.
void* allocate_or_throw(std::size_t bytes) {
  for (;;) {
    if (void* p = allocate(bytes)) return p;
    std::new_handler handler = std::get_new_handler();
    if (!handler) throw std::bad_alloc();
    handler();
  }
}

}  // namespace

// The array and nothrow forms of the C++ library call this one (and so its
// new-handler loop). The deletes below pair with it explicitly (the
// library's would free() as well; tools such as Valgrind see the pairs).
// The aligned forms stay the library's, new and delete alike.
void* operator new(std::size_t bytes) { return allocate_or_throw(bytes); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

#endif
