// TEMPORARY placeholder until the simplify stage lands its Draco encoder and
// decoder here; every entry point reports that .drc is not supported yet.
#include "streaming/draco_io.h"

namespace raylod {
StatusOr<DracoWriteReport> write_draco(const std::filesystem::path& path, const IndexedMesh&, const DracoOptions&) {
  return Status::error(path.string() + ": Draco output is not implemented yet");
}
StatusOr<IndexedMesh> read_draco(const std::filesystem::path& path) {
  return Status::error(path.string() + ": Draco input is not implemented yet");
}
StatusOr<std::unique_ptr<MeshReader>> open_draco_reader(const std::filesystem::path& path, ReaderOptions) {
  return Status::error(path.string() + ": Draco input is not implemented yet");
}
}  // namespace raylod
