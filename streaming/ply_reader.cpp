// Streaming PLY reader (G. Turk's Polygon File Format, 1994): ASCII and
// binary little/big endian, any scalar property types, any element order.
//
// Binary files are memory-mapped; vertices are indexed in place (record
// stride), faces are decoded sequentially in batches. The common face layout
// (one "list uchar int|uint" property, host byte order) has its own tight
// loop; every other layout goes through the generic record decoder. ASCII
// files are read twice: once on open to spill the vertices to a mapped
// scratch file and to check the element counts, then once for the faces.
#include <algorithm>
#include <bit>
#include <cstring>
#include <string>
#include <vector>

#include "streaming/mapped_file.h"
#include "streaming/mesh_reader.h"
#include "streaming/text_scan.h"
#include "streaming/vertex_table.h"

namespace raylod {
namespace {

constexpr bool kHostLittle = std::endian::native == std::endian::little;

enum class PlyEncoding { Ascii, BinaryLittle, BinaryBig };

struct PlyProperty {
  std::string name;
  ScalarType type = ScalarType::Float32;  // the item type for lists
  bool is_list = false;
  ScalarType count_type = ScalarType::UInt8;
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  uint64_t line = 0;             // header line that declared it
  std::vector<PlyProperty> props;
  size_t record_size = 0;        // bytes per binary record; 0 if it has a list property
};

// The vertex properties the reader uses, in coord_prop_ order.
const char* const kCoordNames[6] = {"x", "y", "z", "nx", "ny", "nz"};

bool parse_scalar_type(std::string_view s, ScalarType& t) {
  struct Name { const char* name; ScalarType type; };
  static const Name names[] = {
      {"char", ScalarType::Int8},     {"int8", ScalarType::Int8},       {"uchar", ScalarType::UInt8},
      {"uint8", ScalarType::UInt8},   {"short", ScalarType::Int16},     {"int16", ScalarType::Int16},
      {"ushort", ScalarType::UInt16}, {"uint16", ScalarType::UInt16},   {"int", ScalarType::Int32},
      {"int32", ScalarType::Int32},   {"uint", ScalarType::UInt32},     {"uint32", ScalarType::UInt32},
      {"float", ScalarType::Float32}, {"float32", ScalarType::Float32}, {"double", ScalarType::Float64},
      {"float64", ScalarType::Float64}};
  for (const auto& n : names) {
    if (s == n.name) { t = n.type; return true; }
  }
  return false;
}

class PlyReader final : public MeshReader {
 public:
  static StatusOr<std::unique_ptr<MeshReader>> open(const std::filesystem::path& path, ReaderOptions options);
  StatusOr<bool> next(TriangleBatch& batch) override;

 private:
  Status error(const std::string& message) const { return Status::error(path_.string() + ": " + message); }
  // "line 17" for ASCII faces, "face 12" for binary ones.
  std::string where(uint64_t face, uint64_t line) const {
    return line ? "line " + std::to_string(line) : "face " + std::to_string(face);
  }
  Status parse_header();
  Status check_elements();
  Status locate_binary();
  Status load_ascii();
  Vec3d first_vertex_origin(const PlyElement& ve, std::string_view line) const;
  Status skip_binary_record(const PlyElement& e, size_t& pos, uint64_t record) const;
  Status skip_binary_element(const PlyElement& e, size_t& pos) const;
  Status finish_binary();
  template <class IndexT, bool kPacked, bool kNormals>
  StatusOr<bool> next_binary_fast(TriangleBatch& batch);
  template <class IndexT>
  StatusOr<bool> dispatch_fast(TriangleBatch& batch) {
    const bool packed = pos_.packed_float && (!has_normals_ || nrm_.packed_float);
    if (packed) return has_normals_ ? next_binary_fast<IndexT, true, true>(batch) : next_binary_fast<IndexT, true, false>(batch);
    return has_normals_ ? next_binary_fast<IndexT, false, true>(batch) : next_binary_fast<IndexT, false, false>(batch);
  }
  StatusOr<bool> next_binary_generic(TriangleBatch& batch);
  StatusOr<bool> next_ascii(TriangleBatch& batch);
  Status corner_error(int64_t index, uint64_t face, uint64_t line) const;
  std::string vertex_count_hint() const;
  Status emit_polygon(const int64_t* index, size_t n, TriangleBatch& batch, uint64_t face, uint64_t line);
  StatusOr<bool> end_of_faces();
  Status truncated_faces() const {
    return error("truncated: the file ends inside face " + std::to_string(faces_done_) + " of " +
                 std::to_string(elements_[face_el_].count) + " declared in the header");
  }
  void release_behind_cursor(size_t cursor);

  MappedFile file_;
  ReaderOptions options_;
  PlyEncoding encoding_ = PlyEncoding::Ascii;
  bool swap_ = false;
  std::vector<PlyElement> elements_;
  int vertex_el_ = -1, face_el_ = -1, index_prop_ = -1;
  int coord_prop_[6] = {-1, -1, -1, -1, -1, -1};  // x y z nx ny nz in the vertex element
  bool has_normals_ = false;
  uint64_t header_lines_ = 0;
  size_t data_offset_ = 0;

  SpillFile spill_;
  Vec3Table pos_, nrm_;

  size_t face_offset_ = 0, cursor_ = 0, released_ = 0, vertex_window_start_ = 0;
  text::LineCursor lines_;
  uint64_t faces_done_ = 0, triangles_ = 0;
  bool done_ = false;
  int fast_ = 0;  // 0: generic decoder, 1: uchar + int32 indices, 2: uchar + uint32 indices
  std::vector<int64_t> poly_;
  std::vector<Vec3> poly_pos_, poly_nrm_;
};

Status PlyReader::parse_header() {
  const std::string_view text = file_.text();
  if (text.substr(0, 3) != "ply" || (text.size() > 3 && text[3] != '\n' && text[3] != '\r'))
    return error("not a PLY file (it does not start with the line 'ply')");
  text::LineCursor lc(text);
  std::string_view line;
  lc.next(line);
  bool have_format = false, have_end = false;
  while (lc.next(line)) {
    const uint64_t ln = lc.line_number();
    auto bad = [&](const std::string& what) { return error("line " + std::to_string(ln) + ": " + what); };
    text::Tokens tok(line);
    std::string_view kw;
    if (!tok.next(kw)) continue;
    if (kw == "comment" || kw == "obj_info") continue;
    if (kw == "end_header") {
      if (!tok.done()) return bad("unexpected text after end_header");
      have_end = true;
      break;
    }
    if (kw == "format") {
      std::string_view enc, version;
      if (!tok.next(enc) || !tok.next(version) || !tok.done()) return bad("expected 'format <encoding> 1.0'");
      if (enc == "ascii") encoding_ = PlyEncoding::Ascii;
      else if (enc == "binary_little_endian") encoding_ = PlyEncoding::BinaryLittle;
      else if (enc == "binary_big_endian") encoding_ = PlyEncoding::BinaryBig;
      else return bad("unknown PLY encoding '" + std::string(text::clip(enc)) + "'");
      if (version != "1.0" && version != "1") return bad("unsupported PLY version '" + std::string(text::clip(version)) + "'");
      have_format = true;
      continue;
    }
    if (kw == "element") {
      std::string_view name, count;
      int64_t n = 0;
      if (!tok.next(name) || !tok.next(count) || !tok.done()) return bad("expected 'element <name> <count>'");
      if (!text::parse_number(count, n) || n < 0)
        return bad("element '" + std::string(text::clip(name)) + "' has an invalid count '" + std::string(text::clip(count)) + "'");
      elements_.push_back({std::string(name), uint64_t(n), ln, {}, 0});
      continue;
    }
    if (kw == "property") {
      if (elements_.empty()) return bad("property declared before any element");
      PlyProperty p;
      std::string_view t1, t2, name;
      if (!tok.next(t1)) return bad("expected 'property <type> <name>'");
      if (t1 == "list") {
        if (!tok.next(t2) || !tok.next(t1) || !tok.next(name) || !tok.done())
          return bad("expected 'property list <count type> <item type> <name>'");
        p.is_list = true;
        if (!parse_scalar_type(t2, p.count_type)) return bad("unsupported property type '" + std::string(text::clip(t2)) + "'");
        if (!is_integer(p.count_type)) return bad("list count type '" + std::string(t2) + "' is not an integer type");
      } else if (!tok.next(name) || !tok.done()) {
        return bad("expected 'property <type> <name>'");
      }
      if (!parse_scalar_type(t1, p.type)) return bad("unsupported property type '" + std::string(text::clip(t1)) + "'");
      p.name = std::string(name);
      for (const PlyProperty& q : elements_.back().props)
        if (q.name == p.name)  // which of the two is x? Ambiguous: refused
          return bad("property '" + std::string(text::clip(name)) + "' is declared twice in element '" +
                     elements_.back().name + "'");
      elements_.back().props.push_back(std::move(p));
      continue;
    }
    return bad("unknown header keyword '" + std::string(text::clip(kw)) + "'");
  }
  if (!have_end) return error("the header has no end_header line (truncated or not a PLY file)");
  if (!have_format) return error("the header has no format line");
  header_lines_ = lc.line_number();
  data_offset_ = lc.offset();
  swap_ = (encoding_ == PlyEncoding::BinaryLittle) != kHostLittle && encoding_ != PlyEncoding::Ascii;
  return Status::ok();
}

Status PlyReader::check_elements() {
  for (size_t i = 0; i < elements_.size(); ++i) {
    PlyElement& e = elements_[i];
    size_t rs = 0;
    for (const auto& p : e.props) rs = p.is_list ? SIZE_MAX : rs + scalar_size(p.type);
    e.record_size = rs == SIZE_MAX ? 0 : rs;
    if (e.name == "vertex" && vertex_el_ < 0) vertex_el_ = int(i);
    if (e.name == "face" && face_el_ < 0) face_el_ = int(i);
  }
  if (vertex_el_ < 0) return error("the header declares no 'vertex' element");
  if (face_el_ < 0) return error("the header declares no 'face' element (a point cloud is not a mesh)");
  const PlyElement& ve = elements_[vertex_el_];
  for (size_t k = 0; k < ve.props.size(); ++k) {
    for (int c = 0; c < 6; ++c) {
      if (ve.props[k].name == kCoordNames[c] && coord_prop_[c] < 0) {
        if (ve.props[k].is_list) return error(std::string("vertex property '") + kCoordNames[c] + "' is a list");
        coord_prop_[c] = int(k);
      }
    }
  }
  for (int c = 0; c < 3; ++c)
    if (coord_prop_[c] < 0) return error(std::string("the vertex element has no '") + kCoordNames[c] + "' property");
  const int normals = (coord_prop_[3] >= 0) + (coord_prop_[4] >= 0) + (coord_prop_[5] >= 0);
  if (normals != 0 && normals != 3) return error("the vertex element has some but not all of nx, ny, nz");
  has_normals_ = normals == 3;
  const PlyElement& fe = elements_[face_el_];
  for (size_t k = 0; k < fe.props.size(); ++k) {
    if ((fe.props[k].name == "vertex_indices" || fe.props[k].name == "vertex_index") && index_prop_ < 0) {
      if (!fe.props[k].is_list) return error("face property '" + fe.props[k].name + "' is not a list");
      if (!is_integer(fe.props[k].type))
        return error("face property '" + fe.props[k].name + "' has a non-integer index type (unsupported)");
      index_prop_ = int(k);
    }
  }
  if (index_prop_ < 0) return error("the face element has no 'vertex_indices' (or 'vertex_index') list property");
  if (ve.count == 0) return error("empty mesh: the header declares 0 vertices");
  if (fe.count == 0) return error("empty mesh: the header declares 0 faces");
  return Status::ok();
}

Status PlyReader::skip_binary_record(const PlyElement& e, size_t& pos, uint64_t record) const {
  const size_t size = file_.size();
  for (const auto& p : e.props) {
    if (!p.is_list) {
      pos += scalar_size(p.type);
      continue;
    }
    const size_t cs = scalar_size(p.count_type);
    if (pos + cs > size) {  // the file ends before this list's count
      pos = size + 1;
      break;
    }
    const int64_t n = load_integer(file_.data() + pos, p.count_type, swap_);
    if (n < 0)
      return error(e.name + " " + std::to_string(record) + ": negative list length " + std::to_string(n));
    pos += cs + size_t(n) * scalar_size(p.type);
  }
  if (pos > size)
    return error("truncated: the file ends inside " + e.name + " " + std::to_string(record) + " of " +
                 std::to_string(e.count) + " declared in the header");
  return Status::ok();
}

Status PlyReader::skip_binary_element(const PlyElement& e, size_t& pos) const {
  if (e.record_size > 0) {
    const size_t left = file_.size() - std::min(pos, file_.size());
    if (e.count > left / e.record_size)
      return error("truncated: element '" + e.name + "' needs " + std::to_string(e.count) + " records of " +
                   std::to_string(e.record_size) + " bytes, but only " + std::to_string(left) + " bytes remain");
    pos += e.count * e.record_size;
    return Status::ok();
  }
  // An element without properties takes no bytes, however many records it declares.
  if (e.props.empty()) return Status::ok();
  // Every record now takes at least one byte (a list count), so this ends within the file.
  for (uint64_t r = 0; r < e.count; ++r) RAYLOD_RETURN_IF_ERROR(skip_binary_record(e, pos, r));
  return Status::ok();
}

Status PlyReader::locate_binary() {
  const PlyElement& ve = elements_[vertex_el_];
  if (ve.record_size == 0) return error("binary PLY with a list property in the vertex element is not supported");
  size_t pos = data_offset_;
  bool have_vertices = false;
  for (size_t i = 0; i < elements_.size(); ++i) {
    if (int(i) == vertex_el_) {
      pos_.base = file_.data() + pos;
      have_vertices = true;
    }
    if (int(i) == face_el_) {
      face_offset_ = pos;
      if (have_vertices) break;  // the rest is checked when the faces are done
    }
    RAYLOD_RETURN_IF_ERROR(skip_binary_element(elements_[i], pos));
  }
  // Offsets of x y z (nx ny nz) inside a vertex record.
  uint32_t offs[6] = {0, 0, 0, 0, 0, 0};
  uint32_t off = 0;
  for (size_t k = 0; k < ve.props.size(); ++k) {
    for (int c = 0; c < 6; ++c)
      if (coord_prop_[c] == int(k)) offs[c] = off;
    off += uint32_t(scalar_size(ve.props[k].type));
  }
  pos_.stride = ve.record_size;
  pos_.count = ve.count;
  pos_.swap = swap_;
  nrm_ = pos_;
  for (int c = 0; c < 3; ++c) {
    pos_.type[c] = ve.props[coord_prop_[c]].type;
    pos_.offset[c] = offs[c];
    if (has_normals_) {
      nrm_.type[c] = ve.props[coord_prop_[3 + c]].type;
      nrm_.offset[c] = offs[3 + c];
    }
  }
  if (pos_.count > 0 && pos_.wider_than_float()) {
    pos_.finalize();  // load_exact does not depend on it
    pos_.origin = local_origin_for(pos_.load_exact(0));
    header_.origin = pos_.origin;
  }
  pos_.finalize();
  nrm_.finalize();
  const PlyElement& fe = elements_[face_el_];
  if (fe.props.size() == 1 && !swap_ && fe.props[0].count_type == ScalarType::UInt8) {
    if (fe.props[0].type == ScalarType::Int32) fast_ = 1;
    if (fe.props[0].type == ScalarType::UInt32) fast_ = 2;
  }
  cursor_ = face_offset_;
  released_ = face_offset_;
  vertex_window_start_ = face_offset_;
  file_.advise_sequential(face_offset_, file_.size());
  return Status::ok();
}

Status PlyReader::load_ascii() {
  RAYLOD_ASSIGN_OR_RETURN(spill_, SpillFile::create(path_.string() + " vertex table"));
  const PlyElement& ve = elements_[vertex_el_];
  text::LineCursor lc(file_.text(), data_offset_, header_lines_ + 1);
  std::string_view line;
  // Next non-blank line; false at the end of the file.
  auto next_record = [&]() {
    while (lc.next(line)) {
      if (!text::Tokens(line).done()) return true;
    }
    return false;
  };
  const int ncoords = has_normals_ ? 6 : 3;
  for (size_t i = 0; i < elements_.size(); ++i) {
    const PlyElement& e = elements_[i];
    if (int(i) == face_el_) {
      text::LineCursor at_faces = lc;
      for (uint64_t r = 0; r < e.count; ++r) {
        if (!next_record())
          return error("truncated: the file ends after " + std::to_string(r) + " of " + std::to_string(e.count) +
                       " faces declared in the header");
      }
      lines_ = at_faces;
      continue;
    }
    for (uint64_t r = 0; r < e.count; ++r) {
      if (!next_record())
        return error("truncated: the file ends after " + std::to_string(r) + " of " + std::to_string(e.count) + " '" +
                     e.name + "' records declared in the header");
      if (int(i) != vertex_el_) continue;
      const std::string ln = "line " + std::to_string(lc.line_number()) + ": ";
      float v[6] = {0, 0, 0, 0, 0, 0};
      text::Tokens tok(line);
      std::string_view t;
      if (r == 0) header_.origin = first_vertex_origin(ve, line);
      for (size_t k = 0; k < ve.props.size(); ++k) {
        const PlyProperty& p = ve.props[k];
        if (!tok.next(t)) return error(ln + "vertex " + std::to_string(r) + " has too few values for its header");
        if (p.is_list) {
          int64_t n = 0;
          if (!text::parse_number(t, n) || n < 0) return error(ln + "bad list length '" + std::string(text::clip(t)) + "'");
          for (int64_t j = 0; j < n; ++j)
            if (!tok.next(t)) return error(ln + "vertex " + std::to_string(r) + " has too few values for its header");
          continue;
        }
        for (int c = 0; c < ncoords; ++c) {
          if (coord_prop_[c] != int(k)) continue;
          const text::FloatParse parsed = text::parse_coordinate(t, c < 3 ? header_.origin[c] : 0.0, v[c]);
          if (parsed == text::FloatParse::NotANumber)
            return error(ln + "'" + std::string(text::clip(t)) + "' is not a number");
          if (parsed == text::FloatParse::OutOfRange)
            return error(ln + "vertex " + std::to_string(r) + (c < 3 ? " coordinate " : " normal component ") +
                         kCoordNames[c] + " = " + std::string(text::clip(t)) +
                         " is beyond the float range (about +-3.4e38)");
          if (parsed == text::FloatParse::FarFromOrigin)
            return error(ln + "vertex " + std::to_string(r) + " coordinate " + kCoordNames[c] + " = " +
                         std::string(text::clip(t)) + " lies more than the float range from the mesh's first vertex " +
                         vec_text(header_.origin) + ": the mesh spans more than the float range (about 3.4e38)");
        }
      }
      if (!tok.done()) return error(ln + "vertex " + std::to_string(r) + " has more values than its header declares");
      if (!is_finite(Vec3(v[0], v[1], v[2])))
        return error(ln + "vertex " + std::to_string(r) + " has a non-finite coordinate " + vec_text(Vec3(v[0], v[1], v[2])));
      RAYLOD_RETURN_IF_ERROR(spill_.append(v, sizeof(float) * size_t(ncoords)));
    }
  }
  if (next_record())
    return error("line " + std::to_string(lc.line_number()) +
                 ": more data than the header declares (wrong element count in the header?)");
  RAYLOD_RETURN_IF_ERROR(spill_.map());
  pos_ = Vec3Table{};
  pos_.base = spill_.data();
  pos_.stride = sizeof(float) * size_t(ncoords);
  pos_.count = ve.count;
  pos_.finalize();
  nrm_ = pos_;
  nrm_.offset[0] = 12, nrm_.offset[1] = 16, nrm_.offset[2] = 20;
  nrm_.finalize();
  file_.advise_sequential(lines_.offset(), file_.size());
  released_ = lines_.offset();
  return Status::ok();
}

// The local origin (MeshHeader::origin) from an ASCII file's first vertex
// record; (0, 0, 0) if the record does not parse (load_ascii then reports it).
Vec3d PlyReader::first_vertex_origin(const PlyElement& ve, std::string_view line) const {
  double d[3] = {0, 0, 0};
  text::Tokens tok(line);
  std::string_view t;
  for (size_t k = 0; k < ve.props.size(); ++k) {
    if (!tok.next(t)) return Vec3d(0);
    if (ve.props[k].is_list) {
      int64_t n = 0;
      if (!text::parse_number(t, n) || n < 0) return Vec3d(0);
      for (int64_t j = 0; j < n; ++j)
        if (!tok.next(t)) return Vec3d(0);
      continue;
    }
    for (int c = 0; c < 3; ++c)
      if (coord_prop_[c] == int(k) && !text::parse_double(t, d[c])) return Vec3d(0);
  }
  return local_origin_for(Vec3d(d[0], d[1], d[2]));
}

StatusOr<std::unique_ptr<MeshReader>> PlyReader::open(const std::filesystem::path& path, ReaderOptions options) {
  auto r = std::make_unique<PlyReader>();
  r->path_ = path;
  r->options_ = options;
  if (r->options_.batch_triangles == 0) r->options_.batch_triangles = 1;
  RAYLOD_ASSIGN_OR_RETURN(r->file_, MappedFile::open(path));
  if (r->file_.size() == 0) return r->error("empty file");
  RAYLOD_RETURN_IF_ERROR(r->parse_header());
  RAYLOD_RETURN_IF_ERROR(r->check_elements());
  if (r->encoding_ == PlyEncoding::Ascii) {
    RAYLOD_RETURN_IF_ERROR(r->load_ascii());
  } else {
    RAYLOD_RETURN_IF_ERROR(r->locate_binary());
  }
  MeshHeader& h = r->header_;
  h.format = MeshFormat::Ply;
  h.encoding = r->encoding_ == PlyEncoding::Ascii ? "ascii"
               : r->encoding_ == PlyEncoding::BinaryLittle ? "binary_little_endian" : "binary_big_endian";
  h.vertex_count = r->elements_[r->vertex_el_].count;
  h.face_count = r->elements_[r->face_el_].count;
  h.has_normals = r->has_normals_;
  h.file_bytes = r->file_.size();
  return std::unique_ptr<MeshReader>(std::move(r));
}

// For a binary file whose face records read as nonsense: a header that
// declares the wrong number of vertices shifts every face record. If the
// file's size fits another vertex count exactly (every face a triangle, the
// faces the last element), say so; else nothing.
std::string PlyReader::vertex_count_hint() const {
  if (encoding_ == PlyEncoding::Ascii || face_el_ != int(elements_.size()) - 1) return "";
  const PlyElement& fe = elements_[size_t(face_el_)];
  const PlyElement& ve = elements_[size_t(vertex_el_)];
  if (fe.props.size() != 1 || !fe.props[0].is_list || ve.record_size == 0) return "";
  uint64_t fixed = data_offset_;  // the header and the other elements before the faces
  for (int i = 0; i < face_el_; ++i) {
    if (i == vertex_el_) continue;
    if (elements_[size_t(i)].record_size == 0 && !elements_[size_t(i)].props.empty()) return "";
    fixed += elements_[size_t(i)].count * elements_[size_t(i)].record_size;
  }
  const uint64_t triangle_bytes = scalar_size(fe.props[0].count_type) + 3 * scalar_size(fe.props[0].type);
  if (fe.count > (file_.size() - std::min<uint64_t>(fixed, file_.size())) / triangle_bytes) return "";
  const uint64_t vertex_bytes = file_.size() - fixed - fe.count * triangle_bytes;
  if (vertex_bytes % ve.record_size != 0 || vertex_bytes / ve.record_size == ve.count) return "";
  // Only if the face records, read after that many vertices, are polygons
  // that end exactly where the file does (a face with no corners in a file
  // whose counts are right fits the size test too).
  const size_t cs = scalar_size(fe.props[0].count_type), is = scalar_size(fe.props[0].type);
  size_t pos = size_t(fixed + vertex_bytes);
  for (uint64_t f = 0; f < fe.count; ++f) {
    if (pos + cs > file_.size()) return "";
    const int64_t n = load_integer(file_.data() + pos, fe.props[0].count_type, swap_);
    if (n < 3 || uint64_t(n) > (file_.size() - pos - cs) / is) return "";
    pos += cs + size_t(n) * is;
  }
  if (pos != file_.size()) return "";
  return "the header declares " + std::to_string(ve.count) + " vertices, but with " + std::to_string(fe.count) +
         " triangles the file's size fits " + std::to_string(vertex_bytes / ve.record_size) +
         ": is the header's vertex count wrong?";
}

Status PlyReader::corner_error(int64_t index, uint64_t face, uint64_t line) const {
  const std::string at = where(face, line) + ": ";
  if (index < 0 || uint64_t(index) >= pos_.count) {
    const std::string hint = vertex_count_hint();
    return error(at + "vertex index " + std::to_string(index) + " is out of range (" +
                 (hint.empty() ? "the file has " + std::to_string(pos_.count) + " vertices" : hint) + ")");
  }
  const std::string vertex = "vertex " + std::to_string(index);
  const Vec3 p = pos_.load(uint64_t(index));
  if (!is_finite(p)) {
    // A double property past the float range loads as inf: say what the file holds.
    const Vec3d exact = pos_.load_exact(uint64_t(index));
    if (beyond_float_range(exact))
      return error(at + vertex + " has a coordinate beyond the float range (about +-3.4e38) " + vec_text(exact));
    if (beyond_float_range(exact - pos_.origin))
      return error(at + vertex + " " + vec_text(exact) + " lies " + vec_text(exact - pos_.origin) +
                   " from the mesh's first vertex " + vec_text(pos_.origin) +
                   ": the mesh spans more than the float range (about 3.4e38)");
    return error(at + vertex + " has a non-finite coordinate " + vec_text(p));
  }
  const Vec3d exact = nrm_.load_exact(uint64_t(index));
  if (beyond_float_range(exact))
    return error(at + vertex + " has a normal component beyond the float range (about +-3.4e38) " + vec_text(exact));
  return error(at + vertex + " has a non-finite normal " + vec_text(nrm_.load(uint64_t(index))));
}

Status PlyReader::emit_polygon(const int64_t* index, size_t n, TriangleBatch& batch, uint64_t face, uint64_t line) {
  if (n < 3) {
    const std::string hint = vertex_count_hint();
    return error(where(face, line) + ": a face has " + std::to_string(n) + " corners; at least 3 are needed" +
                 (hint.empty() ? "" : " (" + hint + ")"));
  }
  poly_pos_.resize(n);
  if (has_normals_) poly_nrm_.resize(n);
  bool zero_normal = false;
  for (size_t k = 0; k < n; ++k) {
    const int64_t i = index[k];
    if (i < 0 || uint64_t(i) >= pos_.count) return corner_error(i, face, line);
    poly_pos_[k] = pos_.load(uint64_t(i));
    if (!is_finite(poly_pos_[k])) return corner_error(i, face, line);
    if (has_normals_) {
      poly_nrm_[k] = nrm_.load(uint64_t(i));
      if (!unit_normal(poly_nrm_[k])) {
        if (!is_zero(poly_nrm_[k])) return corner_error(i, face, line);
        zero_normal = true;  // replaced per triangle below
      }
    }
  }
  repaired_normals_ += append_polygon_fan(poly_pos_.data(), has_normals_ ? poly_nrm_.data() : nullptr, n, zero_normal,
                                          batch.positions, batch.normals);
  triangles_ += n - 2;
  return Status::ok();
}

void PlyReader::release_behind_cursor(size_t cursor) {
  constexpr size_t kChunk = size_t(1) << 22;  // release in 4 MiB steps
  if (cursor >= released_ + kChunk) {
    file_.release(released_, cursor);
    released_ = cursor & ~(size_t(4095));
  }
  // The binary vertex table is read at random, so it cannot be released
  // behind a cursor; instead its mapping is dropped after every 64 MiB of
  // face data, which bounds the resident part to the vertices one such
  // window touches (pages come back from the page cache on the next use).
  constexpr size_t kVertexWindow = size_t(1) << 26;
  if (encoding_ != PlyEncoding::Ascii && cursor >= vertex_window_start_ + kVertexWindow) {
    const size_t begin = size_t(pos_.base - file_.data());
    file_.release(begin, begin + pos_.stride * pos_.count);
    vertex_window_start_ = cursor;
  }
}

// The common layout: "list uchar int|uint vertex_indices" as the only face
// property, host byte order. Triangles are written straight into the batch
// (sized once; not cleared between calls, so nothing is zero-filled).
template <class IndexT, bool kPacked, bool kNormals>
StatusOr<bool> PlyReader::next_binary_fast(TriangleBatch& batch) {
  const uint8_t* data = file_.data();
  const size_t size = file_.size();
  const uint64_t face_count = elements_[face_el_].count;
  // Batch limit in corners; the buffers start at what the faces left fill as
  // triangles (so a huge limit on a small mesh does not zero-fill memory) and
  // grow when polygons need more.
  const size_t cap = 3 * options_.batch_triangles;
  const size_t initial = size_t(std::min<uint64_t>(cap, 3 * (face_count - faces_done_)));
  const uint64_t vcount = pos_.count;
  const uint8_t* vbase = pos_.base;
  const size_t stride = pos_.stride;
  const uint32_t po = pos_.offset[0], no = nrm_.offset[0];
  std::vector<Vec3>& P = batch.positions;
  std::vector<Vec3>& N = batch.normals;
  if (P.size() != initial) P.resize(initial);
  if (kNormals && N.size() != initial) N.resize(initial);
  if (!kNormals) N.clear();
  Vec3* pp = P.data();
  Vec3* np = N.data();
  size_t out = 0;
  size_t pos = cursor_;
  auto fail = [&](Status s) {
    batch.clear();
    return s;
  };
  while (faces_done_ < face_count && out < cap) {
    if (pos >= size) return fail(truncated_faces());
    const size_t n = data[pos];
    if (size - pos - 1 < 4 * n) return fail(truncated_faces());
    const uint8_t* q = data + pos + 1;
    if (n == 3) {
      if (out + 3 > P.size()) [[unlikely]] {
        P.resize(std::min(cap, 2 * P.size() + 3));
        if (kNormals) N.resize(P.size());
        pp = P.data();
        np = N.data();
      }
      IndexT raw[3];
      std::memcpy(raw, q, sizeof raw);
      if (int64_t(raw[0]) < 0 || uint64_t(raw[0]) >= vcount || int64_t(raw[1]) < 0 || uint64_t(raw[1]) >= vcount ||
          int64_t(raw[2]) < 0 || uint64_t(raw[2]) >= vcount) {
        for (IndexT r : raw)
          if (int64_t(r) < 0 || uint64_t(r) >= vcount) return fail(corner_error(int64_t(r), faces_done_, 0));
      }
      // Copy the corners straight into the batch, then validate them there:
      // one well-predicted branch per triangle on the common path.
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        const uint8_t* rec = vbase + uint64_t(raw[k]) * stride;
        Vec3& p = pp[out + size_t(k)];
        if constexpr (kPacked) std::memcpy(&p.x, rec + po, 12);
        else p = pos_.load(uint64_t(raw[k]));
        ok &= is_finite(p);
        if constexpr (kNormals) {
          Vec3& nn = np[out + size_t(k)];
          if constexpr (kPacked) std::memcpy(&nn.x, rec + no, 12);
          else nn = nrm_.load(uint64_t(raw[k]));
          const float l2 = nn.x * nn.x + nn.y * nn.y + nn.z * nn.z;
          ok &= l2 > 0.999999f && l2 < 1.000001f;
        }
      }
      if (!ok) {
        // Rare: non-finite data (an error), a non-unit normal (normalised) or
        // a zero-length one (replaced by the face normal).
        bool zero_normal = false;
        for (int k = 0; k < 3; ++k) {
          if (!is_finite(pp[out + size_t(k)])) return fail(corner_error(int64_t(raw[k]), faces_done_, 0));
          if (kNormals && !unit_normal(np[out + size_t(k)])) {
            if (!is_zero(np[out + size_t(k)])) return fail(corner_error(int64_t(raw[k]), faces_done_, 0));
            zero_normal = true;
          }
        }
        if (kNormals && zero_normal) repaired_normals_ += uint64_t(repair_zero_normals(pp + out, np + out));
      }
      out += 3;
      ++triangles_;
    } else {
      // Polygons (rare here) go through the generic emitter.
      poly_.resize(n);
      for (size_t k = 0; k < n; ++k) {
        IndexT raw;
        std::memcpy(&raw, q + 4 * k, 4);
        poly_[k] = int64_t(raw);
      }
      P.resize(out);
      if (kNormals) N.resize(out);
      if (Status s = emit_polygon(poly_.data(), n, batch, faces_done_, 0); !s) return fail(s);
      out = P.size();
      if (P.size() < initial) P.resize(initial);
      if (kNormals && N.size() < P.size()) N.resize(P.size());
      pp = P.data();
      np = N.data();
    }
    pos += 1 + 4 * n;
    ++faces_done_;
  }
  P.resize(out);
  if (kNormals) N.resize(out);
  cursor_ = pos;
  release_behind_cursor(pos);
  if (batch.size() > 0) return true;
  return end_of_faces();
}

StatusOr<bool> PlyReader::next_binary_generic(TriangleBatch& batch) {
  const PlyElement& fe = elements_[face_el_];
  const uint8_t* data = file_.data();
  const size_t size = file_.size();
  const size_t cap = options_.batch_triangles;
  size_t pos = cursor_;
  while (faces_done_ < fe.count && batch.positions.size() < 3 * cap) {
    size_t n = 0;
    for (size_t k = 0; k < fe.props.size(); ++k) {
      const PlyProperty& p = fe.props[k];
      if (!p.is_list) {
        pos += scalar_size(p.type);
        continue;
      }
      const size_t cs = scalar_size(p.count_type), is = scalar_size(p.type);
      if (pos + cs > size) return truncated_faces();
      const int64_t len = load_integer(data + pos, p.count_type, swap_);
      pos += cs;
      if (len < 0) return error("face " + std::to_string(faces_done_) + ": negative list length " + std::to_string(len));
      if (uint64_t(len) > (size - std::min(pos, size)) / is) return truncated_faces();
      if (int(k) == index_prop_) {
        n = size_t(len);
        poly_.resize(n);
        for (size_t j = 0; j < n; ++j) poly_[j] = load_integer(data + pos + j * is, p.type, swap_);
      }
      pos += size_t(len) * is;
    }
    if (pos > size) return truncated_faces();
    RAYLOD_RETURN_IF_ERROR(emit_polygon(poly_.data(), n, batch, faces_done_, 0));
    ++faces_done_;
  }
  cursor_ = pos;
  release_behind_cursor(pos);
  if (batch.size() > 0) return true;
  return end_of_faces();
}

StatusOr<bool> PlyReader::next_ascii(TriangleBatch& batch) {
  const PlyElement& fe = elements_[face_el_];
  const size_t cap = options_.batch_triangles;
  std::string_view line, t;
  while (faces_done_ < fe.count && batch.positions.size() < 3 * cap) {
    // load_ascii() already checked that enough non-blank lines exist.
    do {
      if (!lines_.next(line)) return truncated_faces();
    } while (text::Tokens(line).done());
    const uint64_t ln = lines_.line_number();
    auto bad = [&](const std::string& what) { return error("line " + std::to_string(ln) + ": " + what); };
    text::Tokens tok(line);
    size_t n = 0;
    for (size_t k = 0; k < fe.props.size(); ++k) {
      const PlyProperty& p = fe.props[k];
      if (!tok.next(t)) return bad("face has too few values for its header");
      if (!p.is_list) continue;
      int64_t len = 0;
      if (!text::parse_number(t, len) || len < 0) return bad("bad list length '" + std::string(text::clip(t)) + "'");
      if (len > largest_integer(p.count_type))
        return bad("list length " + std::to_string(len) + " does not fit the header's count type (largest " +
                   std::to_string(largest_integer(p.count_type)) + ")");
      // Each value takes at least 2 characters: a bound before allocating.
      if (uint64_t(len) > tok.rest.size() / 2 + 1)
        return bad("face has fewer indices than its list length " + std::to_string(len));
      if (int(k) == index_prop_) {
        n = size_t(len);
        poly_.resize(n);
      }
      for (int64_t j = 0; j < len; ++j) {
        if (!tok.next(t)) return bad("face has fewer indices than its list length " + std::to_string(len));
        if (int(k) == index_prop_ && !text::parse_number(t, poly_[size_t(j)]))
          return bad("vertex index '" + std::string(text::clip(t)) + "' is not an integer");
      }
    }
    if (!tok.done()) return bad("face has more values than its header declares");
    RAYLOD_RETURN_IF_ERROR(emit_polygon(poly_.data(), n, batch, faces_done_, ln));
    ++faces_done_;
  }
  release_behind_cursor(lines_.offset());
  if (batch.size() > 0) return true;
  return end_of_faces();
}

Status PlyReader::finish_binary() {
  size_t pos = cursor_;
  for (size_t i = size_t(face_el_) + 1; i < elements_.size(); ++i) {
    RAYLOD_RETURN_IF_ERROR(skip_binary_element(elements_[i], pos));
  }
  if (pos < file_.size())
    return error(std::to_string(file_.size() - pos) +
                 " bytes of unexpected data after the last element (wrong element count in the header?)");
  return Status::ok();
}

StatusOr<bool> PlyReader::end_of_faces() {
  if (!done_) {
    done_ = true;
    if (encoding_ != PlyEncoding::Ascii) RAYLOD_RETURN_IF_ERROR(finish_binary());
    if (triangles_ == 0) return error("empty mesh: no triangles");
    warn_repaired_normals();
  }
  return false;
}

StatusOr<bool> PlyReader::next(TriangleBatch& batch) {
  if (done_) {
    batch.clear();
    return false;
  }
  if (fast_ == 1) return dispatch_fast<int32_t>(batch);
  if (fast_ == 2) return dispatch_fast<uint32_t>(batch);
  batch.clear();
  batch.positions.reserve(3 * options_.batch_triangles);
  if (has_normals_) batch.normals.reserve(3 * options_.batch_triangles);
  StatusOr<bool> r = encoding_ == PlyEncoding::Ascii ? next_ascii(batch) : next_binary_generic(batch);
  if (!r.is_ok()) batch.clear();
  return r;
}

}  // namespace

StatusOr<std::unique_ptr<MeshReader>> open_ply_reader(const std::filesystem::path& path, ReaderOptions options) {
  return PlyReader::open(path, options);
}

}  // namespace raylod
