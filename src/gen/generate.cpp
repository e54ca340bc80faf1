#include "gen/generate.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <optional>

#include <tbb/parallel_for.h>

#include "core/progress.h"
#include "core/system.h"
#include "gen/bezier_teapot.h"
#include "gen/bottle.h"
#include "streaming/indexed_ply_writer.h"

namespace raylod {
namespace {

// Vertices evaluated per chunk: bounds memory (24 bytes each for position and
// normal) while leaving enough rows per chunk for the threads to share.
constexpr uint64_t kChunkVertices = uint64_t(1) << 16;
constexpr uint64_t kChunkTriangles = uint64_t(1) << 17;

std::string lower_extension(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  for (auto& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

Status check_request(const std::string& shape, uint64_t triangles) {
  if (shape != "teapot" && shape != "bottle")
    return Status::error("unknown shape '" + shape + "' (expected teapot or bottle)");
  if (triangles < kGenMinTriangles || triangles > kGenMaxTriangles)
    return Status::error("triangle count " + std::to_string(triangles) + " is outside [" +
                         std::to_string(kGenMinTriangles) + ", " + std::to_string(kGenMaxTriangles) + "]");
  return Status::ok();
}

std::vector<std::string> ply_comments(const std::string& shape, uint64_t requested, const std::string& grid) {
  return {"raylod gen " + shape + " --triangles " + std::to_string(requested),
          shape == "teapot" ? std::string("Newell teapot (1975), 32 bicubic Bezier patches, y up, analytic normals")
                            : std::string("glass bottle, surface of revolution of a G1 line/arc profile, analytic normals"),
          "grid " + grid};
}

// A run of consecutive vertex rows [row_begin, row_end) of one piece.
struct RowChunk {
  size_t piece;
  uint32_t row_begin, row_end;
};

// Splits every piece into chunks of at most kChunkVertices vertices (but at
// least min_rows rows), optionally overlapping by one row (for STL, whose
// triangles need both rows of a band).
std::vector<RowChunk> row_chunks(const GridSurface& s, bool overlap) {
  std::vector<RowChunk> chunks;
  const auto& pieces = s.pieces();
  for (size_t p = 0; p < pieces.size(); ++p) {
    const GridPiece& g = pieces[p];
    uint32_t r = 0;
    while (r < g.rows) {
      uint32_t end = r;
      uint64_t n = 0;
      while (end < g.rows && (end == r || n + grid_row_vertices(g, end) <= kChunkVertices)) {
        n += grid_row_vertices(g, end);
        ++end;
      }
      if (overlap && end - r < 2 && end < g.rows) ++end;
      chunks.push_back({p, r, end});
      if (end == g.rows) break;
      r = overlap ? end - 1 : end;
    }
  }
  return chunks;
}

// Evaluates the rows of a chunk in parallel into pos/nrm (row-major, packed).
void eval_chunk(const GridSurface& s, const RowChunk& c, std::vector<Vec3>& pos, std::vector<Vec3>& nrm) {
  const GridPiece& g = s.pieces()[c.piece];
  const uint64_t base = grid_row_offset(g, c.row_begin);
  const uint64_t n = (c.row_end == g.rows ? grid_vertex_count(g) : grid_row_offset(g, c.row_end)) - base;
  pos.resize(n);
  nrm.resize(n);
  tbb::parallel_for(c.row_begin, c.row_end, [&](uint32_t row) {
    const uint64_t at = grid_row_offset(g, row) - base;
    const uint32_t m = grid_row_vertices(g, row);
    s.eval_row(c.piece, row, std::span<Vec3>(pos.data() + at, m), std::span<Vec3>(nrm.data() + at, m));
  });
}

void expand_bounds(Bbox* bounds, const std::vector<Vec3>& pos) {
  if (!bounds || pos.empty()) return;
  Vec3 lo = pos[0], hi = pos[0];
  for (const Vec3& p : pos) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  bounds->expand(lo);
  bounds->expand(hi);
}

}  // namespace

StatusOr<std::unique_ptr<GridSurface>> make_generated_surface(const std::string& shape, uint64_t triangles,
                                                              std::string* grid, uint32_t around) {
  RAYLOD_RETURN_IF_ERROR(check_request(shape, triangles));
  if (around > 0 && shape != "bottle")
    return Status::error("a number of columns around the axis is a bottle's, not a " + shape + "'s");
  if (around > 0 && (around < 3 || 2.0 * around > double(triangles)))
    return Status::error("columns around the axis: " + std::to_string(around) + " is outside [3, " +
                         std::to_string(triangles / 2) + "] for " + std::to_string(triangles) + " triangles");
  if (shape == "teapot") {
    const TeapotPlan plan = plan_teapot(triangles);
    if (grid)
      *grid = "32 patches x " + std::to_string(plan.row_segments) + " x " + std::to_string(plan.col_segments) +
              " segments";
    return std::unique_ptr<GridSurface>(new BezierTeapot(plan));
  }
  const BottleConfig config;
  RAYLOD_RETURN_IF_ERROR(validate_bottle(config));
  const BottlePlan plan = around > 0 ? plan_bottle_around(triangles, around) : plan_bottle(triangles, config);
  if (grid)
    *grid = std::to_string(plan.profile_segments) + " profile segments x " + std::to_string(plan.around) + " around";
  return std::unique_ptr<GridSurface>(new BottleSurface(plan, config));
}

Status write_grid_ply(const GridSurface& s, const std::filesystem::path& out, bool normals,
                      const std::vector<std::string>& comments, Bbox* bounds, bool progress) {
  IndexedPlyLayout layout{s.vertex_count(), s.triangle_count(), normals, comments};
  RAYLOD_ASSIGN_OR_RETURN(auto writer, IndexedPlyWriter::create(out, layout));
  std::optional<Progress> bar;
  if (progress) bar.emplace("gen " + out.filename().string(), layout.vertex_count + layout.face_count);

  std::vector<Vec3> pos, nrm;
  for (const RowChunk& c : row_chunks(s, false)) {
    eval_chunk(s, c, pos, nrm);
    expand_bounds(bounds, pos);
    RAYLOD_RETURN_IF_ERROR(writer->append_vertices(pos, nrm));
    if (bar) bar->advance(pos.size());
  }
  pos.clear();
  pos.shrink_to_fit();
  nrm.clear();
  nrm.shrink_to_fit();

  std::vector<uint32_t> idx;
  uint64_t base = 0;
  for (const GridPiece& g : s.pieces()) {
    const uint32_t bands = g.rows - 1;
    const uint32_t per = uint32_t(std::max<uint64_t>(1, kChunkTriangles / (2 * grid_quads_per_band(g))));
    for (uint32_t b = 0; b < bands; b += per) {
      idx.clear();
      grid_band_indices(g, base, b, std::min(bands, b + per), idx);
      RAYLOD_RETURN_IF_ERROR(writer->append_triangles(idx));
      if (bar) bar->advance(idx.size() / 3);
    }
    base += grid_vertex_count(g);
  }
  RAYLOD_RETURN_IF_ERROR(writer->finish());
  if (bar) bar->finish();
  return Status::ok();
}

Status write_grid_stl(const GridSurface& s, const std::filesystem::path& out, const std::string& header_text,
                      Bbox* bounds, bool progress) {
  const uint64_t total = s.triangle_count();
  if (total > 0xffffffffull) return Status::error(out.string() + ": too many triangles for binary STL");
  AtomicOutput output(out);
  std::FILE* f = std::fopen(output.temp_path().c_str(), "wb");
  if (!f) return Status::error(out.string() + ": cannot create output: " + std::strerror(errno));
  std::setvbuf(f, nullptr, _IOFBF, size_t(4) << 20);
  auto io_error = [&](const char* what) {
    std::fclose(f);
    return Status::error(out.string() + ": " + what + " failed (disk full?): " + std::strerror(errno));
  };
  // 80-byte header (must not start with "solid", which marks ASCII STL), then
  // the little-endian triangle count and 50-byte records.
  char header[80];
  std::memset(header, ' ', sizeof header);
  std::string text = "binary STL: " + header_text;
  std::memcpy(header, text.data(), std::min(text.size(), sizeof header));
  unsigned char count[4] = {uint8_t(total), uint8_t(total >> 8), uint8_t(total >> 16), uint8_t(total >> 24)};
  if (std::fwrite(header, 1, 80, f) != 80 || std::fwrite(count, 1, 4, f) != 4) return io_error("write");

  std::optional<Progress> bar;
  if (progress) bar.emplace("gen " + out.filename().string(), total);
  std::vector<Vec3> pos, nrm;
  std::vector<uint32_t> idx;
  std::vector<unsigned char> rec;
  uint64_t written = 0;
  for (const RowChunk& c : row_chunks(s, true)) {
    const GridPiece& g = s.pieces()[c.piece];
    eval_chunk(s, c, pos, nrm);
    expand_bounds(bounds, pos);
    idx.clear();
    const uint64_t base = grid_row_offset(g, c.row_begin);
    grid_band_indices(g, 0, c.row_begin, c.row_end - 1, idx);
    rec.resize(idx.size() / 3 * 50);
    unsigned char* dst = rec.data();
    for (size_t t = 0; t < idx.size(); t += 3, dst += 50) {
      const Vec3& a = pos[idx[t] - base];
      const Vec3& b = pos[idx[t + 1] - base];
      const Vec3& cc = pos[idx[t + 2] - base];
      Vec3d n = face_normal(Vec3d(a), Vec3d(b), Vec3d(cc));
      if (n == Vec3d(0)) {
        // Degenerate in float (sub-ULP triangle): fall back on the analytic normals.
        n = glm::normalize(Vec3d(nrm[idx[t] - base]) + Vec3d(nrm[idx[t + 1] - base]) + Vec3d(nrm[idx[t + 2] - base]));
      }
      const float v[12] = {float(n.x), float(n.y), float(n.z), a.x, a.y, a.z, b.x, b.y, b.z, cc.x, cc.y, cc.z};
      // Little-endian hosts only write floats as they are; see indexed_ply_writer.cpp for the general case.
      static_assert(std::endian::native == std::endian::little, "binary STL writer assumes a little-endian host");
      std::memcpy(dst, v, 48);
      dst[48] = dst[49] = 0;
    }
    if (!rec.empty() && std::fwrite(rec.data(), 1, rec.size(), f) != rec.size()) return io_error("write");
    written += idx.size() / 3;
    if (bar) bar->advance(idx.size() / 3);
  }
  if (written != total) {
    std::fclose(f);
    return Status::error(out.string() + ": internal error: wrote " + std::to_string(written) + " of " +
                         std::to_string(total) + " triangles");
  }
  if (std::fclose(f) != 0) return Status::error(out.string() + ": close failed (disk full?)");
  RAYLOD_RETURN_IF_ERROR(output.commit());
  if (bar) bar->finish();
  return Status::ok();
}

StatusOr<GenReport> generate_mesh(const GenOptions& options, const std::filesystem::path& out) {
  const auto start = std::chrono::steady_clock::now();
  const std::string ext = lower_extension(out);
  if (ext != ".ply" && ext != ".stl")
    return Status::error(out.string() + ": output must end in .ply or .stl");
  GenReport report;
  report.path = out;
  report.shape = options.shape;
  report.format = ext.substr(1);
  report.requested_triangles = options.triangles;
  RAYLOD_ASSIGN_OR_RETURN(auto surface, make_generated_surface(options.shape, options.triangles, &report.grid, options.around));
  report.triangles = surface->triangle_count();
  report.vertices = surface->vertex_count();
  if (ext == ".ply") {
    RAYLOD_RETURN_IF_ERROR(write_grid_ply(*surface, out, options.normals,
                                          ply_comments(options.shape, options.triangles, report.grid),
                                          &report.bounds, options.progress));
  } else {
    RAYLOD_RETURN_IF_ERROR(write_grid_stl(*surface, out,
                                          "raylod gen " + options.shape + " " + std::to_string(report.triangles) +
                                              " triangles",
                                          &report.bounds, options.progress));
  }
  std::error_code ec;
  report.bytes = std::filesystem::file_size(out, ec);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

std::filesystem::path generated_mesh_path(const GeneratedMesh& g, const std::filesystem::path& cache_dir) {
  return cache_dir / "meshes" / (g.generator + "-" + std::to_string(g.triangles) + ".ply");
}

StatusOr<std::filesystem::path> ensure_generated_mesh(const GeneratedMesh& g, const std::filesystem::path& cache_dir) {
  RAYLOD_RETURN_IF_ERROR(check_request(g.generator, g.triangles));
  const std::filesystem::path path = generated_mesh_path(g, cache_dir);
  std::string grid;
  RAYLOD_ASSIGN_OR_RETURN(auto surface, make_generated_surface(g.generator, g.triangles, &grid));
  const IndexedPlyLayout layout{surface->vertex_count(), surface->triangle_count(), true,
                                ply_comments(g.generator, g.triangles, grid)};
  auto complete = [&] {
    std::error_code ec;
    const uint64_t size = std::filesystem::file_size(path, ec);
    return !ec && size == indexed_ply_file_bytes(layout);
  };
  if (complete()) return path;
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);
  if (ec) return Status::error(path.parent_path().string() + ": cannot create cache directory: " + ec.message());
  // One writer at a time, and a complete file is never rewritten: a process
  // building a store from it would see its modification time change and fail
  // ("the mesh changed while building"). The lock is released on close.
  std::filesystem::path lock_path = path;
  lock_path += ".lock";
  const int lock = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock < 0) return Status::error(lock_path.string() + ": cannot create lock file: " + std::strerror(errno));
  struct Unlock {
    int fd;
    ~Unlock() { ::close(fd); }
  } unlock{lock};
  while (::flock(lock, LOCK_EX) != 0)
    if (errno != EINTR) return Status::error(lock_path.string() + ": cannot lock: " + std::strerror(errno));
  if (complete()) return path;  // another process wrote it while we waited
  // Written to a temporary and renamed into place when complete (AtomicOutput).
  RAYLOD_RETURN_IF_ERROR(write_grid_ply(*surface, path, true, layout.comments));
  return path;
}

Status resolve_generated_meshes(Scene& scene, const std::filesystem::path& cache_dir) {
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    SceneObject& obj = scene.objects[i];
    if (!obj.generate) continue;
    auto path = ensure_generated_mesh(*obj.generate, cache_dir);
    if (!path) return path.status().with_context("object " + std::to_string(i));
    obj.mesh = *path;
  }
  return Status::ok();
}

}  // namespace raylod
