// libFuzzer target: the Draco reader (read_draco, then the MeshReader over it).
#include "fuzz_input.h"
#include "streaming/draco_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  raylod::fuzz::MemFile file(data, size);
  auto mesh = raylod::read_draco(file.path());
  if (mesh) {
    const size_t n = mesh->positions.size();
    RAYLOD_FUZZ_CHECK(mesh->normals.empty() || mesh->normals.size() == n);
    RAYLOD_FUZZ_CHECK(mesh->indices.size() % 3 == 0);
    for (uint32_t i : mesh->indices) RAYLOD_FUZZ_CHECK(i < n);
    for (const raylod::Vec3& p : mesh->positions) RAYLOD_FUZZ_CHECK(raylod::is_finite(p));
  } else {
    RAYLOD_FUZZ_CHECK(!mesh.status().message().empty());
  }
  raylod::fuzz::drain(raylod::open_draco_reader(file.path(), raylod::fuzz::small_batches()));
  return 0;
}
