// libFuzzer target: the PLY reader (open_ply_reader, then every batch).
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  raylod::fuzz::MemFile file(data, size);
  raylod::fuzz::drain(raylod::open_ply_reader(file.path(), raylod::fuzz::small_batches()));
  return 0;
}
