// open_mesh: dispatch by extension to the format readers, and the full-pass
// summary behind `raylod info`.
#include "streaming/mesh_reader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cinttypes>
#include <cstdio>
#include <mutex>
#include <set>
#include <string>

#include "core/system.h"
#include "streaming/draco_io.h"
#include "streaming/gltf_io.h"

namespace raylod {

const char* to_string(MeshFormat f) {
  switch (f) {
    case MeshFormat::Ply: return "PLY";
    case MeshFormat::Stl: return "STL";
    case MeshFormat::Obj: return "OBJ";
    case MeshFormat::Draco: return "Draco";
    case MeshFormat::Gltf: return "glTF";
  }
  return "unknown";
}

Vec3d local_origin_for(const Vec3d& p) {
  if (!is_finite(p)) return Vec3d(0);
  if (!(std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)}) >= kLocalOriginThreshold)) return Vec3d(0);
  return Vec3d(std::round(p.x), std::round(p.y), std::round(p.z));
}

void MeshReader::warn_repaired_normals() const {
  if (repaired_normals_ == 0) return;
  static std::mutex mutex;
  static std::set<std::string> warned;
  std::error_code ec;
  std::filesystem::path key = std::filesystem::weakly_canonical(path_, ec);
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (!warned.insert((ec ? path_ : key).string()).second) return;
  }
  std::fprintf(stderr,
               "raylod: warning: %s: %" PRIu64 " triangle corner%s had a zero-length normal; "
               "each was given its triangle's face normal\n",
               path_.string().c_str(), repaired_normals_, repaired_normals_ == 1 ? "" : "s");
}

StatusOr<MeshFormat> mesh_format_from_extension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".ply") return MeshFormat::Ply;
  if (ext == ".stl") return MeshFormat::Stl;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".drc") return MeshFormat::Draco;
  if (ext == ".gltf" || ext == ".glb") return MeshFormat::Gltf;
  return Status::error(path.string() + ": unknown mesh format '" + ext +
                       "' (expected .ply, .stl, .obj, .drc, .gltf or .glb)");
}

MeshRef parse_mesh_ref(const std::filesystem::path& path) {
  const std::string s = path.string();
  const size_t hash = s.rfind("#meshes[");
  if (hash == std::string::npos || s.size() < hash + 10 || s.back() != ']') return MeshRef{path, -1};
  const std::string digits = s.substr(hash + 8, s.size() - hash - 9);
  if (digits.empty() || digits.size() > 9 || (digits.size() > 1 && digits[0] == '0')) return MeshRef{path, -1};
  for (char c : digits)
    if (c < '0' || c > '9') return MeshRef{path, -1};
  const std::filesystem::path file = s.substr(0, hash);
  auto format = mesh_format_from_extension(file);
  if (!format || *format != MeshFormat::Gltf) return MeshRef{path, -1};
  return MeshRef{file, std::stoi(digits)};
}

std::filesystem::path gltf_mesh_path(const std::filesystem::path& file, int mesh) {
  return std::filesystem::path(file.string() + "#meshes[" + std::to_string(mesh) + "]");
}

StatusOr<std::unique_ptr<MeshReader>> open_mesh(const std::filesystem::path& path, ReaderOptions options) {
  // What the path is comes first: a FIFO or a device must fail at once, and
  // saying "unknown mesh format ''" about /dev/zero would hide the real problem.
  const MeshRef ref = parse_mesh_ref(path);
  RAYLOD_RETURN_IF_ERROR(check_regular_file(ref.file));
  RAYLOD_ASSIGN_OR_RETURN(MeshFormat format, mesh_format_from_extension(ref.file));
  switch (format) {
    case MeshFormat::Ply: return open_ply_reader(path, options);
    case MeshFormat::Stl: return open_stl_reader(path, options);
    case MeshFormat::Obj: return open_obj_reader(path, options);
    case MeshFormat::Draco: return open_draco_reader(path, options);
    case MeshFormat::Gltf: return open_gltf_reader(path, options);
  }
  return Status::error(path.string() + ": unknown mesh format");
}

StatusOr<MeshSummary> summarize_mesh(const std::filesystem::path& path) {
  RAYLOD_ASSIGN_OR_RETURN(std::unique_ptr<MeshReader> reader, open_mesh(path));
  MeshSummary s;
  s.header = reader->header();
  TriangleBatch batch;
  while (true) {
    RAYLOD_ASSIGN_OR_RETURN(bool more, reader->next(batch));
    if (!more) break;
    s.triangle_count += batch.size();
    // Float bounds per batch, then one double expand: exact, since every
    // coordinate (relative to the local origin) is a float.
    Vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (const Vec3& p : batch.positions) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    s.bounds.expand(lo);
    s.bounds.expand(hi);
  }
  // In the file's coordinates.
  if (!s.bounds.empty()) s.bounds = Bbox{s.header.origin + s.bounds.lo, s.header.origin + s.bounds.hi};
  return s;
}

}  // namespace raylod
