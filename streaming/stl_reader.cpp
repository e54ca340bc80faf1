// Streaming STL reader, binary and ASCII.
//
// Binary STL: an 80-byte header, a little-endian uint32 triangle count, then
// 50 bytes per triangle (facet normal, three vertices, 2 attribute bytes).
// Some real binary files begin their header with "solid", so the encoding is
// decided by the size check (84 + 50 * count == file size), not by the first
// word; a file that starts with "solid" and fails the check is read as ASCII.
// ASCII STL: solid / facet normal / outer loop / 3 x vertex / endloop /
// endfacet / endsolid, keywords case-insensitive, several solids allowed.
//
// STL has no per-vertex normals (has_normals = false). Facet normals must be
// finite (NaN/Inf are rejected: they mark a corrupt exporter) but are not
// otherwise used, so zero or wrong facet normals are accepted.
#include <bit>
#include <cstring>
#include <string>

#include "streaming/mapped_file.h"
#include "streaming/mesh_reader.h"
#include "streaming/text_scan.h"
#include "streaming/vertex_table.h"

namespace raylod {
namespace {

constexpr size_t kHeaderBytes = 84, kRecordBytes = 50;

inline bool finite_bits(const float* f, int n) {
  uint32_t bad = 0;
  for (int i = 0; i < n; ++i) {
    uint32_t u;
    std::memcpy(&u, f + i, 4);
    bad |= uint32_t((u & 0x7f800000u) == 0x7f800000u);
  }
  return bad == 0;
}

// Token stream over ASCII STL that counts lines.
struct StlCursor {
  const char* p = nullptr;
  const char* end = nullptr;
  uint64_t line = 1;
  bool token(std::string_view& t, uint64_t& tline) {
    while (p < end && (text::is_space(*p) || *p == '\n')) {
      if (*p == '\n') ++line;
      ++p;
    }
    if (p == end) return false;
    const char* b = p;
    while (p < end && !text::is_space(*p) && *p != '\n') ++p;
    t = std::string_view(b, size_t(p - b));
    tline = line;
    return true;
  }
  void skip_line() {
    const void* nl = std::memchr(p, '\n', size_t(end - p));
    p = nl ? static_cast<const char*>(nl) : end;
  }
};

class StlReader final : public MeshReader {
 public:
  static StatusOr<std::unique_ptr<MeshReader>> open(const std::filesystem::path& path, ReaderOptions options);
  StatusOr<bool> next(TriangleBatch& batch) override;

 private:
  Status error(const std::string& message) const { return Status::error(path_.string() + ": " + message); }
  // Parses up to the next facet; have_facet is false at the end of the file.
  Status read_facet(StlCursor& c, bool& in_solid, Vec3 v[3], bool& have_facet) const;
  StatusOr<bool> next_binary(TriangleBatch& batch);
  StatusOr<bool> next_ascii(TriangleBatch& batch);

  MappedFile file_;
  ReaderOptions options_;
  bool binary_ = true;
  uint64_t count_ = 0, done_count_ = 0;
  StlCursor cursor_;
  bool in_solid_ = false, done_ = false;
  size_t released_ = 0;
};

Status StlReader::read_facet(StlCursor& c, bool& in_solid, Vec3 v[3], bool& have_facet) const {
  have_facet = false;
  std::string_view t;
  uint64_t line = 0;
  auto at = [&](uint64_t l) { return "line " + std::to_string(l) + ": "; };
  auto expect = [&](const char* word) -> Status {
    if (!c.token(t, line)) return error("truncated: the file ends inside a facet (expected '" + std::string(word) + "')");
    if (!text::iequals(t, word))
      return error(at(line) + "expected '" + word + "', found '" + std::string(text::clip(t)) + "'");
    return Status::ok();
  };
  auto numbers = [&](const char* what, Vec3& out) -> Status {
    for (int k = 0; k < 3; ++k) {
      if (!c.token(t, line)) return error("truncated: the file ends inside a facet (in '" + std::string(what) + "')");
      const text::FloatParse parsed = text::parse_float(t, out[k]);
      if (parsed == text::FloatParse::NotANumber)
        return error(at(line) + "expected 3 numbers after '" + what + "', found '" +
                     std::string(text::clip(t)) + "'");
      if (parsed == text::FloatParse::OutOfRange)
        return error(at(line) + std::string(what) + (k == 0 ? " x" : k == 1 ? " y" : " z") + " = " +
                     std::string(text::clip(t)) + " is beyond the float range (about +-3.4e38)");
    }
    return Status::ok();
  };
  while (true) {
    if (!c.token(t, line)) {
      if (in_solid) return error("truncated: the file ends without 'endsolid' (line " + std::to_string(c.line) + ")");
      return Status::ok();
    }
    if (!in_solid) {
      if (!text::iequals(t, "solid")) return error(at(line) + "expected 'solid', found '" + std::string(text::clip(t)) + "'");
      in_solid = true;
      c.skip_line();  // the solid's name, possibly several words
      continue;
    }
    if (text::iequals(t, "endsolid")) {
      in_solid = false;
      c.skip_line();
      continue;
    }
    if (!text::iequals(t, "facet"))
      return error(at(line) + "expected 'facet' or 'endsolid', found '" + std::string(text::clip(t)) + "'");
    const uint64_t facet_line = line;
    RAYLOD_RETURN_IF_ERROR(expect("normal"));
    Vec3 n;
    RAYLOD_RETURN_IF_ERROR(numbers("facet normal", n));
    if (!is_finite(n)) return error(at(facet_line) + "facet normal is not finite " + vec_text(n));
    RAYLOD_RETURN_IF_ERROR(expect("outer"));
    RAYLOD_RETURN_IF_ERROR(expect("loop"));
    int k = 0;
    while (true) {
      if (!c.token(t, line)) return error("truncated: the file ends inside the facet at line " + std::to_string(facet_line));
      if (text::iequals(t, "endloop")) break;
      if (!text::iequals(t, "vertex"))
        return error(at(line) + "expected 'vertex' or 'endloop', found '" + std::string(text::clip(t)) + "'");
      if (k == 3)
        return error(at(facet_line) + "facet has more than 3 vertices (STL facets are triangles)");
      const uint64_t vline = line;
      RAYLOD_RETURN_IF_ERROR(numbers("vertex", v[k]));
      if (!is_finite(v[k])) return error(at(vline) + "vertex has a non-finite coordinate " + vec_text(v[k]));
      ++k;
    }
    if (k < 3)
      return error(at(facet_line) + "facet has " + std::to_string(k) + " vertices; STL facets need exactly 3");
    RAYLOD_RETURN_IF_ERROR(expect("endfacet"));
    have_facet = true;
    return Status::ok();
  }
}

StatusOr<std::unique_ptr<MeshReader>> StlReader::open(const std::filesystem::path& path, ReaderOptions options) {
  auto r = std::make_unique<StlReader>();
  r->path_ = path;
  r->options_ = options;
  if (r->options_.batch_triangles == 0) r->options_.batch_triangles = 1;
  RAYLOD_ASSIGN_OR_RETURN(r->file_, MappedFile::open(path));
  const size_t size = r->file_.size();
  const uint8_t* d = r->file_.data();
  if (size == 0) return r->error("empty file");
  uint64_t declared = 0;
  bool size_matches = false;
  if (size >= kHeaderBytes) {
    declared = uint64_t(d[80]) | uint64_t(d[81]) << 8 | uint64_t(d[82]) << 16 | uint64_t(d[83]) << 24;
    size_matches = kHeaderBytes + kRecordBytes * declared == size;
  }
  // "solid" as the first word, and no NUL byte in the first 512 bytes (text).
  const size_t bom = text::utf8_bom_bytes(r->file_.text());
  std::string_view head = r->file_.text().substr(bom, 512);
  size_t i = 0;
  while (i < head.size() && (text::is_space(head[i]) || head[i] == '\n')) ++i;
  const bool says_solid = head.size() >= i + 5 && text::iequals(head.substr(i, 5), "solid") &&
                          (head.size() == i + 5 || text::is_space(head[i + 5]) || head[i + 5] == '\n');
  const bool looks_text = head.find('\0') == std::string_view::npos;
  MeshHeader& h = r->header_;
  h.format = MeshFormat::Stl;
  h.has_normals = false;
  h.file_bytes = size;
  if (size_matches) {
    r->binary_ = true;
    r->count_ = declared;
    if (declared == 0) return r->error("empty mesh: the binary STL header declares 0 triangles");
    h.encoding = "binary";
    r->file_.advise_sequential();
    r->released_ = 0;
  } else if (says_solid && looks_text) {
    r->binary_ = false;
    h.encoding = "ascii";
    // A validating pass counts the facets, so that errors surface on open and
    // the header's counts are exact.
    StlCursor c{reinterpret_cast<const char*>(d) + bom, reinterpret_cast<const char*>(d) + size, 1};
    bool in_solid = false, have = true;
    Vec3 v[3];
    uint64_t n = 0;
    while (true) {
      RAYLOD_RETURN_IF_ERROR(r->read_facet(c, in_solid, v, have));
      if (!have) break;
      ++n;
    }
    if (n == 0) return r->error("empty mesh: the ASCII STL file has no facets");
    r->count_ = n;
    r->cursor_ = StlCursor{reinterpret_cast<const char*>(d) + bom, reinterpret_cast<const char*>(d) + size, 1};
  } else if (size < kHeaderBytes) {
    return r->error("not an STL file: too short for a binary STL header (" + std::to_string(size) +
                    " bytes, need 84) and not ASCII STL (no leading 'solid')");
  } else {
    return r->error("wrong triangle count in the binary STL header: it declares " + std::to_string(declared) +
                    " triangles (84 + 50 x " + std::to_string(declared) + " = " +
                    std::to_string(kHeaderBytes + kRecordBytes * declared) + " bytes), but the file has " +
                    std::to_string(size) + " bytes" +
                    ((size - kHeaderBytes) % kRecordBytes ? "" : " (room for " + std::to_string((size - kHeaderBytes) / kRecordBytes) + ")"));
  }
  h.face_count = r->count_;
  h.vertex_count = 3 * r->count_;
  return std::unique_ptr<MeshReader>(std::move(r));
}

StatusOr<bool> StlReader::next_binary(TriangleBatch& batch) {
  const uint64_t end = std::min<uint64_t>(count_, done_count_ + options_.batch_triangles);
  batch.positions.resize(size_t(3 * (end - done_count_)));
  Vec3* out = batch.positions.data();
  const uint8_t* rec = file_.data() + kHeaderBytes + kRecordBytes * done_count_;
  for (uint64_t t = done_count_; t < end; ++t, rec += kRecordBytes, out += 3) {
    float f[12];
    std::memcpy(f, rec, sizeof f);
    if constexpr (std::endian::native == std::endian::big) {
      for (float& x : f) x = std::bit_cast<float>(__builtin_bswap32(std::bit_cast<uint32_t>(x)));
    }
    if (!finite_bits(f, 12)) {
      const bool normal_ok = finite_bits(f, 3);
      batch.clear();
      return error("triangle " + std::to_string(t) + ": " +
                   (normal_ok ? "a vertex has a non-finite coordinate" : "the facet normal is not finite " +
                                                                            vec_text(Vec3(f[0], f[1], f[2]))));
    }
    std::memcpy(out, f + 3, sizeof(float) * 9);
  }
  done_count_ = end;
  const size_t cursor = size_t(rec - file_.data());
  if (cursor >= released_ + (size_t(1) << 22)) {
    file_.release(released_, cursor);
    released_ = cursor & ~size_t(4095);
  }
  return batch.size() > 0;
}

StatusOr<bool> StlReader::next_ascii(TriangleBatch& batch) {
  const size_t cap = options_.batch_triangles;
  batch.positions.reserve(3 * cap);
  Vec3 v[3];
  bool have = false;
  while (batch.size() < cap) {
    RAYLOD_RETURN_IF_ERROR(read_facet(cursor_, in_solid_, v, have));
    if (!have) break;
    batch.positions.insert(batch.positions.end(), v, v + 3);
    ++done_count_;
  }
  return batch.size() > 0;
}

StatusOr<bool> StlReader::next(TriangleBatch& batch) {
  // Binary batches are resized, not cleared first, so that a batch of the
  // same size as the last one is not zero-filled again.
  if (done_ || !binary_) batch.clear();
  batch.normals.clear();
  if (done_) return false;
  StatusOr<bool> r = binary_ ? next_binary(batch) : next_ascii(batch);
  if (r.is_ok() && !r.value()) {
    done_ = true;
    if (done_count_ != count_)  // the file changed between open and read
      return error("read " + std::to_string(done_count_) + " triangles, expected " + std::to_string(count_));
  }
  return r;
}

}  // namespace

StatusOr<std::unique_ptr<MeshReader>> open_stl_reader(const std::filesystem::path& path, ReaderOptions options) {
  return StlReader::open(path, options);
}

}  // namespace raylod
