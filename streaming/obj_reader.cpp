// Streaming Wavefront OBJ reader: v, vn and f (v, v/vt, v//vn, v/vt/vn
// corners; 1-based and negative, i.e. relative, indices; polygons as fans).
// Texture coordinates, groups, objects, smoothing groups, materials, free-form
// geometry, line and point elements are ignored; '#' starts a comment and a
// trailing backslash continues a line.
//
// Two passes over the memory-mapped file. Pass 1 (on open) spills v and vn
// to a mapped scratch file (so the vertex table is paged by the OS, not held
// on the heap), checks every face's syntax and relative indices, and counts
// faces. Pass 2 (next()) re-reads the face lines and emits triangles.
// Normals are used only if every face gives one for each of its corners;
// otherwise the whole mesh is read without normals (mixing smooth-shaded and
// unshaded faces in one mesh has no meaning for the renderer, and dropping
// them is better than inventing some).
#include <cstring>
#include <string>
#include <vector>

#include "streaming/mapped_file.h"
#include "streaming/mesh_reader.h"
#include "streaming/text_scan.h"
#include "streaming/vertex_table.h"

namespace raylod {
namespace {

// Logical lines: physical lines joined at a trailing backslash, comments cut.
class ObjLines {
 public:
  ObjLines() = default;
  ObjLines(std::string_view text, size_t offset, uint64_t line) : lc_(text, offset, line) {}
  bool next(std::string_view& line, uint64_t& number) {
    std::string_view phys;
    if (!lc_.next(phys)) return false;
    number = lc_.line_number();
    if (phys.empty() || phys.back() != '\\') {
      line = cut_comment(phys);
      return true;
    }
    joined_.assign(phys.data(), phys.size() - 1);
    while (lc_.next(phys)) {
      joined_ += ' ';
      if (phys.empty() || phys.back() != '\\') {
        joined_.append(phys.data(), phys.size());
        break;
      }
      joined_.append(phys.data(), phys.size() - 1);
    }
    line = cut_comment(joined_);
    return true;
  }
  size_t offset() const { return lc_.offset(); }

 private:
  static std::string_view cut_comment(std::string_view s) {
    const size_t h = s.find('#');
    return h == std::string_view::npos ? s : s.substr(0, h);
  }
  text::LineCursor lc_;
  std::string joined_;
};

// One face corner "v", "v/vt", "v//vn" or "v/vt/vn"; 0 means absent.
struct Corner {
  int64_t v = 0, vt = 0, vn = 0;
};

bool parse_corner(std::string_view tok, Corner& c) {
  c = Corner{};
  const size_t s1 = tok.find('/');
  if (!text::parse_number(tok.substr(0, s1), c.v) || c.v == 0) return false;
  if (s1 == std::string_view::npos) return true;
  std::string_view rest = tok.substr(s1 + 1);
  const size_t s2 = rest.find('/');
  std::string_view vt = rest.substr(0, s2);
  if (!vt.empty() && (!text::parse_number(vt, c.vt) || c.vt == 0)) return false;
  if (s2 == std::string_view::npos) return !vt.empty();
  std::string_view vn = rest.substr(s2 + 1);
  return text::parse_number(vn, c.vn) && c.vn != 0;
}

class ObjReader final : public MeshReader {
 public:
  static StatusOr<std::unique_ptr<MeshReader>> open(const std::filesystem::path& path, ReaderOptions options);
  StatusOr<bool> next(TriangleBatch& batch) override;

 private:
  Status error(const std::string& message) const { return Status::error(path_.string() + ": " + message); }
  Status at(uint64_t line, const std::string& message) const {
    return error("line " + std::to_string(line) + ": " + message);
  }
  Status first_pass();
  // Parses the corners of an f line into corners_; checks syntax and the
  // relative indices against the counts seen so far.
  Status parse_face(text::Tokens& tok, uint64_t line, uint64_t v_seen, uint64_t vt_seen, uint64_t vn_seen);

  MappedFile file_;
  ReaderOptions options_;
  SpillFile v_spill_, vn_spill_;
  Vec3Table pos_, nrm_;
  bool use_normals_ = false;
  std::vector<Corner> corners_;
  std::vector<Vec3> poly_pos_, poly_nrm_;
  // Pass 2 state.
  ObjLines lines_;
  uint64_t v_seen_ = 0, vt_seen_ = 0, vn_seen_ = 0, faces_done_ = 0, face_count_ = 0, triangles_ = 0;
  uint64_t vt_count_ = 0;  // texture coordinates (not read; their indices are checked)
  bool done_ = false;
  size_t released_ = 0;
  // Where pass 2 starts: the first f line, and the v / vn counts before it.
  size_t first_face_offset_ = 0;
  uint64_t first_face_line_ = 1, v_before_ = 0, vt_before_ = 0, vn_before_ = 0;
};

Status ObjReader::parse_face(text::Tokens& tok, uint64_t line, uint64_t v_seen, uint64_t vt_seen, uint64_t vn_seen) {
  corners_.clear();
  std::string_view t;
  while (tok.next(t)) {
    Corner c;
    if (!parse_corner(t, c))
      return at(line, "bad face corner '" + std::string(text::clip(t)) + "' (expected v, v/vt, v//vn or v/vt/vn with non-zero integers)");
    if (c.v < 0 && uint64_t(-c.v) > v_seen)
      return at(line, "relative vertex index " + std::to_string(c.v) + " refers before the first vertex (" +
                          std::to_string(v_seen) + " defined so far)");
    if (c.vt < 0 && uint64_t(-c.vt) > vt_seen)
      return at(line, "relative texture coordinate index " + std::to_string(c.vt) +
                          " refers before the first texture coordinate (" + std::to_string(vt_seen) + " defined so far)");
    if (c.vn < 0 && uint64_t(-c.vn) > vn_seen)
      return at(line, "relative normal index " + std::to_string(c.vn) + " refers before the first normal (" +
                          std::to_string(vn_seen) + " defined so far)");
    corners_.push_back(c);
  }
  if (corners_.size() < 3)
    return at(line, "a face has " + std::to_string(corners_.size()) + " corners; at least 3 are needed");
  return Status::ok();
}

Status ObjReader::first_pass() {
  RAYLOD_ASSIGN_OR_RETURN(v_spill_, SpillFile::create(path_.string() + " vertex table"));
  RAYLOD_ASSIGN_OR_RETURN(vn_spill_, SpillFile::create(path_.string() + " normal table"));
  ObjLines lines(file_.text(), text::utf8_bom_bytes(file_.text()), 1);
  std::string_view line, kw, t;
  uint64_t ln = 0, nv = 0, nt = 0, nn = 0, faces = 0, faces_with_normals = 0, triangles = 0;
  size_t line_start = 0;
  while (true) {
    line_start = lines.offset();
    if (!lines.next(line, ln)) break;
    text::Tokens tok(line);
    if (!tok.next(kw)) continue;
    if (kw == "v" || kw == "vn") {
      if (kw == "v" && nv == 0) {
        // The first vertex decides the local origin (MeshHeader::origin).
        text::Tokens first = tok;
        double d[3];
        std::string_view u;
        bool ok = true;
        for (double& c : d) ok = ok && first.next(u) && text::parse_double(u, c);
        if (ok) header_.origin = local_origin_for(Vec3d(d[0], d[1], d[2]));
      }
      float x[3];
      for (int i = 0; i < 3; ++i) {
        float& c = x[i];
        if (!tok.next(t)) return at(ln, "'" + std::string(kw) + "' needs 3 coordinates");
        const text::FloatParse parsed = text::parse_coordinate(t, kw == "v" ? header_.origin[i] : 0.0, c);
        if (parsed == text::FloatParse::NotANumber) return at(ln, "'" + std::string(text::clip(t)) + "' is not a number");
        if (parsed == text::FloatParse::OutOfRange)
          return at(ln, (kw == "v" ? "vertex " + std::to_string(nv + 1) + " coordinate "
                                   : "normal " + std::to_string(nn + 1) + " component ") +
                            std::string(text::clip(t)) + " is beyond the float range (about +-3.4e38)");
        if (parsed == text::FloatParse::FarFromOrigin)
          return at(ln, "vertex " + std::to_string(nv + 1) + " coordinate " + std::string(text::clip(t)) +
                            " lies more than the float range from the mesh's first vertex " + vec_text(header_.origin) +
                            ": the mesh spans more than the float range (about 3.4e38)");
      }
      const Vec3 p(x[0], x[1], x[2]);
      if (kw == "v") {
        if (!is_finite(p)) return at(ln, "vertex " + std::to_string(nv + 1) + " has a non-finite coordinate " + vec_text(p));
        RAYLOD_RETURN_IF_ERROR(v_spill_.append(x, sizeof x));
        ++nv;
      } else {
        if (!is_finite(p)) return at(ln, "normal " + std::to_string(nn + 1) + " is not finite " + vec_text(p));
        RAYLOD_RETURN_IF_ERROR(vn_spill_.append(x, sizeof x));
        ++nn;
      }
    } else if (kw == "vt") {
      ++nt;
    } else if (kw == "f") {
      RAYLOD_RETURN_IF_ERROR(parse_face(tok, ln, nv, nt, nn));
      if (faces == 0) {
        first_face_offset_ = line_start;
        first_face_line_ = ln;
        v_before_ = nv;
        vt_before_ = nt;
        vn_before_ = nn;
      }
      bool all = true;
      for (const Corner& c : corners_) all = all && c.vn != 0;
      faces_with_normals += all;
      ++faces;
      triangles += corners_.size() - 2;
    }
    // Everything else (vp, g, o, s, usemtl, mtllib, l, p, ...) is ignored.
  }
  if (faces == 0) return error("empty mesh: no faces ('f' lines)");
  if (nv == 0) return error("empty mesh: faces but no vertices ('v' lines)");
  RAYLOD_RETURN_IF_ERROR(v_spill_.map());
  RAYLOD_RETURN_IF_ERROR(vn_spill_.map());
  pos_.base = v_spill_.data();
  pos_.stride = 12;
  pos_.count = nv;
  pos_.finalize();
  nrm_.base = vn_spill_.data();
  nrm_.stride = 12;
  nrm_.count = nn;
  nrm_.finalize();
  use_normals_ = faces_with_normals == faces;
  vt_count_ = nt;
  face_count_ = faces;
  header_.vertex_count = nv;
  header_.face_count = faces;
  header_.has_normals = use_normals_;
  (void)triangles;
  return Status::ok();
}

StatusOr<std::unique_ptr<MeshReader>> ObjReader::open(const std::filesystem::path& path, ReaderOptions options) {
  auto r = std::make_unique<ObjReader>();
  r->path_ = path;
  r->options_ = options;
  if (r->options_.batch_triangles == 0) r->options_.batch_triangles = 1;
  RAYLOD_ASSIGN_OR_RETURN(r->file_, MappedFile::open(path));
  if (r->file_.size() == 0) return r->error("empty file");
  if (r->file_.text().substr(0, 4096).find('\0') != std::string_view::npos)
    return r->error("not an OBJ file (it contains binary data)");
  r->file_.advise_sequential();
  RAYLOD_RETURN_IF_ERROR(r->first_pass());
  r->header_.format = MeshFormat::Obj;
  r->header_.encoding = "ascii";
  r->header_.file_bytes = r->file_.size();
  r->lines_ = ObjLines(r->file_.text(), r->first_face_offset_, r->first_face_line_);
  r->v_seen_ = r->v_before_;
  r->vn_seen_ = r->vn_before_;
  r->vt_seen_ = r->vt_before_;
  r->released_ = 0;
  return std::unique_ptr<MeshReader>(std::move(r));
}

StatusOr<bool> ObjReader::next(TriangleBatch& batch) {
  batch.clear();
  if (done_) return false;
  const size_t cap = options_.batch_triangles;
  batch.positions.reserve(3 * cap);
  if (use_normals_) batch.normals.reserve(3 * cap);
  std::string_view line, kw;
  uint64_t ln = 0;
  while (faces_done_ < face_count_ && batch.size() < cap) {
    if (!lines_.next(line, ln)) return error("the file changed while it was read (fewer faces than on open)");
    text::Tokens tok(line);
    if (!tok.next(kw)) continue;
    if (kw == "v") { ++v_seen_; continue; }
    if (kw == "vn") { ++vn_seen_; continue; }
    if (kw == "vt") { ++vt_seen_; continue; }
    if (kw != "f") continue;
    RAYLOD_RETURN_IF_ERROR(parse_face(tok, ln, v_seen_, vt_seen_, vn_seen_));
    const size_t n = corners_.size();
    poly_pos_.resize(n);
    poly_nrm_.resize(n);
    bool zero_normal = false;
    for (size_t k = 0; k < n; ++k) {
      const Corner& c = corners_[k];
      // 1-based, or relative to the vertices defined so far (pass 1 checked those).
      const int64_t vi = c.v > 0 ? c.v - 1 : int64_t(v_seen_) + c.v;
      if (uint64_t(vi) >= pos_.count)
        return at(ln, "vertex index " + std::to_string(c.v) + " is out of range (the file has " +
                          std::to_string(pos_.count) + " vertices)");
      poly_pos_[k] = pos_.load(uint64_t(vi));
      if (c.vt > 0 && uint64_t(c.vt) > vt_count_)  // texture coordinates are not read, but a bad index is an error
        return at(ln, "texture coordinate index " + std::to_string(c.vt) + " is out of range (the file has " +
                          std::to_string(vt_count_) + " texture coordinates)");
      if (!use_normals_) continue;
      const int64_t ni = c.vn > 0 ? c.vn - 1 : int64_t(vn_seen_) + c.vn;
      if (uint64_t(ni) >= nrm_.count)
        return at(ln, "normal index " + std::to_string(c.vn) + " is out of range (the file has " +
                          std::to_string(nrm_.count) + " normals)");
      poly_nrm_[k] = nrm_.load(uint64_t(ni));
      // Pass 1 rejected non-finite normals, so this one has zero length:
      // replaced per triangle below.
      if (!unit_normal(poly_nrm_[k])) zero_normal = true;
    }
    repaired_normals_ += append_polygon_fan(poly_pos_.data(), use_normals_ ? poly_nrm_.data() : nullptr, n,
                                            zero_normal, batch.positions, batch.normals);
    triangles_ += n - 2;
    ++faces_done_;
  }
  const size_t cursor = lines_.offset();
  if (cursor >= released_ + (size_t(1) << 22)) {
    file_.release(released_, cursor);
    released_ = cursor & ~size_t(4095);
  }
  if (batch.size() > 0) return true;
  done_ = true;
  if (triangles_ == 0) return error("empty mesh: no triangles");
  warn_repaired_normals();
  return false;
}

}  // namespace

StatusOr<std::unique_ptr<MeshReader>> open_obj_reader(const std::filesystem::path& path, ReaderOptions options) {
  return ObjReader::open(path, options);
}

}  // namespace raylod
