// Whether this build replaces the global operator new with huge_page_new.cpp's
// (RAYLOD_HUGE_PAGE_NEW 1: Linux with MADV_HUGEPAGE, not under
// AddressSanitizer, whose own operator new must pair with its operator
// delete), and the sizes it works in. Shared with its test.
#pragma once

#include <sys/mman.h>

#include <cstddef>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RAYLOD_NEW_UNDER_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define RAYLOD_NEW_UNDER_ASAN 1
#endif

#if defined(__linux__) && defined(MADV_HUGEPAGE) && !defined(RAYLOD_NEW_UNDER_ASAN)
#define RAYLOD_HUGE_PAGE_NEW 1
#else
#define RAYLOD_HUGE_PAGE_NEW 0
#endif

namespace raylod {

inline constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;
// Blocks this large are advised: at least one whole huge page inside,
// wherever malloc places the block.
inline constexpr std::size_t kHugePageAdviceMinimum = 2 * kHugePageBytes;

}  // namespace raylod
