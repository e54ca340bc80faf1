// bench_readers: streaming throughput of the mesh readers against the raw
// sequential read speed of the same file.
//
// Generates (unless --mesh is given) an indexed binary PLY grid of N
// triangles with analytic vertex normals -- a wavy height field, written by
// the small writer below so the benchmark does not depend on `raylod gen` --
// and converts it to binary STL, and (at a smaller size, --text-triangles) to
// ASCII PLY and OBJ. Each file is then streamed --runs times; the median is
// reported with triangles/s, MB/s, the raw read() speed of the same file and
// the peak RSS while reading it (VmHWM, reset before each format).
//
//   bench_readers [--triangles N] [--text-triangles N] [--runs R] [--batch B]
//                 [--dir DIR] [--mesh FILE] [--formats ply,stl,ascii-ply,obj]
//                 [--json FILE] [--keep]
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/system.h"
#include "streaming/mesh_reader.h"
#include "streaming/mesh_writer.h"

namespace fs = std::filesystem;
using namespace raylod;

namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Resets VmHWM to the current RSS (Linux >= 4.0), so that peak_rss_bytes()
// measures one phase.
void reset_peak_rss() {
  std::ofstream("/proc/self/clear_refs") << "5";
}

// Height field z = a sin(kx) cos(ky) over a W x H vertex grid in [0,1]^2,
// with its analytic unit normal; 2 triangles per quad, first `triangles`.
struct Grid {
  uint64_t triangles, w, h;
  explicit Grid(uint64_t t) : triangles(t) {
    w = 4097;
    const uint64_t quads = (t + 1) / 2;
    h = (quads + (w - 1) - 1) / (w - 1) + 1;
  }
  uint64_t vertices() const { return w * h; }
  void vertex(uint64_t i, float out[6]) const {
    const double x = double(i % w) / double(w - 1), y = double(i / w) / double(h - 1);
    const double a = 0.02, k = 40.0;
    const double z = a * std::sin(k * x) * std::cos(k * y);
    const double dx = a * k * std::cos(k * x) * std::cos(k * y), dy = -a * k * std::sin(k * x) * std::sin(k * y);
    const double len = std::sqrt(dx * dx + dy * dy + 1.0);
    const float v[6] = {float(x), float(y), float(z), float(-dx / len), float(-dy / len), float(1.0 / len)};
    std::memcpy(out, v, sizeof v);
  }
  void triangle(uint64_t t, uint32_t c[3]) const {
    const uint64_t q = t / 2, qx = q % (w - 1), qy = q / (w - 1);
    const uint32_t a = uint32_t(qy * w + qx), b = a + 1, d = uint32_t(a + w), e = d + 1;
    if (t % 2 == 0) { c[0] = a; c[1] = b; c[2] = e; }
    else { c[0] = a; c[1] = e; c[2] = d; }
  }
};

bool write_grid_ply(const fs::path& path, const Grid& g) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\ncomment bench_readers height field\nelement vertex %llu\n"
               "property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n"
               "property float nz\nelement face %llu\nproperty list uchar int vertex_indices\nend_header\n",
               (unsigned long long)g.vertices(), (unsigned long long)g.triangles);
  std::vector<char> buf;
  buf.reserve(1 << 22);
  auto flush = [&] { std::fwrite(buf.data(), 1, buf.size(), f); buf.clear(); };
  for (uint64_t i = 0; i < g.vertices(); ++i) {
    float v[6];
    g.vertex(i, v);
    buf.insert(buf.end(), reinterpret_cast<char*>(v), reinterpret_cast<char*>(v) + 24);
    if (buf.size() > (1 << 22) - 64) flush();
  }
  for (uint64_t t = 0; t < g.triangles; ++t) {
    uint32_t c[3];
    g.triangle(t, c);
    buf.push_back(3);
    buf.insert(buf.end(), reinterpret_cast<char*>(c), reinterpret_cast<char*>(c) + 12);
    if (buf.size() > (1 << 22) - 64) flush();
  }
  flush();
  return std::fclose(f) == 0;
}

bool write_text(const fs::path& path, const Grid& g, bool obj) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  if (!obj)
    std::fprintf(f,
                 "ply\nformat ascii 1.0\nelement vertex %llu\nproperty float x\nproperty float y\nproperty float z\n"
                 "property float nx\nproperty float ny\nproperty float nz\nelement face %llu\n"
                 "property list uchar int vertex_indices\nend_header\n",
                 (unsigned long long)g.vertices(), (unsigned long long)g.triangles);
  for (uint64_t i = 0; i < g.vertices(); ++i) {
    float v[6];
    g.vertex(i, v);
    if (obj) std::fprintf(f, "v %.9g %.9g %.9g\nvn %.9g %.9g %.9g\n", v[0], v[1], v[2], v[3], v[4], v[5]);
    else std::fprintf(f, "%.9g %.9g %.9g %.9g %.9g %.9g\n", v[0], v[1], v[2], v[3], v[4], v[5]);
  }
  for (uint64_t t = 0; t < g.triangles; ++t) {
    uint32_t c[3];
    g.triangle(t, c);
    if (obj) std::fprintf(f, "f %u//%u %u//%u %u//%u\n", c[0] + 1, c[0] + 1, c[1] + 1, c[1] + 1, c[2] + 1, c[2] + 1);
    else std::fprintf(f, "3 %u %u %u\n", c[0], c[1], c[2]);
  }
  return std::fclose(f) == 0;
}

Status convert(const fs::path& from, const fs::path& to) {
  RAYLOD_ASSIGN_OR_RETURN(auto reader, open_mesh(from));
  RAYLOD_ASSIGN_OR_RETURN(auto writer, create_mesh_writer(to));
  TriangleBatch b;
  while (true) {
    RAYLOD_ASSIGN_OR_RETURN(bool more, reader->next(b));
    if (!more) break;
    RAYLOD_RETURN_IF_ERROR(writer->write(b));
  }
  return writer->finish();
}

double raw_read_seconds(const fs::path& path) {
  const double t0 = now();
  int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return 0;
  std::vector<char> buf(1 << 20);
  uint64_t sum = 0;
  ssize_t n;
  while ((n = ::read(fd, buf.data(), buf.size())) > 0) sum += uint64_t(buf[0]) + uint64_t(n);
  ::close(fd);
  const double t = now() - t0;
  if (sum == 1) std::printf(" ");  // keep the loop
  return t;
}

struct Result {
  std::string format, file;
  uint64_t bytes = 0, triangles = 0;
  double seconds = 0, raw_seconds = 0;
  uint64_t peak_rss = 0;
};

bool bench(const fs::path& path, const std::string& label, int runs, size_t batch, Result& out) {
  out.format = label;
  out.file = path.string();
  out.bytes = fs::file_size(path);
  std::vector<double> times, raw;
  for (int r = 0; r < runs; ++r) raw.push_back(raw_read_seconds(path));
  reset_peak_rss();
  for (int r = 0; r < runs; ++r) {
    const double t0 = now();
    auto reader = open_mesh(path, ReaderOptions{batch});
    if (!reader) {
      std::fprintf(stderr, "bench_readers: %s\n", reader.status().message().c_str());
      return false;
    }
    TriangleBatch b;
    uint64_t tris = 0;
    float checksum = 0;
    while (true) {
      auto more = reader.value()->next(b);
      if (!more) {
        std::fprintf(stderr, "bench_readers: %s\n", more.status().message().c_str());
        return false;
      }
      if (!more.value()) break;
      tris += b.size();
      checksum += b.positions.back().x;
    }
    times.push_back(now() - t0);
    out.triangles = tris;
    if (checksum == -1.2345f) std::printf(" ");
  }
  out.peak_rss = peak_rss_bytes();
  out.seconds = median(times);
  out.raw_seconds = median(raw);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t triangles = 20'000'000, text_triangles = 2'000'000;
  int runs = 5;
  size_t batch = ReaderOptions{}.batch_triangles;
  fs::path dir = "/tmp/raylod-bench", mesh, json;
  std::string formats = "ply,stl,ascii-ply,obj";
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) { std::fprintf(stderr, "bench_readers: %s needs a value\n", a.c_str()); std::exit(2); }
      return argv[++i];
    };
    if (a == "--triangles") triangles = std::stoull(value());
    else if (a == "--text-triangles") text_triangles = std::stoull(value());
    else if (a == "--runs") runs = std::max(1, std::stoi(value()));
    else if (a == "--batch") batch = std::stoull(value());
    else if (a == "--dir") dir = value();
    else if (a == "--mesh") mesh = value();
    else if (a == "--formats") formats = value();
    else if (a == "--json") json = value();
    else if (a == "--keep") keep = true;
    else {
      std::printf("usage: bench_readers [--triangles N] [--text-triangles N] [--runs R] [--batch B] [--dir DIR]\n"
                  "                     [--mesh FILE] [--formats ply,stl,ascii-ply,obj] [--json FILE] [--keep]\n");
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  fs::create_directories(dir);
  std::vector<std::pair<std::string, fs::path>> files;
  std::vector<fs::path> generated;
  auto want = [&](const char* f) { return ("," + formats + ",").find("," + std::string(f) + ",") != std::string::npos; };
  if (!mesh.empty()) {
    files.push_back({mesh.extension().string(), mesh});
  } else {
    const Grid g(triangles), gt(std::min(triangles, text_triangles));
    const fs::path ply = dir / ("grid_" + std::to_string(triangles) + ".ply");
    std::printf("generating %s (%llu triangles, %llu vertices with normals)...\n", ply.c_str(),
                (unsigned long long)g.triangles, (unsigned long long)g.vertices());
    if (!write_grid_ply(ply, g)) { std::fprintf(stderr, "bench_readers: cannot write %s\n", ply.c_str()); return 1; }
    generated.push_back(ply);
    if (want("ply")) files.push_back({"binary PLY", ply});
    if (want("stl")) {
      const fs::path stl = dir / ("grid_" + std::to_string(triangles) + ".stl");
      if (Status s = convert(ply, stl); !s) { std::fprintf(stderr, "bench_readers: %s\n", s.message().c_str()); return 1; }
      generated.push_back(stl);
      files.push_back({"binary STL", stl});
    }
    if (want("ascii-ply")) {
      const fs::path p = dir / ("grid_" + std::to_string(gt.triangles) + "_ascii.ply");
      if (!write_text(p, gt, false)) return 1;
      generated.push_back(p);
      files.push_back({"ASCII PLY", p});
    }
    if (want("obj")) {
      const fs::path p = dir / ("grid_" + std::to_string(gt.triangles) + ".obj");
      if (!write_text(p, gt, true)) return 1;
      generated.push_back(p);
      files.push_back({"OBJ", p});
    }
  }
  std::printf("%d runs each (median), batch %zu triangles, warm page cache\n\n", runs, batch);
  std::printf("%-11s %12s %10s %14s %10s %12s %10s\n", "format", "triangles", "MB", "triangles/s", "MB/s",
              "raw read MB/s", "peak RSS");
  std::vector<Result> results;
  for (const auto& [label, path] : files) {
    Result r;
    if (!bench(path, label, runs, batch, r)) return 1;
    const double mb = double(r.bytes) / 1e6;
    std::printf("%-11s %12llu %10.1f %14.4g %10.1f %12.1f %10s\n", label.c_str(), (unsigned long long)r.triangles, mb,
                double(r.triangles) / r.seconds, mb / r.seconds, mb / r.raw_seconds, format_bytes(r.peak_rss).c_str());
    results.push_back(r);
  }
  if (!json.empty()) {
    std::FILE* f = std::fopen(json.c_str(), "w");
    if (!f) { std::fprintf(stderr, "bench_readers: cannot write %s\n", json.c_str()); return 1; }
    std::fprintf(f, "{\n  \"benchmark\": \"bench_readers\",\n  \"runs\": %d,\n  \"batch_triangles\": %zu,\n  \"results\": [\n",
                 runs, batch);
    for (size_t i = 0; i < results.size(); ++i) {
      const Result& r = results[i];
      std::fprintf(f,
                   "    {\"format\": \"%s\", \"file\": \"%s\", \"bytes\": %llu, \"triangles\": %llu, "
                   "\"median_seconds\": %.6f, \"triangles_per_second\": %.1f, \"mb_per_second\": %.1f, "
                   "\"raw_read_mb_per_second\": %.1f, \"peak_rss_bytes\": %llu}%s\n",
                   r.format.c_str(), r.file.c_str(), (unsigned long long)r.bytes, (unsigned long long)r.triangles,
                   r.seconds, double(r.triangles) / r.seconds, double(r.bytes) / 1e6 / r.seconds,
                   double(r.bytes) / 1e6 / r.raw_seconds, (unsigned long long)r.peak_rss,
                   i + 1 < results.size() ? "," : "");
    }
    std::fprintf(f, "  ]\n}\n");
    std::fclose(f);
  }
  if (!keep)
    for (const auto& p : generated) fs::remove(p);
  return 0;
}
