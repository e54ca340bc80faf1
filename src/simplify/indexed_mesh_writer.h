// Writers for the simplified (indexed) mesh in formats other tools view:
// binary little-endian PLY (through streaming/indexed_ply_writer.h) and OBJ
// (v, vn, f a//a). Written atomically: a failure leaves nothing under the name.
#pragma once

#include <filesystem>

#include "core/status.h"
#include "streaming/draco_io.h"

namespace raylod {

Status write_indexed_ply(const std::filesystem::path& path, const IndexedMesh& mesh);
Status write_indexed_obj(const std::filesystem::path& path, const IndexedMesh& mesh);
// Bytes write_indexed_ply would write (header + vertices + faces).
uint64_t indexed_ply_bytes(const IndexedMesh& mesh);

}  // namespace raylod
