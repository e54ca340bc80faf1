// libFuzzer target: the STL reader (open_stl_reader, then every batch).
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  raylod::fuzz::MemFile file(data, size);
  raylod::fuzz::drain(raylod::open_stl_reader(file.path(), raylod::fuzz::small_batches()));
  return 0;
}
