// libFuzzer target: reading a cut file. The first input byte chooses the
// mode, the rest is the file:
//   even: the bytes as they are;
//   odd:  the payload size and FNV-1a checksum in the 32-byte header are
//         set to match the bytes after it, so mutations reach the payload checks.
#include <cstring>
#include <string>

#include "core/system.h"
#include "fuzz_input.h"
#include "streaming/cut_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace raylod;
  if (size == 0) return 0;
  std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if ((data[0] & 1) && bytes.size() >= 32) {
    const uint64_t payload = bytes.size() - 32;
    const uint64_t sum = fnv1a64(bytes.data() + 32, payload);
    std::memcpy(bytes.data() + 16, &payload, 8);
    std::memcpy(bytes.data() + 24, &sum, 8);
  }
  fuzz::MemFile file(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
  auto cut = read_cut(file.path());
  if (!cut) {
    RAYLOD_FUZZ_CHECK(!cut.status().message().empty());
    return 0;
  }
  // What read_cut promises: an antichain of valid cells, sorted by key.
  for (size_t i = 0; i < cut->cells.size(); ++i) {
    const CellKey k = cut->cells[i].key;
    RAYLOD_FUZZ_CHECK(k.level <= 21);
    if (i > 0) RAYLOD_FUZZ_CHECK(cut->cells[i - 1].key < k);
  }
  return 0;
}
