// The programs' operator new (src/cli/huge_page_new.cpp, linked into this
// test as into raylod): a large block is advised for transparent huge pages
// over the 2 MiB pages it wholly covers; the kernel shows the advice as the
// "hg" flag of the mapping (/proc/self/smaps). RAYLOD_HUGE_PAGES=0 turns
// the advice off, and this test with it.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include "cli/huge_page_new.h"

namespace raylod {
namespace {

// The VmFlags of the mapping that holds `address` ("" if none is found).
std::string mapping_flags(std::uintptr_t address) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    unsigned long long lo = 0, hi = 0;
    char dash = 0;
    std::istringstream header(line);
    if (header >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = address >= lo && address < hi;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line + " ";
  }
  return "";
}

TEST(HugePageNew, LargeBlocksAskForHugePages) {
#if !RAYLOD_HUGE_PAGE_NEW
  GTEST_SKIP() << "this build keeps the library's operator new (AddressSanitizer's, or not Linux)";
#else
  if (const char* v = std::getenv("RAYLOD_HUGE_PAGES"); v && std::string(v) == "0")
    GTEST_SKIP() << "RAYLOD_HUGE_PAGES=0 turns the advice off";
  if (!std::filesystem::exists("/sys/kernel/mm/transparent_hugepage/enabled"))
    GTEST_SKIP() << "this kernel has no transparent huge pages";
  constexpr std::size_t kHuge = kHugePageBytes;
  const std::size_t bytes = 8 * kHuge;
  std::unique_ptr<char[]> block(new char[bytes]);
  const std::uintptr_t start = reinterpret_cast<std::uintptr_t>(block.get());
  const std::uintptr_t first_whole = (start + kHuge - 1) & ~(kHuge - 1);
  const std::string flags = mapping_flags(first_whole);
  ASSERT_FALSE(flags.empty()) << "no mapping holds the block";
  EXPECT_NE(flags.find(" hg "), std::string::npos) << flags;
  // The last whole huge page of the block is advised too.
  const std::uintptr_t last_whole = ((start + bytes) & ~(kHuge - 1)) - kHuge;
  EXPECT_NE(mapping_flags(last_whole).find(" hg "), std::string::npos) << mapping_flags(last_whole);
#endif
}

}  // namespace
}  // namespace raylod
