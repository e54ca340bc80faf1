// libFuzzer target: the OBJ reader (open_obj_reader, then every batch).
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  raylod::fuzz::MemFile file(data, size);
  raylod::fuzz::drain(raylod::open_obj_reader(file.path(), raylod::fuzz::small_batches()));
  return 0;
}
