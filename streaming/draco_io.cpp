// Draco (.drc) encode and decode of indexed triangle meshes with positions
// and optional vertex normals, through the Draco C++ API (draco::Mesh with
// point attributes, draco::Encoder, draco::Decoder).
//
// Quantisation: Draco quantises each position component to `bits` over the
// largest side of the bounding box (range), so a coordinate moves by at most
// half a step, range / (2^bits - 1) / 2, plus float rounding in the encoder's
// subtraction and the decoder's multiply-add. position_bits is chosen as the
// smallest value whose 3D bound meets the requested error. Normals use
// Draco's octahedral quantisation: a normal is a point on a 2D grid with
// 2^bits - 2 steps over [-1, 1]; half a diagonal step, stretched by at most
// sqrt(3) when the octahedron is projected onto the sphere, bounds the angle.
#include "streaming/draco_io.h"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <unordered_map>

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/compression/point_cloud/point_cloud_decoder.h>
#include <draco/core/varint_decoding.h>
#include <draco/metadata/metadata_decoder.h>
#include <draco/mesh/mesh.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include "core/fault_point.h"
#include "core/ordered_pipeline.h"
#include "core/parallelism.h"
#include "core/system.h"
#include "streaming/distinct_keys.h"
#include "streaming/mesh_reader.h"

namespace raylod {
namespace {

constexpr int kMaxDracoBits = 30;

}  // namespace

double normal_error_bound(int bits) {
  if (bits <= 1) return M_PI;
  const double step = 2.0 / double((uint64_t(1) << bits) - 2);
  return std::min(M_PI, std::sqrt(3.0) * std::sqrt(2.0) * step);  // generous: half-diagonal x 2
}

int choose_normal_bits(double max_error) {
  for (int bits = 2; bits < kMaxNormalBits; ++bits)
    if (normal_error_bound(bits) <= max_error) return bits;
  return kMaxNormalBits;
}

namespace {

Status check_mesh(const std::filesystem::path& path, const IndexedMesh& mesh) {
  const std::string where = path.string() + ": ";
  if (mesh.indices.size() % 3 != 0) return Status::error(where + "index count is not a multiple of 3");
  if (mesh.triangle_count() == 0) return Status::error(where + "the mesh has no triangles to write");
  if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
    return Status::error(where + "normals do not match positions (" + std::to_string(mesh.normals.size()) + " vs " +
                         std::to_string(mesh.positions.size()) + ")");
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    if (!is_finite(mesh.positions[i]) || (!mesh.normals.empty() && !is_finite(mesh.normals[i])))
      return Status::error(where + "vertex " + std::to_string(i) + " is not finite");
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const uint32_t* f = &mesh.indices[3 * t];
    for (int k = 0; k < 3; ++k)
      if (f[k] >= mesh.positions.size())
        return Status::error(where + "triangle " + std::to_string(t) + " has index " + std::to_string(f[k]) +
                             " out of range");
    const Vec3 &a = mesh.positions[f[0]], &b = mesh.positions[f[1]], &c = mesh.positions[f[2]];
    // Draco merges equal positions and then drops faces with a repeated
    // corner; such a face would silently change the triangle count.
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2] || a == b || b == c || a == c)
      return Status::error(where + "triangle " + std::to_string(t) +
                           " is degenerate (repeated corner); remove degenerate triangles before encoding");
  }
  return Status::ok();
}

}  // namespace

double position_error_bound(double extent, double max_abs, int bits) {
  bits = std::clamp(bits, 1, kMaxDracoBits);
  const double step = extent / double((uint64_t(1) << bits) - 1);
  return std::sqrt(3.0) * (0.5 * step + 0x1p-23 * (extent + max_abs));
}

int choose_position_bits(double extent, double max_abs, double max_error) {
  for (int bits = 1; bits <= kMaxDracoBits; ++bits)
    if (position_error_bound(extent, max_abs, bits) <= max_error) return bits;
  // Unreachable: the float rounding of the decoded positions dominates, and
  // more bits buy nothing but encoder memory (Draco's tables grow with the
  // quantisation range: 30 bits took 4.7 GB on a 255k-triangle mesh). Take
  // the fewest bits within 10% of the best achievable bound.
  const double best = position_error_bound(extent, max_abs, kMaxDracoBits);
  for (int bits = 1; bits <= kMaxDracoBits; ++bits)
    if (position_error_bound(extent, max_abs, bits) <= 1.1 * best) return bits;
  return kMaxDracoBits;
}

// The geometry metadata entry holding IndexedMesh::origin.
constexpr const char* kOriginEntry = "raylod_origin";
// The entry holding the triangle count, so that a reader can size its memory
// from the header alone (draco_triangle_count) instead of decoding twice.
constexpr const char* kTrianglesEntry = "raylod_triangles";

namespace {

// Bit-identical values become one attribute value, and vertices with the
// same values one point, so that edgebreaker sees the connectivity across
// normal seams (better prediction, smaller file). This is what Draco's
// DeduplicateAttributeValues and DeduplicatePointIds do, in the same
// first-use order, but with one flat hash table instead of a node-based
// map per attribute (writing 9.4M triangles: 12.2 s before, 5.8 s after).
void fill_draco_mesh(const IndexedMesh& mesh, draco::Mesh& dm, int& position_id, int& normal_id) {
  const bool normals = !mesh.normals.empty();
  const uint32_t n = uint32_t(mesh.positions.size());
  auto bits_of = [](const Vec3& v) {
    std::array<uint32_t, 3> k;
    std::memcpy(k.data(), &v.x, 12);
    return k;
  };
  std::vector<uint32_t> position_values, position_of, normal_values, normal_of, point_of;
  // Distinct positions and distinct normals, side by side.
  tbb::parallel_invoke(
      [&] {
        std::vector<uint32_t> slots;
        index_distinct_keys<3>(n, [&](size_t i) { return bits_of(mesh.positions[i]); }, slots, position_values,
                               position_of);
      },
      [&] {
        if (!normals) return;
        std::vector<uint32_t> slots;
        index_distinct_keys<3>(n, [&](size_t i) { return bits_of(mesh.normals[i]); }, slots, normal_values, normal_of);
      });
  uint32_t points = 0;
  if (normals) {
    // Distinct (position, normal) pairs in first-use order, as
    // index_distinct_keys would number them: a vertex whose position no other
    // vertex has is a point of its own, so only shared positions are hashed.
    std::vector<uint8_t> shared(position_values.size() / 3, 0);
    for (uint32_t i = 0; i < n; ++i) shared[position_of[i]] = uint8_t(std::min(shared[position_of[i]] + 1, 2));
    std::unordered_map<uint64_t, uint32_t> pair_point;
    point_of.resize(n);
    for (uint32_t i = 0; i < n; ++i) {
      if (shared[position_of[i]] < 2) {
        point_of[i] = points++;
        continue;
      }
      const auto [it, added] = pair_point.try_emplace(uint64_t(position_of[i]) << 32 | normal_of[i], points);
      point_of[i] = it->second;
      points += added;
    }
  } else {
    point_of = position_of;
    points = uint32_t(position_values.size() / 3);
  }
  // Each point's vertex (the first vertex that gave it).
  std::vector<uint32_t> vertex_of_point(points, 0);
  for (uint32_t i = n; i-- > 0;) vertex_of_point[point_of[i]] = i;

  dm.set_num_points(points);
  // An attribute of `values` distinct values (3 words each): identity-mapped
  // when there are as many as points, as Draco leaves an attribute whose
  // values were all distinct.
  auto add_attribute = [&](draco::GeometryAttribute::Type type, const std::vector<uint32_t>& values,
                           const std::vector<uint32_t>& value_of) {
    const uint32_t count = uint32_t(values.size() / 3);
    draco::GeometryAttribute att;
    att.Init(type, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
    const int id = dm.AddAttribute(att, count == points, count);
    draco::PointAttribute* pa = dm.attribute(id);
    for (uint32_t v = 0; v < count; ++v) pa->SetAttributeValue(draco::AttributeValueIndex(v), &values[3 * size_t(v)]);
    if (count != points)
      for (uint32_t p = 0; p < points; ++p)
        pa->SetPointMapEntry(draco::PointIndex(p), draco::AttributeValueIndex(value_of[vertex_of_point[p]]));
    return int(pa->unique_id());
  };
  position_id = add_attribute(draco::GeometryAttribute::POSITION, position_values, position_of);
  if (normals) normal_id = add_attribute(draco::GeometryAttribute::NORMAL, normal_values, normal_of);
  dm.SetNumFaces(mesh.triangle_count());
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    draco::Mesh::Face f;
    for (int k = 0; k < 3; ++k) f[k] = draco::PointIndex(point_of[mesh.indices[3 * t + k]]);
    dm.SetFace(draco::FaceIndex(uint32_t(t)), f);
  }
}

// `release`, if given, is `mesh` itself: its arrays are freed once Draco's
// mesh holds a copy, before the encoder's own tables are allocated.
// The quantisation of a part file's parts: the whole mesh's grid, as Draco
// computes it for one mesh (AttributeQuantizationTransform: the per-axis
// float minimum, and the largest float extent, 1 if that is 0).
struct ExplicitGrid {
  float origin[3];
  float range;
};
ExplicitGrid whole_mesh_grid(const IndexedMesh& mesh) {
  Vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
  for (const Vec3& p : mesh.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  ExplicitGrid g{{lo.x, lo.y, lo.z}, 0.f};
  for (int a = 0; a < 3; ++a) g.range = std::max(g.range, hi[a] - lo[a]);
  if (g.range == 0.f) g.range = 1.f;
  return g;
}

// The position quantisation of a mesh: its bits, the error they were chosen
// for and the bound they give (DracoWriteReport's fields).
struct PositionPlan {
  int bits = 0;
  double requested_error = 0, max_error = 0;
};
StatusOr<PositionPlan> plan_positions(const std::filesystem::path& path, const IndexedMesh& mesh,
                                      const DracoOptions& options) {
  Bbox box;
  double max_abs = 0;
  for (const Vec3& p : mesh.positions) {
    box.expand(p);
    max_abs = std::max({max_abs, double(std::abs(p.x)), double(std::abs(p.y)), double(std::abs(p.z))});
  }
  const double extent = std::max({box.extent().x, box.extent().y, box.extent().z});
  // Draco takes max - min in float as its quantisation range; past the float
  // range that is inf and the encoder crashes instead of failing.
  if (!(extent <= double(std::numeric_limits<float>::max()))) {
    char what[120];
    std::snprintf(what, sizeof what, ": the mesh spans %g, more than the float range (about 3.4e38) Draco quantises over", extent);
    return Status::error(path.string() + what);
  }
  PositionPlan plan;
  if (options.position_bits > 0) {
    if (options.position_bits > kMaxDracoBits)
      return Status::error(path.string() + ": position_bits " + std::to_string(options.position_bits) +
                           " is over Draco's limit of 30");
    plan.bits = options.position_bits;
  } else {
    // Without a target, keep the error a millionth of the mesh size.
    plan.requested_error = options.max_position_error > 0 ? options.max_position_error : 1e-6 * std::max(extent, 1e-30);
    plan.bits = choose_position_bits(extent, max_abs, plan.requested_error);
  }
  plan.max_error = position_error_bound(extent, max_abs, plan.bits);
  return plan;
}

// A part file's parts share the whole mesh's quantisation: its grid, bits and bounds.
struct WholeMeshQuantisation {
  ExplicitGrid grid;
  PositionPlan plan;
};

// Encodes one Draco bitstream. `whole`, for a part of a part file, is the
// whole mesh's quantisation (the whole mesh was checked; the part is not
// checked again).
StatusOr<DracoEncoded> encode_draco_mesh(const std::filesystem::path& path, const IndexedMesh& mesh,
                                          const DracoOptions& options, IndexedMesh* release,
                                          const WholeMeshQuantisation* whole = nullptr) {
  if (!whole) RAYLOD_RETURN_IF_ERROR(check_mesh(path, mesh));
  const bool normals = !mesh.normals.empty();
  PositionPlan plan;
  if (whole) {
    plan = whole->plan;
  } else {
    RAYLOD_ASSIGN_OR_RETURN(plan, plan_positions(path, mesh, options));
  }
  DracoEncoded encoded;
  DracoWriteReport& report = encoded.report;
  report.position_bits = plan.bits;
  report.requested_position_error = plan.requested_error;
  report.max_position_error = plan.max_error;
  if (normals) {
    if (options.normal_bits == 0) {
      if (!(options.max_normal_error > 0))
        return Status::error(path.string() + ": normal_bits 0 needs a positive max_normal_error");
      report.normal_bits = choose_normal_bits(options.max_normal_error);
    } else {
      if (options.normal_bits < 2 || options.normal_bits > kMaxNormalBits)
        return Status::error(path.string() + ": normal_bits must be between 2 and " + std::to_string(kMaxNormalBits));
      report.normal_bits = options.normal_bits;
    }
    report.max_normal_error = normal_error_bound(report.normal_bits);
  }

  draco::Mesh dm;
  fill_draco_mesh(mesh, dm, encoded.position_id, encoded.normal_id);  // its tables are freed before encoding

  {
    auto metadata = std::make_unique<draco::GeometryMetadata>();
    if (mesh.origin != Vec3d(0))
      metadata->AddEntryDoubleArray(kOriginEntry, {mesh.origin.x, mesh.origin.y, mesh.origin.z});
    metadata->AddEntryDouble(kTrianglesEntry, double(dm.num_faces()));  // exact below 2^53
    dm.AddMetadata(std::move(metadata));
  }
  if (release) *release = IndexedMesh{};

  draco::Encoder encoder;
  if (whole)
    encoder.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION, report.position_bits, 3,
                                             whole->grid.origin, whole->grid.range);
  else
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, report.position_bits);
  if (normals) encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, report.normal_bits);
  const int speed = std::clamp(options.speed, 0, 10);
  encoder.SetSpeedOptions(speed, speed);
  draco::EncoderBuffer buffer;
  const draco::Status st = encoder.EncodeMeshToBuffer(dm, &buffer);
  if (!st.ok()) return Status::error(path.string() + ": Draco encoding failed: " + st.error_msg_string());
  encoded.bytes.assign(buffer.data(), buffer.data() + buffer.size());
  report.bytes = buffer.size();
  return encoded;
}

void put_le(std::vector<char>& out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(char((v >> (8 * i)) & 0xff));
}
uint64_t get_le(const char* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= uint64_t(uint8_t(p[i])) << (8 * i);
  return v;
}
constexpr size_t kPartsHeaderBytes = 16, kPartEntryBytes = 16;

// A part file (draco_io.h): the triangles [t0, t1) of each part with the
// vertices they use, encoded in parallel on the whole mesh's grid. The
// position bits are chosen for the whole mesh (its extent and error bound),
// so every part reports the same bounds.
StatusOr<DracoEncoded> encode_draco_parts(const std::filesystem::path& path, const IndexedMesh& mesh,
                                           const DracoOptions& options, IndexedMesh* release) {
  RAYLOD_RETURN_IF_ERROR(check_mesh(path, mesh));
  const size_t triangles = mesh.triangle_count();
  const size_t parts = std::clamp<size_t>(size_t(std::max(options.parts, 1)), 1, std::max<size_t>(triangles, 1));
  // The whole mesh's grid, bits and bounds (a part's own extent is smaller).
  WholeMeshQuantisation whole{whole_mesh_grid(mesh), {}};
  RAYLOD_ASSIGN_OR_RETURN(whole.plan, plan_positions(path, mesh, options));
  std::vector<StatusOr<DracoEncoded>> encoded(parts, Status::error("not encoded"));
  tbb::parallel_for(size_t(0), parts, [&](size_t p) {
    const size_t t0 = triangles * p / parts, t1 = triangles * (p + 1) / parts;
    IndexedMesh part;
    part.origin = mesh.origin;
    std::unordered_map<uint32_t, uint32_t> local;
    local.reserve(2 * (t1 - t0));
    part.indices.reserve(3 * (t1 - t0));
    for (size_t c = 3 * t0; c < 3 * t1; ++c) {
      const uint32_t v = mesh.indices[c];
      const auto [it, added] = local.try_emplace(v, uint32_t(part.positions.size()));
      if (added) {
        part.positions.push_back(mesh.positions[v]);
        if (!mesh.normals.empty()) part.normals.push_back(mesh.normals[v]);
      }
      part.indices.push_back(it->second);
    }
    std::unordered_map<uint32_t, uint32_t>().swap(local);
    encoded[p] = encode_draco_mesh(path, part, options, &part, &whole);
  });
  for (auto& e : encoded) RAYLOD_RETURN_IF_ERROR(e.status());  // the first failing part's error
  if (release) *release = IndexedMesh{};
  DracoEncoded out;
  out.report = encoded[0]->report;  // every part's: the whole mesh's bounds
  out.position_id = encoded[0]->position_id;
  out.normal_id = encoded[0]->normal_id;
  size_t total = kPartsHeaderBytes + kPartEntryBytes * parts;
  for (const auto& e : encoded) total += e->bytes.size();
  out.bytes.reserve(total);
  out.bytes.insert(out.bytes.end(), kDracoPartsMagic, kDracoPartsMagic + 8);
  put_le(out.bytes, 1, 4);
  put_le(out.bytes, parts, 4);
  for (size_t p = 0; p < parts; ++p) {
    put_le(out.bytes, encoded[p]->bytes.size(), 8);
    put_le(out.bytes, triangles * (p + 1) / parts - triangles * p / parts, 8);
  }
  for (auto& e : encoded) {
    out.bytes.insert(out.bytes.end(), e->bytes.begin(), e->bytes.end());
    std::vector<char>().swap(e->bytes);
  }
  out.report.bytes = out.bytes.size();
  return out;
}

}  // namespace

namespace {

// Draco quantises the three axes on one grid over the largest side, and
// the float rounding of coordinates far from zero (2^-23 of their size)
// sets how fine that grid can usefully be, for every axis: a float sphere of
// radius 1 at x = 1e7 (a mesh read from a float file keeps its coordinates,
// MeshHeader::origin) got 4 bits, its positions 2.18 off where y and z held
// 1e-7. A mesh whose centre lies kLocalOriginThreshold or more from its
// origin is encoded relative to a local origin there (an integer point):
// float coordinates minus it are exact, and the grid then follows the mesh's
// own size.
Vec3d local_shift(const IndexedMesh& mesh) {
  if (mesh.positions.empty()) return Vec3d(0);
  Vec3 lo = mesh.positions[0], hi = lo;
  for (const Vec3& p : mesh.positions) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  return local_origin_for(0.5 * (Vec3d(lo) + Vec3d(hi)));
}

void shift_positions(IndexedMesh& mesh, const Vec3d& shift) {
  for (Vec3& p : mesh.positions) p = Vec3(Vec3d(p) - shift);
  mesh.origin += shift;
}

}  // namespace

StatusOr<DracoEncoded> encode_draco(const std::filesystem::path& path, const IndexedMesh& mesh,
                                     const DracoOptions& options) {
  // Draco's symbol coder sizes a histogram by the largest symbol on every
  // call (ComputeShannonEntropy: 128 MiB at 25 position bits), a fresh
  // mapping each time that faults in page by page: kept by the allocator
  // meanwhile, those pages are touched once.
  const ScopedKeptFreeMemory keep;
  if (const Vec3d shift = local_shift(mesh); shift != Vec3d(0)) {
    IndexedMesh near = mesh;
    shift_positions(near, shift);
    return encode_draco(path, std::move(near), options);
  }
  if (options.parts > 1) return encode_draco_parts(path, mesh, options, nullptr);
  return encode_draco_mesh(path, mesh, options, nullptr);
}

StatusOr<DracoEncoded> encode_draco(const std::filesystem::path& path, IndexedMesh&& mesh,
                                     const DracoOptions& options) {
  const ScopedKeptFreeMemory keep;  // as above
  shift_positions(mesh, local_shift(mesh));
  if (options.parts > 1) return encode_draco_parts(path, mesh, options, &mesh);
  return encode_draco_mesh(path, mesh, options, &mesh);
}

namespace {

bool is_part_file(const char* data, size_t size) { return size >= 8 && std::memcmp(data, kDracoPartsMagic, 8) == 0; }

// A part file's table (its first bytes, `size` of them, suffice): each
// part's Draco bytes and triangles.
struct PartEntry {
  uint64_t bytes = 0, triangles = 0;
};
StatusOr<std::vector<PartEntry>> read_part_table(const char* data, size_t size, const std::string& where) {
  if (size < kPartsHeaderBytes) return Status::error(where + "part file header is truncated");
  const uint64_t version = get_le(data + 8, 4), parts = get_le(data + 12, 4);
  if (version != 1) return Status::error(where + "part file version " + std::to_string(version) + ", this raylod reads 1");
  if (parts == 0 || parts > 256) return Status::error(where + "part file names " + std::to_string(parts) + " parts (1 to 256)");
  if (size < kPartsHeaderBytes + kPartEntryBytes * parts) return Status::error(where + "part table is truncated");
  std::vector<PartEntry> table(parts);
  for (uint64_t p = 0; p < parts; ++p) {
    const char* entry = data + kPartsHeaderBytes + kPartEntryBytes * p;
    table[p] = {get_le(entry, 8), get_le(entry + 8, 8)};
  }
  return table;
}

uint64_t total_triangles(std::span<const PartEntry> table) {
  uint64_t n = 0;
  for (const PartEntry& e : table) n += e.triangles;
  return n;
}

// A whole part file: its table and each part's Draco bytes, checked to
// fill the file exactly.
struct PartFile {
  std::vector<PartEntry> table;
  std::vector<std::span<const char>> parts;
};
StatusOr<PartFile> split_part_file(const char* data, size_t size, const std::string& where) {
  PartFile file;
  RAYLOD_ASSIGN_OR_RETURN(file.table, read_part_table(data, size, where));
  uint64_t offset = kPartsHeaderBytes + kPartEntryBytes * file.table.size();
  for (size_t p = 0; p < file.table.size(); ++p) {
    if (file.table[p].bytes > size - offset)
      return Status::error(where + "part " + std::to_string(p) + " of " + std::to_string(file.table.size()) +
                           " runs past the end of the file");
    file.parts.emplace_back(data + offset, size_t(file.table[p].bytes));
    offset += file.table[p].bytes;
  }
  if (offset != size) return Status::error(where + std::to_string(size - offset) + " bytes after the last part");
  return file;
}

}  // namespace

StatusOr<std::vector<std::span<const char>>> draco_parts(const char* data, size_t size, const std::string& name) {
  if (!is_part_file(data, size)) return std::vector<std::span<const char>>{std::span<const char>(data, size)};
  RAYLOD_ASSIGN_OR_RETURN(PartFile file, split_part_file(data, size, name + ": "));
  return std::move(file.parts);
}

namespace {

Status write_encoded(const std::filesystem::path& path, const std::vector<char>& buffer) {
  AtomicOutput out(path);
  // In two halves, with a fault point between them (core/fault_point.h).
  const size_t half = buffer.size() / 2;
  RAYLOD_RETURN_IF_ERROR(write_temporary(
      out, {std::string_view(buffer.data(), half), std::string_view(buffer.data() + half, buffer.size() - half)},
      [](size_t) { fault_point("draco.partial"); }));
  return out.commit();
}

}  // namespace

StatusOr<DracoWriteReport> write_draco(const std::filesystem::path& path, const IndexedMesh& mesh,
                                       const DracoOptions& options) {
  RAYLOD_ASSIGN_OR_RETURN(DracoEncoded encoded, encode_draco(path, mesh, options));
  RAYLOD_RETURN_IF_ERROR(write_encoded(path, encoded.bytes));
  return encoded.report;
}

StatusOr<DracoWriteReport> write_draco(const std::filesystem::path& path, IndexedMesh&& mesh,
                                       const DracoOptions& options) {
  RAYLOD_ASSIGN_OR_RETURN(DracoEncoded encoded, encode_draco(path, std::move(mesh), options));
  RAYLOD_RETURN_IF_ERROR(write_encoded(path, encoded.bytes));
  return encoded.report;
}

StatusOr<IndexedMesh> read_draco(const std::filesystem::path& path) {
  const std::string where = path.string() + ": ";
  std::ifstream f(path, std::ios::binary | std::ios::ate);
  if (!f) return Status::error(where + "cannot open file");
  std::vector<char> data(size_t(std::max<std::streamoff>(0, f.tellg())));
  f.seekg(0);
  if (!f.read(data.data(), std::streamsize(data.size()))) return Status::error(where + "read failed");
  if (is_part_file(data.data(), data.size())) {
    // Parts decoded in parallel and appended in order, a few in flight, so
    // that the parts and the whole mesh are not all held at once.
    RAYLOD_ASSIGN_OR_RETURN(const PartFile file, split_part_file(data.data(), data.size(), where));
    const std::vector<std::span<const char>>& parts = file.parts;
    const uint64_t triangles = total_triangles(file.table);
    IndexedMesh mesh;
    // The table's count, checked below, bounded here by what the bytes can
    // hold (edgebreaker needs more than a bit per triangle): a damaged table
    // must not reserve terabytes.
    mesh.indices.reserve(size_t(3 * std::min<uint64_t>(triangles, 8 * uint64_t(data.size()))));
    const size_t ntokens = std::clamp<size_t>(size_t(ambient_parallelism()) + 1, 2, 8);
    RAYLOD_RETURN_IF_ERROR(ordered_pipeline<IndexedMesh>(
        parts.size(), ntokens,
        [&](IndexedMesh& part, size_t p) -> Status {
          RAYLOD_ASSIGN_OR_RETURN(part, decode_draco(parts[p].data(), parts[p].size(),
                                                     path.string() + " (part " + std::to_string(p + 1) + ")"));
          return Status::ok();
        },
        [&](IndexedMesh& d, size_t p) -> Status {
          if (p == 0) {
            mesh.origin = d.origin;
            const size_t vertices = size_t(double(d.positions.size()) * double(parts.size()) * 1.05);
            mesh.positions.reserve(vertices);
            if (!d.normals.empty()) mesh.normals.reserve(vertices);
          } else if (d.origin != mesh.origin) {
            return Status::error(where + "parts disagree on the mesh origin");
          } else if (d.normals.empty() != mesh.normals.empty()) {
            return Status::error(where + "parts disagree on having normals");
          }
          const uint32_t base = uint32_t(mesh.positions.size());
          if (uint64_t(base) + d.positions.size() >= uint64_t(UINT32_MAX))
            return Status::error(where + "more than 2^32 vertices");
          mesh.positions.insert(mesh.positions.end(), d.positions.begin(), d.positions.end());
          mesh.normals.insert(mesh.normals.end(), d.normals.begin(), d.normals.end());
          for (uint32_t v : d.indices) mesh.indices.push_back(base + v);
          d = IndexedMesh{};
          return Status::ok();
        }));
    if (mesh.triangle_count() != triangles)
      return Status::error(where + "the parts hold " + std::to_string(mesh.triangle_count()) + " triangles, the part table " +
                           std::to_string(triangles));
    return mesh;
  }
  if (data.size() < 5 || std::memcmp(data.data(), "DRACO", 5) != 0)
    return Status::error(where + "not a Draco file (no DRACO header)");
  return decode_draco(data.data(), data.size(), path.string());
}

StatusOr<uint64_t> draco_triangle_count(const std::filesystem::path& path) {
  {
    // The header and the metadata come first; raylod's own files fit in far
    // less than this.
    RAYLOD_RETURN_IF_ERROR(check_regular_file(path));  // a FIFO or device fails at once
    std::ifstream f(path, std::ios::binary);
    if (!f) return Status::error(path.string() + ": cannot open file");
    std::vector<char> head(64 << 10);
    f.read(head.data(), std::streamsize(head.size()));
    head.resize(size_t(f.gcount()));
    if (is_part_file(head.data(), head.size())) {
      // A part file: the triangle counts are in its table (256 parts at most
      // fit the head); a damaged table is reported by the decode below.
      if (auto table = read_part_table(head.data(), head.size(), path.string() + ": "); table.is_ok())
        return total_triangles(*table);
    }
    draco::DecoderBuffer buffer;
    buffer.Init(head.data(), head.size());
    draco::DracoHeader header;
    if (draco::PointCloudDecoder::DecodeHeader(&buffer, &header).ok() && (header.flags & METADATA_FLAG_MASK) &&
        DRACO_BITSTREAM_VERSION(header.version_major, header.version_minor) >= DRACO_BITSTREAM_VERSION(1, 3)) {
      buffer.set_bitstream_version(DRACO_BITSTREAM_VERSION(header.version_major, header.version_minor));
      draco::GeometryMetadata metadata;
      draco::MetadataDecoder decoder;
      double n = -1;
      if (decoder.DecodeGeometryMetadata(&buffer, &metadata) && metadata.GetEntryDouble(kTrianglesEntry, &n) &&
          n >= 0 && n <= 9007199254740992.0 && n == std::floor(n))
        return uint64_t(n);
    }
  }
  RAYLOD_ASSIGN_OR_RETURN(IndexedMesh mesh, read_draco(path));  // a file from elsewhere: count by decoding
  return mesh.triangle_count();
}

// The counts read as Draco 2.2 reads them (what Draco and raylod write;
// other 2.x versions are left to Draco): the header, the metadata, then the
// edgebreaker or sequential connectivity's counts. Real files take bits a
// triangle (raylod's, 5 to 8 bytes); kDracoCountsPerByte would be 0.03 bits.
Status check_draco_counts(const char* data, size_t size, const std::string& where) {
  draco::DecoderBuffer buffer;
  buffer.Init(data, size);
  draco::DracoHeader header;
  if (!draco::PointCloudDecoder::DecodeHeader(&buffer, &header).ok()) return Status::ok();
  // Bitstreams before version 2 give their vertex and face counts as raw
  // 32-bit numbers, which Draco's decoder allocates for before it reads any
  // connectivity: 22 bytes made it allocate 3 GB (found by fuzz_draco).
  // Draco has written 2.x since 2017, as raylod does; older ones are refused.
  if (header.version_major < 2)
    return Status::error(where + "Draco bitstream version " + std::to_string(header.version_major) + "." +
                         std::to_string(header.version_minor) + " is not read (raylod reads version 2 and later)");
  const uint16_t version = DRACO_BITSTREAM_VERSION(header.version_major, header.version_minor);
  if (header.encoder_type != draco::TRIANGULAR_MESH || version != DRACO_BITSTREAM_VERSION(2, 2)) return Status::ok();
  buffer.set_bitstream_version(version);
  if (header.flags & METADATA_FLAG_MASK) {
    draco::GeometryMetadata metadata;
    draco::MetadataDecoder decoder;
    if (!decoder.DecodeGeometryMetadata(&buffer, &metadata)) return Status::ok();
  }
  uint64_t faces = 0, vertices = 0;
  if (header.encoder_method == draco::MESH_EDGEBREAKER_ENCODING) {
    uint8_t traversal = 0, attribute_data = 0;
    uint32_t encoded_vertices = 0, encoded_faces = 0, symbols = 0, split_symbols = 0;
    if (!buffer.Decode(&traversal) || !draco::DecodeVarint(&encoded_vertices, &buffer) ||
        !draco::DecodeVarint(&encoded_faces, &buffer) || !buffer.Decode(&attribute_data) ||
        !draco::DecodeVarint(&symbols, &buffer) || !draco::DecodeVarint(&split_symbols, &buffer))
      return Status::ok();
    faces = encoded_faces;
    vertices = uint64_t(encoded_vertices) + split_symbols;
    if (encoded_vertices > 3 * faces)
      return Status::error(where + "the Draco header claims " + std::to_string(encoded_vertices) + " vertices for " +
                           std::to_string(faces) + " triangles (at most three a triangle)");
  } else if (header.encoder_method == draco::MESH_SEQUENTIAL_ENCODING) {
    uint32_t encoded_faces = 0, points = 0;
    if (!draco::DecodeVarint(&encoded_faces, &buffer) || !draco::DecodeVarint(&points, &buffer)) return Status::ok();
    faces = encoded_faces;
    vertices = points;
  }
  const uint64_t most = kDracoCountFloor + kDracoCountsPerByte * uint64_t(size);
  if (faces > most || vertices > most)
    return Status::error(where + "the Draco header claims " + std::to_string(faces) + " triangles and " +
                         std::to_string(vertices) + " vertices in " + std::to_string(size) +
                         " bytes, more than raylod reads from a file of that size (" + std::to_string(kDracoCountFloor) +
                         " and " + std::to_string(kDracoCountsPerByte) + " a byte)");
  return Status::ok();
}

bool draco_attribute_holds_numbers(const draco::PointAttribute& attribute) {
  const draco::DataType t = attribute.data_type();
  return t != draco::DT_BOOL && t != draco::DT_INVALID && t < draco::DT_TYPES_COUNT;
}

StatusOr<IndexedMesh> decode_draco(const char* data, size_t size, const std::string& name) {
  const std::string where = name + ": ";
  RAYLOD_RETURN_IF_ERROR(check_draco_counts(data, size, where));
  draco::DecoderBuffer buffer;
  buffer.Init(data, size);
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) return Status::error(where + "Draco decoding failed: " + decoded.status().error_msg_string());
  std::unique_ptr<draco::Mesh> dm = std::move(decoded).value();
  if (!dm) return Status::error(where + "Draco file holds no mesh");
  const draco::PointAttribute* pos = dm->GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (!pos || pos->num_components() != 3) return Status::error(where + "no 3-component position attribute");
  if (!draco_attribute_holds_numbers(*pos)) return Status::error(where + "the position attribute does not hold numbers");
  const draco::PointAttribute* nrm = dm->GetNamedAttribute(draco::GeometryAttribute::NORMAL);
  if (nrm && nrm->num_components() != 3) nrm = nullptr;
  if (nrm && !draco_attribute_holds_numbers(*nrm)) return Status::error(where + "the normal attribute does not hold numbers");

  IndexedMesh mesh;
  if (const draco::GeometryMetadata* metadata = dm->GetMetadata()) {
    std::vector<double> origin;
    if (metadata->GetEntryDoubleArray(kOriginEntry, &origin)) {
      if (origin.size() != 3 || !is_finite(Vec3d(origin[0], origin[1], origin[2])))
        return Status::error(where + "bad " + kOriginEntry + " metadata (expected 3 finite numbers)");
      mesh.origin = Vec3d(origin[0], origin[1], origin[2]);
    }
  }
  const uint32_t n = dm->num_points();
  mesh.positions.resize(n);
  if (nrm) mesh.normals.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    const draco::PointIndex pi(i);
    if (!pos->ConvertValue<float, 3>(pos->mapped_index(pi), &mesh.positions[i].x) || !is_finite(mesh.positions[i]))
      return Status::error(where + "bad position for point " + std::to_string(i));
    if (nrm) {
      Vec3& v = mesh.normals[i];
      if (!nrm->ConvertValue<float, 3>(nrm->mapped_index(pi), &v.x) || !is_finite(v))
        return Status::error(where + "bad normal for point " + std::to_string(i));
      const float len = glm::length(v);
      v = len > 0 ? v / len : Vec3(0, 1, 0);
    }
  }
  mesh.indices.resize(size_t(dm->num_faces()) * 3);
  for (uint32_t t = 0; t < dm->num_faces(); ++t) {
    const auto& face = dm->face(draco::FaceIndex(t));
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = face[k].value();
      if (v >= n) return Status::error(where + "face " + std::to_string(t) + " has an index out of range");
      mesh.indices[3 * size_t(t) + k] = v;
    }
  }
  if (mesh.triangle_count() == 0) return Status::error(where + "empty mesh");
  return mesh;
}

namespace {

class DracoReader final : public MeshReader {
 public:
  DracoReader(std::filesystem::path path, IndexedMesh mesh, ReaderOptions options, uint64_t bytes)
      : mesh_(std::move(mesh)), options_(options) {
    path_ = std::move(path);
    header_.format = MeshFormat::Draco;
    header_.encoding = "draco";
    header_.vertex_count = mesh_.positions.size();
    header_.face_count = mesh_.triangle_count();
    header_.has_normals = !mesh_.normals.empty();
    header_.file_bytes = bytes;
    header_.origin = mesh_.origin;
  }

  StatusOr<bool> next(TriangleBatch& batch) override {
    batch.clear();
    const size_t total = mesh_.triangle_count();
    const size_t end = std::min(total, next_ + std::max<size_t>(1, options_.batch_triangles));
    for (; next_ < end; ++next_) {
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = mesh_.indices[3 * next_ + k];
        batch.positions.push_back(mesh_.positions[v]);
        if (!mesh_.normals.empty()) batch.normals.push_back(mesh_.normals[v]);
      }
    }
    return batch.size() > 0;
  }

 private:
  IndexedMesh mesh_;
  ReaderOptions options_;
  size_t next_ = 0;
};

}  // namespace

StatusOr<std::unique_ptr<MeshReader>> open_draco_reader(const std::filesystem::path& path, ReaderOptions options) {
  RAYLOD_ASSIGN_OR_RETURN(IndexedMesh mesh, read_draco(path));
  std::error_code ec;
  const uint64_t bytes = std::filesystem::file_size(path, ec);
  return std::unique_ptr<MeshReader>(std::make_unique<DracoReader>(path, std::move(mesh), options, ec ? 0 : bytes));
}

}  // namespace raylod
