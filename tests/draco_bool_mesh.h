// A one-triangle Draco mesh (sequential encoding) whose positions, or whose
// normals, are stored as bools: the readers must refuse it, since Draco
// converts a stored bool by reading each byte as a C++ bool (undefined for
// bytes other than 0 and 1). The encoded bytes, and the position
// attribute's unique id (what a glTF primitive names).
#pragma once

#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>

#include <string>

namespace raylod::test {

struct DracoBytes {
  std::string bytes;
  int position_id = -1;
};

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

}  // namespace raylod::test
