#include "streaming/indexed_ply_writer.h"

#include <bit>
#include <cerrno>
#include <cstring>
#include <sstream>

namespace raylod {
namespace {

// Stores a 32-bit value little endian whatever the host.
inline void put32(unsigned char* dst, uint32_t v) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(dst, &v, 4);
  } else {
    dst[0] = uint8_t(v);
    dst[1] = uint8_t(v >> 8);
    dst[2] = uint8_t(v >> 16);
    dst[3] = uint8_t(v >> 24);
  }
}
inline void put_float(unsigned char* dst, float f) { put32(dst, std::bit_cast<uint32_t>(f)); }

inline void put_double(unsigned char* dst, double d) {
  const uint64_t v = std::bit_cast<uint64_t>(d);
  put32(dst, uint32_t(v));
  put32(dst + 4, uint32_t(v >> 32));
}

bool double_positions(const IndexedPlyLayout& l) { return l.origin != Vec3d(0); }
size_t position_bytes(const IndexedPlyLayout& l) { return double_positions(l) ? 24 : 12; }
size_t vertex_record_bytes(const IndexedPlyLayout& l) { return position_bytes(l) + (l.normals ? 12 : 0); }
constexpr size_t kFaceRecordBytes = 1 + 3 * 4;

}  // namespace

std::string indexed_ply_header(const IndexedPlyLayout& l) {
  std::ostringstream h;
  h << "ply\nformat binary_little_endian 1.0\n";
  for (const auto& c : l.comments) h << "comment " << c << "\n";
  h << "element vertex " << l.vertex_count << "\n"
    << (double_positions(l) ? "property double x\nproperty double y\nproperty double z\n"
                            : "property float x\nproperty float y\nproperty float z\n");
  if (l.normals) h << "property float nx\nproperty float ny\nproperty float nz\n";
  h << "element face " << l.face_count << "\n"
    << "property list uchar int vertex_indices\nend_header\n";
  return h.str();
}

uint64_t indexed_ply_file_bytes(const IndexedPlyLayout& l) {
  return indexed_ply_header(l).size() + l.vertex_count * vertex_record_bytes(l) + l.face_count * kFaceRecordBytes;
}

IndexedPlyWriter::IndexedPlyWriter(const std::filesystem::path& path, IndexedPlyLayout layout)
    : layout_(std::move(layout)), out_(path) {}

IndexedPlyWriter::~IndexedPlyWriter() {
  if (file_) std::fclose(file_);
}

StatusOr<std::unique_ptr<IndexedPlyWriter>> IndexedPlyWriter::create(const std::filesystem::path& path,
                                                                     IndexedPlyLayout layout) {
  if (layout.vertex_count >= (uint64_t(1) << 31))
    return Status::error(path.string() + ": " + std::to_string(layout.vertex_count) +
                         " vertices do not fit the PLY int vertex indices (limit 2^31 - 1)");
  for (const auto& c : layout.comments)
    if (c.find('\n') != std::string::npos || c.find('\r') != std::string::npos)
      return Status::error(path.string() + ": PLY comment must be one line");
  std::unique_ptr<IndexedPlyWriter> w(new IndexedPlyWriter(path, std::move(layout)));
  w->file_ = std::fopen(w->out_.temp_path().c_str(), "wb");
  if (!w->file_)
    return Status::error(path.string() + ": cannot create output: " + std::strerror(errno));
  std::setvbuf(w->file_, nullptr, _IONBF, 0);  // we stage ourselves
  w->staging_.reserve(kStagingBytes);
  const std::string header = indexed_ply_header(w->layout_);
  RAYLOD_RETURN_IF_ERROR(w->write_bytes(header.data(), header.size()));
  return w;
}

Status IndexedPlyWriter::fail(const std::string& what) {
  failed_ = true;
  return Status::error(out_.destination().string() + ": " + what);
}

Status IndexedPlyWriter::flush_staging() {
  if (staging_.empty()) return Status::ok();
  const size_t n = staging_.size();
  if (std::fwrite(staging_.data(), 1, n, file_) != n)
    return fail(std::string("write failed: ") + std::strerror(errno));
  staging_.clear();
  return Status::ok();
}

Status IndexedPlyWriter::write_bytes(const void* data, size_t n) {
  const auto* p = static_cast<const unsigned char*>(data);
  if (staging_.size() + n > kStagingBytes) RAYLOD_RETURN_IF_ERROR(flush_staging());
  staging_.insert(staging_.end(), p, p + n);
  bytes_ += n;
  return Status::ok();
}

Status IndexedPlyWriter::append_vertices(std::span<const Vec3> positions, std::span<const Vec3> normals) {
  if (failed_ || finished_) return fail("append_vertices after an error or finish()");
  if (triangles_ > 0) return fail("vertices appended after faces");
  if (layout_.normals && normals.size() != positions.size())
    return fail("vertex chunk has " + std::to_string(positions.size()) + " positions but " +
                std::to_string(normals.size()) + " normals");
  if (vertices_ + positions.size() > layout_.vertex_count)
    return fail("more vertices than the " + std::to_string(layout_.vertex_count) + " declared");
  const size_t rec = vertex_record_bytes(layout_), pb = position_bytes(layout_);
  const bool wide = double_positions(layout_);
  const size_t per_batch = kStagingBytes / rec;
  for (size_t first = 0; first < positions.size(); first += per_batch) {
    const size_t n = std::min(per_batch, positions.size() - first);
    if (staging_.size() + n * rec > kStagingBytes) RAYLOD_RETURN_IF_ERROR(flush_staging());
    const size_t at = staging_.size();
    staging_.resize(at + n * rec);
    unsigned char* dst = staging_.data() + at;
    for (size_t i = first; i < first + n; ++i, dst += rec) {
      if (wide) {
        const Vec3d p = layout_.origin + Vec3d(positions[i]);
        put_double(dst + 0, p.x);
        put_double(dst + 8, p.y);
        put_double(dst + 16, p.z);
      } else {
        put_float(dst + 0, positions[i].x);
        put_float(dst + 4, positions[i].y);
        put_float(dst + 8, positions[i].z);
      }
      if (layout_.normals) {
        put_float(dst + pb + 0, normals[i].x);
        put_float(dst + pb + 4, normals[i].y);
        put_float(dst + pb + 8, normals[i].z);
      }
    }
    bytes_ += n * rec;
  }
  vertices_ += positions.size();
  return Status::ok();
}

Status IndexedPlyWriter::append_triangles(std::span<const uint32_t> indices) {
  if (failed_ || finished_) return fail("append_triangles after an error or finish()");
  if (indices.size() % 3 != 0) return fail("triangle index count is not a multiple of 3");
  if (vertices_ != layout_.vertex_count)
    return fail("faces appended after " + std::to_string(vertices_) + " of " +
                std::to_string(layout_.vertex_count) + " vertices");
  const size_t n_tri = indices.size() / 3;
  if (triangles_ + n_tri > layout_.face_count)
    return fail("more faces than the " + std::to_string(layout_.face_count) + " declared");
  const size_t per_batch = kStagingBytes / kFaceRecordBytes;
  for (size_t first = 0; first < n_tri; first += per_batch) {
    const size_t n = std::min(per_batch, n_tri - first);
    if (staging_.size() + n * kFaceRecordBytes > kStagingBytes) RAYLOD_RETURN_IF_ERROR(flush_staging());
    const size_t at = staging_.size();
    staging_.resize(at + n * kFaceRecordBytes);
    unsigned char* dst = staging_.data() + at;
    for (size_t t = first; t < first + n; ++t, dst += kFaceRecordBytes) {
      dst[0] = 3;
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = indices[3 * t + k];
        if (v >= layout_.vertex_count)
          return fail("face " + std::to_string(triangles_ + t) + " has vertex index " + std::to_string(v) +
                      " >= vertex count " + std::to_string(layout_.vertex_count));
        put32(dst + 1 + 4 * k, v);
      }
    }
    bytes_ += n * kFaceRecordBytes;
  }
  triangles_ += n_tri;
  return Status::ok();
}

Status IndexedPlyWriter::finish() {
  if (failed_ || finished_) return fail("finish() after an error or a previous finish()");
  if (vertices_ != layout_.vertex_count || triangles_ != layout_.face_count)
    return fail("wrote " + std::to_string(vertices_) + " vertices and " + std::to_string(triangles_) +
                " faces, header declares " + std::to_string(layout_.vertex_count) + " and " +
                std::to_string(layout_.face_count));
  RAYLOD_RETURN_IF_ERROR(flush_staging());
  const int rc = std::fclose(file_);
  file_ = nullptr;
  if (rc != 0) return fail(std::string("close failed (disk full?): ") + std::strerror(errno));
  RAYLOD_RETURN_IF_ERROR(out_.commit());
  finished_ = true;
  return Status::ok();
}

}  // namespace raylod
