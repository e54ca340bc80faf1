// libFuzzer target: the glTF reader (describe_gltf, then the MeshReader over
// the whole default scene). GLB and JSON inputs both start from the seeds;
// external buffers resolve inside /proc/self/fd, where nothing else matches.
#include "fuzz_input.h"
#include "streaming/gltf_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  raylod::fuzz::MemFile file(data, size);
  auto summary = raylod::describe_gltf(file.path());
  if (summary) {
    for (const raylod::GltfInstance& inst : summary->instances)
      RAYLOD_FUZZ_CHECK(inst.mesh >= 0 && size_t(inst.mesh) < summary->meshes.size());
    for (const raylod::GltfMeshInfo& m : summary->meshes)
      RAYLOD_FUZZ_CHECK(m.material < int(summary->materials.size()));
  } else {
    RAYLOD_FUZZ_CHECK(!summary.status().message().empty());
  }
  raylod::fuzz::drain(raylod::open_gltf_reader(file.path(), raylod::fuzz::small_batches()));
  return 0;
}
