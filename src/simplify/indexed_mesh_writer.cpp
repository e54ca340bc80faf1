#include "simplify/indexed_mesh_writer.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "core/system.h"
#include "streaming/indexed_ply_writer.h"

namespace raylod {
namespace {

IndexedPlyLayout layout_of(const IndexedMesh& mesh) {
  IndexedPlyLayout layout;
  layout.vertex_count = mesh.positions.size();
  layout.face_count = mesh.triangle_count();
  layout.normals = !mesh.normals.empty();
  layout.origin = mesh.origin;
  layout.comments = {"raylod simplified mesh"};
  return layout;
}

Status finish(std::ofstream& f, AtomicOutput& out) {
  const std::string dest = out.destination().string();
  errno = 0;
  f.close();
  if (!f) return Status::write_failed(dest, dest + ": write failed: " + std::strerror(errno), errno);
  return out.commit();
}

}  // namespace

uint64_t indexed_ply_bytes(const IndexedMesh& mesh) { return indexed_ply_file_bytes(layout_of(mesh)); }

Status write_indexed_ply(const std::filesystem::path& path, const IndexedMesh& mesh) {
  RAYLOD_ASSIGN_OR_RETURN(auto writer, IndexedPlyWriter::create(path, layout_of(mesh)));
  RAYLOD_RETURN_IF_ERROR(writer->append_vertices(mesh.positions, mesh.normals));
  RAYLOD_RETURN_IF_ERROR(writer->append_triangles(mesh.indices));
  return writer->finish();
}

Status write_indexed_obj(const std::filesystem::path& path, const IndexedMesh& mesh) {
  AtomicOutput out(path);
  errno = 0;
  std::ofstream f(out.temp_path());
  if (!f) return Status::write_failed(path.string(), path.string() + ": cannot open for writing: " + std::strerror(errno), errno);
  f << "# raylod simplified mesh: " << mesh.positions.size() << " vertices, " << mesh.triangle_count() << " triangles\n";
  char line[160];
  // Far from zero (mesh.origin), enough digits for the detail a float
  // relative to the origin keeps.
  const bool far = mesh.origin != Vec3d(0);
  for (const Vec3& q : mesh.positions) {
    const Vec3d p = mesh.origin + Vec3d(q);
    std::snprintf(line, sizeof line, far ? "v %.17g %.17g %.17g\n" : "v %.9g %.9g %.9g\n", p.x, p.y, p.z);
    f << line;
  }
  const bool normals = !mesh.normals.empty();
  for (const Vec3& n : mesh.normals) {
    std::snprintf(line, sizeof line, "vn %.9g %.9g %.9g\n", n.x, n.y, n.z);
    f << line;
  }
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const uint32_t* v = &mesh.indices[3 * t];
    if (normals)
      std::snprintf(line, sizeof line, "f %u//%u %u//%u %u//%u\n", v[0] + 1, v[0] + 1, v[1] + 1, v[1] + 1, v[2] + 1,
                    v[2] + 1);
    else
      std::snprintf(line, sizeof line, "f %u %u %u\n", v[0] + 1, v[1] + 1, v[2] + 1);
    f << line;
  }
  return finish(f, out);
}

}  // namespace raylod
