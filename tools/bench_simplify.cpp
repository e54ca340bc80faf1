// Benchmark of `raylod simplify` (method step A5) against meshoptimizer.
//
//   bench_simplify --store S.raylod --cut C.cut --mesh M.ply [--runs N] [--out-dir D] [--json OUT.json]
//
// Every measurement runs in a child process (fork), so that each one's peak
// memory (ru_maxrss from wait4) is its own. Modes:
//   raylod   open the store, collapse the cut (streaming pages), write .drc;
//            reports output triangles, open/collapse/write times, .drc bytes and
//            the bytes of the same mesh as binary PLY.
//   meshopt  load the whole mesh into memory (welded by position), then
//            meshopt_simplify to the triangle count raylod produced.
//   sloppy   the same with meshopt_simplifySloppy.
// Prints medians over --runs and writes JSON.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

#include "core/progress.h"
#include "core/system.h"
#include "simplify/collapse.h"
#include "simplify/indexed_mesh_writer.h"
#include "streaming/cut_file.h"
#include "streaming/draco_io.h"
#include "streaming/mesh_reader.h"
#include "streaming/octree_store.h"
#include "pipeline/pipeline.h"

using namespace raylod;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Options {
  std::filesystem::path store, cut, mesh, out_dir = "/tmp/raylod-bench-simplify", json_path;
  int runs = 3;
  bool meshopt = true;
};

StatusOr<json> run_raylod(const Options& o, int run) {
  json r;
  auto t = Clock::now();
  RAYLOD_ASSIGN_OR_RETURN(auto store, OctreeStore::open(o.store));
  RAYLOD_ASSIGN_OR_RETURN(Cut cut, read_cut(o.cut));
  r["open_seconds"] = since(t);
  t = Clock::now();
  RAYLOD_ASSIGN_OR_RETURN(SimplifyResult s, simplify(*store, cut, {}));
  r["collapse_seconds"] = since(t);
  r["input_triangles"] = s.stats.input_triangles;
  r["output_triangles"] = s.stats.output_triangles;
  r["output_vertices"] = s.stats.output_vertices;
  r["cut_cells"] = s.cut_cells;
  r["pages"] = s.pages_read;
  r["mesh_build_bytes"] = s.stats.peak_bytes;
  r["collapse_triangles_per_second"] = double(s.stats.input_triangles) / r["collapse_seconds"].get<double>();
  DracoOptions d;
  d.max_position_error = draco_error_bound(cut, *store);  // the bound raylod run uses
  t = Clock::now();
  const auto drc = o.out_dir / ("simplified-" + std::to_string(run) + ".drc");
  RAYLOD_ASSIGN_OR_RETURN(DracoWriteReport w, write_draco(drc, s.mesh, d));
  r["draco_seconds"] = since(t);
  r["drc_bytes"] = w.bytes;
  r["position_bits"] = w.position_bits;
  r["max_position_error"] = w.max_position_error;
  r["ply_bytes"] = indexed_ply_bytes(s.mesh);
  std::filesystem::remove(drc);
  return r;
}

// The whole mesh in memory, welded by position (what meshoptimizer needs).
StatusOr<IndexedMesh> load_welded(const std::filesystem::path& path) {
  RAYLOD_ASSIGN_OR_RETURN(auto reader, open_mesh(path));
  CollapseBuilder builder({}, false);
  TriangleBatch batch;
  std::vector<uint32_t> keep;
  while (true) {
    RAYLOD_ASSIGN_OR_RETURN(bool more, reader->next(batch));
    if (!more) break;
    batch.normals.clear();
    keep.assign(batch.positions.size(), kKeepVertex);
    builder.add(batch, keep);
  }
  IndexedMesh m = builder.finish();
  m.normals.clear();
  m.normals.shrink_to_fit();
  return m;
}

StatusOr<json> run_meshopt(const Options& o, uint64_t target_triangles, bool sloppy) {
  json r;
  auto t = Clock::now();
  RAYLOD_ASSIGN_OR_RETURN(IndexedMesh m, load_welded(o.mesh));
  r["load_seconds"] = since(t);
  r["input_triangles"] = m.triangle_count();
  r["loaded_rss_bytes"] = current_rss_bytes();
  std::vector<unsigned int> out(m.indices.size());
  t = Clock::now();
  float err = 0;
  const size_t n = sloppy ? meshopt_simplifySloppy(out.data(), m.indices.data(), m.indices.size(), &m.positions[0].x,
                                                   m.positions.size(), sizeof(Vec3), 3 * target_triangles, 1.0f, &err)
                          : meshopt_simplify(out.data(), m.indices.data(), m.indices.size(), &m.positions[0].x,
                                             m.positions.size(), sizeof(Vec3), 3 * target_triangles, 1.0f, 0, &err);
  r["simplify_seconds"] = since(t);
  r["output_triangles"] = n / 3;
  r["result_error_relative"] = err;
  return r;
}

// Runs fn in a child; returns its JSON with "peak_rss_bytes" from wait4.
template <class Fn>
StatusOr<json> in_child(Fn fn) {
  int fds[2];
  if (pipe(fds) != 0) return Status::error("pipe failed");
  const pid_t pid = fork();
  if (pid < 0) return Status::error("fork failed");
  if (pid == 0) {
    close(fds[0]);
    StatusOr<json> r = fn();
    const std::string text = r.is_ok() ? r->dump() : json{{"error", r.status().message()}}.dump();
    size_t off = 0;
    while (off < text.size()) {
      const ssize_t w = write(fds[1], text.data() + off, text.size() - off);
      if (w <= 0) break;
      off += size_t(w);
    }
    close(fds[1]);
    _exit(r.is_ok() ? 0 : 1);
  }
  close(fds[1]);
  std::string text;
  char buf[4096];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof buf)) > 0) text.append(buf, size_t(n));
  close(fds[0]);
  int status = 0;
  struct rusage ru {};
  wait4(pid, &status, 0, &ru);
  if (text.empty()) return Status::error("child process failed (status " + std::to_string(status) + ")");
  json j = json::parse(text);
  if (j.contains("error")) return Status::error(j["error"].get<std::string>());
  j["peak_rss_bytes"] = uint64_t(ru.ru_maxrss) * 1024;
  return j;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

json summarize(const std::vector<json>& runs) {
  json s = runs.front();
  for (auto& [key, value] : s.items()) {
    if (!value.is_number_float() || key.find("seconds") == std::string::npos) continue;
    std::vector<double> v;
    for (const auto& r : runs) v.push_back(r[key].get<double>());
    s[key] = median(v);
  }
  uint64_t peak = 0;
  for (const auto& r : runs) peak = std::max(peak, r["peak_rss_bytes"].get<uint64_t>());
  s["peak_rss_bytes"] = peak;
  s["runs"] = runs.size();
  return s;
}

int usage() {
  std::fprintf(stderr, "usage: bench_simplify --store S.raylod --cut C.cut --mesh M.ply [--runs N] [--out-dir D] "
                       "[--json OUT.json] [--no-meshopt]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--store") o.store = next();
    else if (a == "--cut") o.cut = next();
    else if (a == "--mesh") o.mesh = next();
    else if (a == "--runs") o.runs = std::max(1, std::atoi(next().c_str()));
    else if (a == "--out-dir") o.out_dir = next();
    else if (a == "--json") o.json_path = next();
    else if (a == "--no-meshopt") o.meshopt = false;
    else return usage();
  }
  if (o.store.empty() || o.cut.empty() || (o.meshopt && o.mesh.empty())) return usage();
  std::filesystem::create_directories(o.out_dir);
  Progress::set_enabled(false);

  json report;
  report["store"] = o.store.string();
  report["cut"] = o.cut.string();
  report["mesh"] = o.mesh.string();
  std::vector<json> runs;
  for (int k = 0; k < o.runs; ++k) {
    auto r = in_child([&] { return run_raylod(o, k); });
    if (!r) { std::fprintf(stderr, "bench_simplify: raylod: %s\n", r.status().message().c_str()); return 1; }
    runs.push_back(*r);
  }
  report["raylod"] = summarize(runs);
  const json& rl = report["raylod"];
  const uint64_t target = rl["output_triangles"].get<uint64_t>();
  std::printf("raylod simplify (%d runs, medians)\n", o.runs);
  std::printf("  triangles        %llu -> %llu (%llu cut cells, %llu pages)\n",
              (unsigned long long)rl["input_triangles"].get<uint64_t>(), (unsigned long long)target,
              (unsigned long long)rl["cut_cells"].get<uint64_t>(), (unsigned long long)rl["pages"].get<uint64_t>());
  std::printf("  time             open %.2f s, collapse %.2f s (%.2f M triangles/s), draco %.2f s\n",
              rl["open_seconds"].get<double>(), rl["collapse_seconds"].get<double>(),
              rl["collapse_triangles_per_second"].get<double>() / 1e6, rl["draco_seconds"].get<double>());
  std::printf("  peak memory      %s (mesh build %s)\n", format_bytes(rl["peak_rss_bytes"].get<uint64_t>()).c_str(),
              format_bytes(rl["mesh_build_bytes"].get<uint64_t>()).c_str());
  std::printf("  output           .drc %s (%d position bits, max error %.3g), binary PLY %s\n",
              format_bytes(rl["drc_bytes"].get<uint64_t>()).c_str(), rl["position_bits"].get<int>(),
              rl["max_position_error"].get<double>(), format_bytes(rl["ply_bytes"].get<uint64_t>()).c_str());

  if (o.meshopt) {
    for (bool sloppy : {false, true}) {
      std::vector<json> mruns;
      for (int k = 0; k < o.runs; ++k) {
        auto r = in_child([&] { return run_meshopt(o, target, sloppy); });
        if (!r) { std::fprintf(stderr, "bench_simplify: meshopt: %s\n", r.status().message().c_str()); return 1; }
        mruns.push_back(*r);
      }
      const json m = summarize(mruns);
      report[sloppy ? "meshopt_simplifySloppy" : "meshopt_simplify"] = m;
      std::printf("%s (meshoptimizer %d.%d, whole mesh in memory, %d runs, medians)\n",
                  sloppy ? "meshopt_simplifySloppy" : "meshopt_simplify", MESHOPTIMIZER_VERSION / 1000,
                  (MESHOPTIMIZER_VERSION % 1000) / 10, o.runs);
      std::printf("  triangles        %llu -> %llu (target %llu)\n",
                  (unsigned long long)m["input_triangles"].get<uint64_t>(),
                  (unsigned long long)m["output_triangles"].get<uint64_t>(), (unsigned long long)target);
      std::printf("  time             load+weld %.2f s, simplify %.2f s\n", m["load_seconds"].get<double>(),
                  m["simplify_seconds"].get<double>());
      std::printf("  peak memory      %s (loaded mesh: %s)\n", format_bytes(m["peak_rss_bytes"].get<uint64_t>()).c_str(),
                  format_bytes(m["loaded_rss_bytes"].get<uint64_t>()).c_str());
    }
  }
  if (!o.json_path.empty()) {
    std::ofstream f(o.json_path);
    f << report.dump(2) << "\n";
    std::printf("wrote %s\n", o.json_path.string().c_str());
  }
  return 0;
}
