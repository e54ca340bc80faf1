// Draco data the readers must refuse (the .drc reader and glTF's Draco
// primitives).
#pragma once

#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>

#include <string>

namespace raylod::test {

struct DracoBytes {
  std::string bytes;
  int position_id = -1;
};

// A one-triangle mesh (sequential encoding) whose positions, or whose
// normals, are stored as bools: Draco converts a stored bool by reading each
// byte as a C++ bool, undefined for bytes other than 0 and 1. The encoded
// bytes, and the position attribute's unique id (what a glTF primitive
// names).
inline DracoBytes draco_mesh_with_bools(bool bool_normals) {
  draco::TriangleSoupMeshBuilder builder;
  builder.Start(1);
  const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3,
                                       bool_normals ? draco::DT_FLOAT32 : draco::DT_BOOL);
  const int nrm = builder.AddAttribute(draco::GeometryAttribute::NORMAL, 3,
                                       bool_normals ? draco::DT_BOOL : draco::DT_FLOAT32);
  const float p[3][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, n[3] = {0, 0, 1};
  const bool bp[3][3] = {{false, false, false}, {true, false, false}, {false, true, false}}, bn[3] = {false, false, true};
  if (bool_normals) {
    builder.SetAttributeValuesForFace(pos, draco::FaceIndex(0), p[0], p[1], p[2]);
    builder.SetAttributeValuesForFace(nrm, draco::FaceIndex(0), bn, bn, bn);
  } else {
    builder.SetAttributeValuesForFace(pos, draco::FaceIndex(0), bp[0], bp[1], bp[2]);
    builder.SetAttributeValuesForFace(nrm, draco::FaceIndex(0), n, n, n);
  }
  std::unique_ptr<draco::Mesh> mesh = builder.Finalize();
  if (!mesh) return {};
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer buffer;
  if (!encoder.EncodeMeshToBuffer(*mesh, &buffer).ok()) return {};
  return {std::string(buffer.data(), buffer.size()), int(mesh->attribute(pos)->unique_id())};
}

// `size` bytes: a Draco 2.2 edgebreaker mesh header (no metadata) claiming
// `vertices` and `faces`, then the connectivity's other counts (one
// attribute data, as many symbols as faces, no split symbols), then filler.
// Draco sizes its tables from such counts before reading anything else.
inline std::string draco_header_claiming(uint64_t vertices, uint64_t faces, size_t size) {
  auto varint = [](uint64_t v) {
    std::string b;
    do {
      b += char((v & 0x7f) | (v >= 0x80 ? 0x80 : 0));
      v >>= 7;
    } while (v);
    return b;
  };
  std::string bytes = std::string("DRACO\x02\x02\x01\x01\x00\x00", 11) + '\0' + varint(vertices) + varint(faces) +
                      '\x01' + varint(faces) + varint(0);
  if (bytes.size() < size) bytes += std::string(size - bytes.size(), '\x33');
  return bytes;
}

}  // namespace raylod::test
