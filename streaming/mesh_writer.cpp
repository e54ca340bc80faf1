// Streaming triangle-soup writers: binary little-endian PLY and binary STL.
// Every triangle is written as three vertices of its own (no deduplication);
// readers and the octree builder do not need shared vertices. The PLY header
// is written last, into a fixed-size slot padded by a comment line, because
// the counts are only known at finish(); the face list of a soup is implicit
// (3t, 3t+1, 3t+2) and is generated then, so nothing is kept in memory.
#include "streaming/mesh_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <bit>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "core/system.h"

namespace raylod {
namespace {

static_assert(std::endian::native == std::endian::little, "the writers assume a little-endian host");

// A file descriptor with a 1 MiB write buffer; errors name the destination.
class OutputFile {
 public:
  explicit OutputFile(std::string name) : name_(std::move(name)) { buffer_.reserve(1 << 20); }
  ~OutputFile() { if (fd_ >= 0) ::close(fd_); }
  Status open(const std::filesystem::path& temp) {
    fd_ = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) return Status::error(name_ + ": cannot create: " + std::strerror(errno));
    return Status::ok();
  }
  Status write(const void* data, size_t n) {
    if (buffer_.size() + n > buffer_.capacity()) RAYLOD_RETURN_IF_ERROR(flush());
    const auto* b = static_cast<const uint8_t*>(data);
    buffer_.insert(buffer_.end(), b, b + n);
    return Status::ok();
  }
  Status flush() {
    const uint8_t* p = buffer_.data();
    size_t left = buffer_.size();
    while (left > 0) {
      ssize_t n = ::write(fd_, p, left);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) return Status::error(name_ + ": write failed: " + std::strerror(errno));
      p += n;
      left -= size_t(n);
    }
    buffer_.clear();
    return Status::ok();
  }
  Status write_at(uint64_t offset, const void* data, size_t n) {
    RAYLOD_RETURN_IF_ERROR(flush());
    if (::pwrite(fd_, data, n, off_t(offset)) != ssize_t(n))
      return Status::error(name_ + ": write failed: " + std::strerror(errno));
    return Status::ok();
  }
  Status close() {
    RAYLOD_RETURN_IF_ERROR(flush());
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) return Status::error(name_ + ": close failed: " + std::strerror(errno));
    return Status::ok();
  }

 private:
  std::string name_;
  int fd_ = -1;
  std::vector<uint8_t> buffer_;
};

Status check_batch(const std::string& name, const TriangleBatch& batch) {
  if (batch.positions.size() % 3 != 0)
    return Status::error(name + ": batch has " + std::to_string(batch.positions.size()) +
                         " positions, not a multiple of 3");
  if (!batch.normals.empty() && batch.normals.size() != batch.positions.size())
    return Status::error(name + ": batch has " + std::to_string(batch.normals.size()) + " normals for " +
                         std::to_string(batch.positions.size()) + " positions");
  return Status::ok();
}

// The checks both writers make when finishing: once only, and never an empty mesh.
Status start_finish(const std::string& name, bool& finished, uint64_t triangles) {
  if (finished) return Status::error(name + ": finish called twice");
  finished = true;
  if (triangles == 0) return Status::error(name + ": no triangles to write (an empty mesh is not a valid file)");
  return Status::ok();
}

class PlyWriter final : public MeshWriter {
 public:
  static constexpr size_t kHeaderSlot = 512;
  PlyWriter(const std::filesystem::path& path, WriterOptions options)
      : out_(path), file_(path.string()), options_(options) {}
  Status start() {
    RAYLOD_RETURN_IF_ERROR(file_.open(out_.temp_path()));
    const std::string placeholder(kHeaderSlot, ' ');
    return file_.write(placeholder.data(), placeholder.size());
  }
  Status write(const TriangleBatch& batch) override {
    const std::string name = out_.destination().string();
    if (finished_) return Status::error(name + ": write after finish");
    RAYLOD_RETURN_IF_ERROR(check_batch(name, batch));
    if (batch.positions.empty()) return Status::ok();
    if (!layout_fixed_) {
      normals_ = options_.normals && !batch.normals.empty();
      layout_fixed_ = true;
    }
    if (normals_ && batch.normals.empty())
      return Status::error(name + ": a batch without normals follows batches with normals");
    if ((triangles_ + batch.size()) * 3 > uint64_t(std::numeric_limits<int32_t>::max()))
      return Status::error(name + ": too many triangles for int vertex indices in PLY");
    for (size_t i = 0; i < batch.positions.size(); ++i) {
      float rec[6];
      std::memcpy(rec, &batch.positions[i].x, 12);
      if (normals_) std::memcpy(rec + 3, &batch.normals[i].x, 12);
      RAYLOD_RETURN_IF_ERROR(file_.write(rec, normals_ ? 24 : 12));
    }
    triangles_ += batch.size();
    return Status::ok();
  }
  Status finish() override {
    const std::string name = out_.destination().string();
    RAYLOD_RETURN_IF_ERROR(start_finish(name, finished_, triangles_));
    for (uint64_t t = 0; t < triangles_; ++t) {
      uint8_t rec[13];
      rec[0] = 3;
      const int32_t idx[3] = {int32_t(3 * t), int32_t(3 * t + 1), int32_t(3 * t + 2)};
      std::memcpy(rec + 1, idx, 12);
      RAYLOD_RETURN_IF_ERROR(file_.write(rec, sizeof rec));
    }
    std::string h = "ply\nformat binary_little_endian 1.0\ncomment written by raylod (triangle soup)\n";
    h += "element vertex " + std::to_string(3 * triangles_) + "\n";
    h += "property float x\nproperty float y\nproperty float z\n";
    if (normals_) h += "property float nx\nproperty float ny\nproperty float nz\n";
    h += "element face " + std::to_string(triangles_) + "\nproperty list uchar int vertex_indices\n";
    const std::string end = "end_header\n";
    const size_t pad = kHeaderSlot - h.size() - end.size();  // > 200 bytes: the slot has room
    h += "comment" + std::string(pad - 8, ' ') + "\n" + end;
    RAYLOD_RETURN_IF_ERROR(file_.write_at(0, h.data(), h.size()));
    RAYLOD_RETURN_IF_ERROR(file_.close());
    return out_.commit();
  }
  uint64_t triangles_written() const override { return triangles_; }

 private:
  AtomicOutput out_;
  OutputFile file_;
  WriterOptions options_;
  bool layout_fixed_ = false, normals_ = false, finished_ = false;
  uint64_t triangles_ = 0;
};

class StlWriter final : public MeshWriter {
 public:
  StlWriter(const std::filesystem::path& path, WriterOptions options) : out_(path), file_(path.string()) {}
  Status start() {
    RAYLOD_RETURN_IF_ERROR(file_.open(out_.temp_path()));
    // The header must not begin with "solid": readers that sniff it would take the file for ASCII.
    char header[84] = {};
    std::snprintf(header, 80, "binary STL written by raylod");
    return file_.write(header, sizeof header);
  }
  Status write(const TriangleBatch& batch) override {
    const std::string name = out_.destination().string();
    if (finished_) return Status::error(name + ": write after finish");
    RAYLOD_RETURN_IF_ERROR(check_batch(name, batch));
    if (triangles_ + batch.size() > std::numeric_limits<uint32_t>::max())
      return Status::error(name + ": more than 2^32-1 triangles do not fit binary STL");
    for (size_t t = 0; t < batch.size(); ++t) {
      const Vec3* p = &batch.positions[3 * t];
      // STL stores face normals only; the right-hand-rule normal of the corners.
      const Vec3 n(face_normal(Vec3d(p[0]), Vec3d(p[1]), Vec3d(p[2])));
      uint8_t rec[50] = {};
      std::memcpy(rec, &n.x, 12);
      std::memcpy(rec + 12, &p[0].x, 12);
      std::memcpy(rec + 24, &p[1].x, 12);
      std::memcpy(rec + 36, &p[2].x, 12);
      RAYLOD_RETURN_IF_ERROR(file_.write(rec, sizeof rec));
    }
    triangles_ += batch.size();
    return Status::ok();
  }
  Status finish() override {
    const std::string name = out_.destination().string();
    RAYLOD_RETURN_IF_ERROR(start_finish(name, finished_, triangles_));
    const uint32_t count = uint32_t(triangles_);
    RAYLOD_RETURN_IF_ERROR(file_.write_at(80, &count, 4));
    RAYLOD_RETURN_IF_ERROR(file_.close());
    return out_.commit();
  }
  uint64_t triangles_written() const override { return triangles_; }

 private:
  AtomicOutput out_;
  OutputFile file_;
  bool finished_ = false;
  uint64_t triangles_ = 0;
};

}  // namespace

StatusOr<std::unique_ptr<MeshWriter>> create_mesh_writer(const std::filesystem::path& path, WriterOptions options) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".ply") {
    auto w = std::make_unique<PlyWriter>(path, options);
    RAYLOD_RETURN_IF_ERROR(w->start());
    return std::unique_ptr<MeshWriter>(std::move(w));
  }
  if (ext == ".stl") {
    auto w = std::make_unique<StlWriter>(path, options);
    RAYLOD_RETURN_IF_ERROR(w->start());
    return std::unique_ptr<MeshWriter>(std::move(w));
  }
  return Status::error(path.string() + ": cannot write meshes with extension '" + ext + "' (expected .ply or .stl)");
}

}  // namespace raylod
