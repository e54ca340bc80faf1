// Size options (--memory-limit, --cache-limit; parse_size): positive whole
// numbers of bytes with an optional K, M, G or T suffix (powers of 1024).
// Fractions, zero and sizes past 2^64 - 1 bytes are errors naming the option
// and the value, never a silent fallback to the default. The end-to-end case
// runs the raylod executable (this folder's tests may).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/system.h"
#include "run_command.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

TEST(SizeOption, WholeNumbersWithPowerOf1024Units) {
  const std::pair<const char*, uint64_t> good[] = {
      {"1", 1},          {"1000000", 1000000},   {"512K", 512ull << 10},    {"512m", 512ull << 20},
      {"2G", 2ull << 30}, {"1GiB", 1ull << 30},  {"3tb", 3ull << 40},       {"7B", 7},
      {"16777215T", 16777215ull << 40},          {"18446744073709551615", UINT64_MAX}};
  for (const auto& [text, bytes] : good) {
    auto v = parse_size(text);
    ASSERT_TRUE(v.is_ok()) << text << ": " << v.status().message();
    EXPECT_EQ(*v, bytes) << text;
  }
}

TEST(SizeOption, RejectsFractionsZeroOverflowAndJunk) {
  const std::pair<const char*, const char*> bad[] = {
      {"0", "'0': the size must be at least 1 byte"},
      {"0G", "'0G': the size must be at least 1 byte"},
      {"0.5", "'0.5' is not a whole number of bytes"},
      {"1.5G", "'1.5G' is not a whole number of bytes (write 1536M for 1.5G)"},
      {"1.5M", "'1.5M' is not a whole number of bytes (write 1536K for 1.5M)"},
      {"0.3g", "(write about 307M for 0.3g)"},
      {"2,5K", "(write 2560 for 2,5K)"},
      {"99999999T", "'99999999T' is too large"},
      {"16777216T", "'16777216T' is too large"},
      {"18446744073709551616", "'18446744073709551616' is too large"},
      {"-1G", "'-1G' is not a size"},
      {"+1G", "'+1G' is not a size"},
      {" 1G", "' 1G' is not a size"},
      {"", "'' is not a size"},
      {"G", "'G' is not a size"},
      {"1e9", "unknown size unit 'e9'"},
      {"1P", "unknown size unit 'P'"},
      {"0x10", "unknown size unit 'x10'"}};
  for (const auto& [text, expected] : bad) {
    auto v = parse_size(text);
    ASSERT_FALSE(v.is_ok()) << text << " parsed as " << *v;
    EXPECT_NE(v.status().message().find(expected), std::string::npos) << v.status().message();
  }
}

int run(const std::string& args, std::string& out) { return test::run_raylod(args, out); }

TEST(SizeOption, BadMemoryLimitFailsTheCommandAndWritesNothing) {
  const fs::path dir = test::scratch_dir("size-option");
  const fs::path mesh = dir / "tri.obj";
  std::ofstream(mesh) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const fs::path store = dir / "tri.raylod";
  for (const char* value : {"0", "0.5", "99999999T", "1023K"}) {
    std::string out;
    EXPECT_EQ(run("build -q " + mesh.string() + " -o " + store.string() + " --memory-limit " + value, out), 1) << out;
    EXPECT_NE(out.find(std::string("raylod build: error: --memory-limit: '") + value + "'"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(store)) << value;
  }
  std::string out;  // and a good value still builds
  EXPECT_EQ(run("build -q " + mesh.string() + " -o " + store.string() + " --memory-limit 64M", out), 0) << out;
  EXPECT_TRUE(fs::exists(store)) << out;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace raylod
