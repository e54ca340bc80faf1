// Benchmark of `raylod build` (the out-of-core octree store) against loading
// the same mesh into memory with OpenMesh.
//
//   bench_build [--runs N] [--memory-limit SIZE] [--threads T] [--out DIR] [--json FILE] [--no-openmesh] MESH...
//
// Every build and every OpenMesh load runs in a child process, so the peak
// resident memory reported is the child's ru_maxrss from wait4() -- the same
// figure `/usr/bin/time -v` prints -- and the user + system CPU seconds come
// from the same rusage. The parent never touches the mesh. Runs are warm-cache
// (the mesh is read once before timing). Prints medians and named counters,
// and writes JSON.
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include "core/progress.h"
#include "core/system.h"
#include "streaming/octree_store.h"

namespace {

using namespace raylod;

struct ChildResult {
  bool ok = false;
  double wall = 0, user = 0, sys = 0;
  uint64_t max_rss = 0;
  // build
  double scan = 0, bin = 0, write = 0, commit = 0, inside = 0;
  uint64_t triangles = 0, nodes = 0, pages = 0, store_bytes = 0, node_bytes = 0;
  uint64_t written = 0;  // bytes the process passed to write calls (/proc/self/io wchar): runs and store
  uint64_t open_edges = 0, open_edges_peak = 0, runs_written = 0, runs_held_peak = 0;
  int quadric_depth = 0, page_level = 0;
  double open = 0;  // read back: OctreeStore::open alone (header, tables, node table checked)
  // OpenMesh
  uint64_t faces = 0, vertices = 0;
  char error[512] = {};
};

// Runs fn in a child; fn fills the result, which comes back through a pipe.
template <class Fn>
ChildResult in_child(Fn fn) {
  int fds[2];
  if (pipe(fds) != 0) std::abort();
  auto t0 = std::chrono::steady_clock::now();
  pid_t pid = fork();
  if (pid == 0) {
    close(fds[0]);
    ChildResult r;
    fn(r);
    ssize_t w = write(fds[1], &r, sizeof r);
    _exit(w == ssize_t(sizeof r) ? 0 : 1);
  }
  close(fds[1]);
  ChildResult r;
  ssize_t got = 0;
  while (got < ssize_t(sizeof r)) {
    ssize_t n = read(fds[0], reinterpret_cast<char*>(&r) + got, sizeof r - size_t(got));
    if (n <= 0) break;
    got += n;
  }
  close(fds[0]);
  int status = 0;
  struct rusage ru {};
  wait4(pid, &status, 0, &ru);
  r.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.user = double(ru.ru_utime.tv_sec) + 1e-6 * double(ru.ru_utime.tv_usec);
  r.sys = double(ru.ru_stime.tv_sec) + 1e-6 * double(ru.ru_stime.tv_usec);
  r.max_rss = uint64_t(ru.ru_maxrss) * 1024;
  if (got != ssize_t(sizeof r) || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    r.ok = false;
    if (!r.error[0]) std::snprintf(r.error, sizeof r.error, "child failed (status %d)", status);
  }
  return r;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Reads the whole file (as `cat FILE > /dev/null`); returns the seconds it took.
double warm(const std::string& path) {
  const auto t0 = std::chrono::steady_clock::now();
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buf(1 << 22);
  while (in.read(buf.data(), std::streamsize(buf.size())) || in.gcount() > 0) {
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// /proc/self/io's wchar: bytes this process has passed to write calls.
uint64_t bytes_written_by_process() {
  std::ifstream io("/proc/self/io");
  std::string key;
  uint64_t value = 0;
  while (io >> key >> value)
    if (key == "wchar:") return value;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 3, threads = 0;
  uint64_t limit = uint64_t(1) << 30;
  std::string out_dir = "/tmp/raylod-bench-build", json_path;
  bool openmesh = true;
  std::vector<std::string> meshes;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_build: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--runs") runs = std::max(1, std::atoi(next().c_str()));
    else if (a == "--threads") threads = std::atoi(next().c_str());
    else if (a == "--memory-limit") {
      auto v = parse_size(next());
      if (!v) { std::fprintf(stderr, "bench_build: %s\n", v.status().message().c_str()); return 2; }
      limit = *v;
    } else if (a == "--out") out_dir = next();
    else if (a == "--json") json_path = next();
    else if (a == "--no-openmesh") openmesh = false;
    else if (a == "-h" || a == "--help") {
      std::printf("usage: bench_build [--runs N] [--memory-limit SIZE] [--threads T] [--out DIR] [--json FILE] "
                  "[--no-openmesh] MESH...\n");
      return 0;
    } else meshes.push_back(a);
  }
  if (meshes.empty()) {
    std::fprintf(stderr, "bench_build: no mesh given (try --help)\n");
    return 2;
  }
  std::filesystem::create_directories(out_dir);
  nlohmann::json report = nlohmann::json::array();

  for (const std::string& mesh : meshes) {
    const uint64_t mesh_bytes = std::filesystem::file_size(mesh);
    uint64_t declared_faces = 0;
    {
      ChildResult h = in_child([&](ChildResult& r) {
        auto reader = open_mesh(mesh);
        if (!reader) { std::snprintf(r.error, sizeof r.error, "%s", reader.status().message().c_str()); return; }
        r.faces = (*reader)->header().face_count;
        r.ok = true;
      });
      if (!h.ok) { std::fprintf(stderr, "bench_build: %s\n", h.error); return 1; }
      declared_faces = h.faces;
    }
    warm(mesh);
    const double read_s = warm(mesh);  // warm, as the build's reads are
    const std::filesystem::path store = std::filesystem::path(out_dir) / (std::filesystem::path(mesh).filename().string() + ".raylod");
    std::vector<double> walls, cpus;
    ChildResult last;
    uint64_t peak = 0;
    for (int run = 0; run < runs; ++run) {
      ChildResult r = in_child([&](ChildResult& out) {
        Progress::set_enabled(false);
        // As raylod's main(): one thread limit for the process (this child) that builds.
        std::optional<tbb::global_control> parallelism;
        if (threads > 0) parallelism.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));
        StoreOptions opt;
        opt.memory_limit = limit;
        // What `raylod build --force` runs: the content hash is computed concurrently with pass 1.
        const uint64_t written_before = bytes_written_by_process();
        auto built = build_store(mesh, store, opt, /*force=*/true);
        out.written = bytes_written_by_process() - written_before;
        if (!built) { std::snprintf(out.error, sizeof out.error, "%s", built.status().message().c_str()); return; }
        out.ok = true;
        out.inside = built->seconds;
        out.scan = built->scan_seconds; out.bin = built->bin_seconds;
        out.write = built->write_seconds; out.commit = built->commit_seconds;
        out.triangles = built->triangles; out.nodes = built->nodes; out.pages = built->pages;
        out.store_bytes = built->store_bytes; out.node_bytes = built->node_table_bytes;
        out.quadric_depth = built->quadric_depth; out.page_level = built->page_level;
        out.open_edges = built->open_edges; out.open_edges_peak = built->open_edges_peak;
        out.runs_written = built->runs_written; out.runs_held_peak = built->runs_held_peak;
      });
      if (!r.ok) { std::fprintf(stderr, "bench_build: %s: %s\n", mesh.c_str(), r.error); return 1; }
      walls.push_back(r.wall);
      cpus.push_back(r.user + r.sys);
      peak = std::max(peak, r.max_rss);
      last = r;
    }
    // Memory per quadric level, from the store itself.
    nlohmann::json levels = nlohmann::json::array();
    {
      auto opened = OctreeStore::open(store);
      if (!opened) { std::fprintf(stderr, "bench_build: %s\n", opened.status().message().c_str()); return 1; }
      for (int l = 0; l <= (*opened)->header().quadric_depth; ++l)
        levels.push_back({{"level", l}, {"nodes", (*opened)->level(l).size()},
                          {"bytes", (*opened)->level(l).size() * sizeof(NodeRecord)}});
    }
    // Read every page back (checksums verified), in a child so its memory is its own.
    ChildResult rb = in_child([&](ChildResult& r) {
      const auto t_open = std::chrono::steady_clock::now();
      auto opened = OctreeStore::open(store);
      r.open = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_open).count();
      if (!opened) { std::snprintf(r.error, sizeof r.error, "%s", opened.status().message().c_str()); return; }
      TriangleBatch batch;
      for (size_t i = 0; i < (*opened)->pages().size(); ++i) {
        Status st = (*opened)->read_page(i, batch);
        if (!st) { std::snprintf(r.error, sizeof r.error, "%s", st.message().c_str()); return; }
        r.triangles += batch.size();
      }
      r.ok = true;
    });
    if (!rb.ok) { std::fprintf(stderr, "bench_build: read back: %s\n", rb.error); return 1; }
    const double wall = median(walls), cpu = median(cpus);
    std::printf("%s: %" PRIu64 " triangles, %s, memory limit %s, %d runs (median)\n", mesh.c_str(), last.triangles,
                format_bytes(mesh_bytes).c_str(), format_bytes(limit).c_str(), runs);
    std::printf("  build            %.2f s wall (%.2f M triangles/s), %.2f s CPU (user+sys; %.2f M triangles per CPU-s)\n",
                wall, double(last.triangles) / wall / 1e6, cpu, double(last.triangles) / cpu / 1e6);
    std::printf("  phases (last)    bounds %.2f, binning %.2f, pages %.2f, fsync %.2f s; build_store %.2f s of the "
                "process's %.2f s\n",
                last.scan, last.bin, last.write, last.commit, last.inside, last.wall);
    std::printf("  reading the file %.2f s warm (as cat FILE > /dev/null): the build takes %.1fx that\n", read_s,
                wall / read_s);
    std::printf("  written (last)   %s = %.2fx the store (runs and store, bytes passed to write calls)\n",
                format_bytes(last.written).c_str(), double(last.written) / double(last.store_bytes));
    std::printf("  peak RSS         %s (max over runs; limit %s)\n", format_bytes(peak).c_str(), format_bytes(limit).c_str());
    std::printf("  store            %s = %.2fx the input (node table %s, %" PRIu64 " nodes, levels 0..%d; %" PRIu64
                " pages at level %d)\n",
                format_bytes(last.store_bytes).c_str(), double(last.store_bytes) / double(mesh_bytes),
                format_bytes(last.node_bytes).c_str(), last.nodes, last.quadric_depth, last.pages, last.page_level);
    std::printf("  sorted runs      %s written to the temporary file, at most %s kept in memory instead\n",
                format_bytes(last.runs_written).c_str(), format_bytes(last.runs_held_peak).c_str());
    std::printf("  open edges       %" PRIu64 " (a hole's or open surface's rim); at most %" PRIu64
                " pending a match across pages at once\n",
                last.open_edges, last.open_edges_peak);
    std::printf("  read back        %" PRIu64 " triangles, every page checksum verified: %.2f s (%.1f M triangles/s, "
                "open included: %.3f s), peak RSS %s\n",
                rb.triangles, rb.wall, double(rb.triangles) / rb.wall / 1e6, rb.open, format_bytes(rb.max_rss).c_str());
    std::printf("  quadric memory   ");
    for (const auto& l : levels) std::printf("L%d %s  ", int(l["level"]), format_bytes(l["bytes"]).c_str());
    std::printf("\n");
    nlohmann::json entry = {{"mesh", mesh}, {"mesh_bytes", mesh_bytes}, {"triangles", last.triangles},
                            {"memory_limit", limit}, {"threads", threads}, {"runs", runs},
                            {"build_wall_s_median", wall}, {"build_cpu_s_median", cpu},
                            {"triangles_per_s", double(last.triangles) / wall},
                            {"triangles_per_cpu_s", double(last.triangles) / cpu},
                            {"build_walls_s", walls},
                            {"phases_s", {{"bounds", last.scan}, {"binning", last.bin}, {"pages", last.write}, {"fsync", last.commit}}},
                            {"read_file_s", read_s}, {"build_over_read", wall / read_s},
                            {"written_bytes", last.written},
                            {"peak_rss_bytes", peak}, {"store_bytes", last.store_bytes},
                            {"store_over_input", double(last.store_bytes) / double(mesh_bytes)},
                            {"nodes", last.nodes}, {"node_table_bytes", last.node_bytes}, {"pages", last.pages},
                            {"read_back_s", rb.wall}, {"open_s", rb.open}, {"read_back_peak_rss_bytes", rb.max_rss},
                            {"quadric_depth", last.quadric_depth}, {"page_level", last.page_level}, {"levels", levels}};
    if (openmesh) {
      ChildResult om = in_child([&](ChildResult& r) {
        OpenMesh::TriMesh_ArrayKernelT<> m;
        m.request_vertex_normals();
        OpenMesh::IO::Options opt = OpenMesh::IO::Options::VertexNormal;
        try {
          if (!OpenMesh::IO::read_mesh(m, mesh, opt)) {
            std::snprintf(r.error, sizeof r.error, "OpenMesh could not read %s", mesh.c_str());
            return;
          }
        } catch (const std::exception& e) {
          std::snprintf(r.error, sizeof r.error, "OpenMesh: %s", e.what());
          return;
        }
        r.faces = m.n_faces();
        r.vertices = m.n_vertices();
        r.ok = true;
      });
      if (!om.ok) {
        std::printf("  OpenMesh load    failed: %s\n", om.error);
        entry["openmesh"] = {{"error", om.error}};
      } else {
        const uint64_t dropped = declared_faces > om.faces ? declared_faces - om.faces : 0;
        std::printf("  OpenMesh load    %.2f s wall, %.2f s CPU, peak RSS %s, %" PRIu64 " faces kept, %" PRIu64
                    " dropped; build / load = %.2f\n",
                    om.wall, om.user + om.sys, format_bytes(om.max_rss).c_str(), om.faces, dropped, wall / om.wall);
        entry["openmesh"] = {{"load_wall_s", om.wall}, {"load_cpu_s", om.user + om.sys}, {"peak_rss_bytes", om.max_rss},
                             {"faces", om.faces}, {"dropped_faces", dropped}, {"build_over_load", wall / om.wall}};
      }
    }
    report.push_back(entry);
    std::fflush(stdout);
  }
  if (!json_path.empty()) std::ofstream(json_path) << report.dump(2) << "\n";
  return 0;
}
