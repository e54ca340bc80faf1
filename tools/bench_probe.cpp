// bench_probe: probe time and pages read for test-ray counts and materials
// on prebuilt stores (raylod build MESH first), the default scene's camera.
//
//   bench_probe STORE [STORE...] [--rays 5000,50000] [--repeats 3]
//               [--memory-limit 1G] [--threads 0] [--unseen-cells off]
//               [--json FILE]
//
// --unseen-cells off: the cut's rule before unseen cells
// (ProbeConfig::unseen_cells), which traces no shadow rays from the ground.
// Prints, per store x material (diffuse, glass) x ray count, the median probe
// time over the repeats, rays/s, pages read, bytes read, cache peak, cells
// marked and peak RSS; --json writes the same rows.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <tbb/global_control.h>

#include "core/system.h"
#include "probe/probe.h"
#include "scene/scene.h"
#include "streaming/octree_store.h"

using namespace raylod;

namespace {

Scene bench_scene(MaterialType type) {
  auto s = default_scene();
  Scene scene = s.value();
  scene.materials[size_t(scene.objects[0].material)].type = type;
  scene.materials[size_t(scene.objects[0].material)].ior = 1.5f;
  return scene;
}

std::vector<uint64_t> parse_list(const std::string& text) {
  std::vector<uint64_t> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stoull(item));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // Evicted pages are large, short-lived buffers: a fixed mmap threshold
  // returns them to the OS instead of leaving a fragmented heap behind (glibc
  // otherwise raises the threshold after the first large free), which keeps
  // the resident size within --memory-limit.
  mallopt(M_MMAP_THRESHOLD, 256 * 1024);
#endif
  std::vector<std::string> stores;
  std::vector<uint64_t> ray_counts{5000, 50000};
  int repeats = 3, threads = 0;
  uint64_t memory_limit = uint64_t(1) << 30;
  std::string json_path;
  bool unseen_cells = true;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) { std::fprintf(stderr, "bench_probe: %s needs a value\n", a.c_str()); std::exit(2); }
      return argv[++i];
    };
    if (a == "--rays") ray_counts = parse_list(value());
    else if (a == "--repeats") repeats = std::max(1, std::stoi(value()));
    else if (a == "--threads") threads = std::stoi(value());
    else if (a == "--json") json_path = value();
    else if (a == "--unseen-cells") {
      const std::string v = value();
      if (v != "on" && v != "off") {
        std::fprintf(stderr, "bench_probe: --unseen-cells takes on or off, not '%s'\n", v.c_str());
        return 1;
      }
      unseen_cells = v == "on";
    }
    else if (a == "--memory-limit") {
      auto v = parse_size(value());
      if (!v) { std::fprintf(stderr, "bench_probe: %s\n", v.status().message().c_str()); return 2; }
      memory_limit = *v;
    } else if (a == "-h" || a == "--help") {
      std::printf("usage: bench_probe STORE [STORE...] [--rays 5000,50000] [--repeats 3] [--memory-limit 1G] "
                  "[--threads 0] [--unseen-cells off] [--json FILE]\n");
      return 0;
    } else stores.push_back(a);
  }
  if (stores.empty()) { std::fprintf(stderr, "bench_probe: give at least one store (raylod build MESH)\n"); return 2; }
  // As raylod's main(): one thread limit for the process, which the probe uses.
  std::optional<tbb::global_control> parallelism;
  if (threads > 0) parallelism.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));

  // The page cache gets what the limit leaves after the node tables (opened
  // first) and a reserve for the hit records; computed once, before any run.
  std::vector<std::unique_ptr<OctreeStore>> opened_stores;
  for (const std::string& path : stores) {
    auto opened = OctreeStore::open(path);
    if (!opened) { std::fprintf(stderr, "bench_probe: %s\n", opened.status().message().c_str()); return 1; }
    opened_stores.push_back(std::move(opened.value()));
  }
  const uint64_t max_rays = *std::max_element(ray_counts.begin(), ray_counts.end());
  const uint64_t rss0 = current_rss_bytes();
  const uint64_t reserve = max_rays * 64 * 6 + (uint64_t(32) << 20);
  if (memory_limit <= rss0 + reserve) {
    std::fprintf(stderr, "bench_probe: --memory-limit is below the node tables (%s resident)\n", format_bytes(rss0).c_str());
    return 1;
  }
  const uint64_t cache_bytes = (memory_limit - rss0 - reserve) / 2;  // as raylod probe
  std::printf("memory limit %s, resident after opening the stores %s, page cache %s\n", format_bytes(memory_limit).c_str(),
              format_bytes(rss0).c_str(), format_bytes(cache_bytes).c_str());
  std::string json = "[\n";
  bool first = true;
  std::printf("%-24s %-8s %7s %9s %8s %8s %10s %8s %10s %7s %10s %10s %9s %10s\n", "store", "material", "rays",
              "median_s", "trace_s", "cut_s", "rays/s", "gshadow", "visits/ray", "pages", "bytes_read", "cache_peak", "cells", "peak_rss");
  for (size_t si = 0; si < stores.size(); ++si) {
    const std::string& path = stores[si];
    const OctreeStore& store = *opened_stores[si];
    ProbeStore ps{&store, path};
    for (MaterialType type : {MaterialType::Diffuse, MaterialType::Glass}) {
      const Scene scene = bench_scene(type);
      const ProbeObject object{0, scene.objects[0].transform, scene.objects[0].material};
      for (uint64_t rays : ray_counts) {
        ProbeConfig config;
        config.rays = rays;
        config.seed = 1;
        config.cache_bytes = cache_bytes;
        config.unseen_cells = unseen_cells;
        std::vector<double> seconds;
        ProbeResult last;
        for (int r = 0; r < repeats; ++r) {
          const auto t0 = std::chrono::steady_clock::now();
          auto result = run_probe(scene, std::span<const ProbeStore>(&ps, 1), std::span<const ProbeObject>(&object, 1),
                                  config);
          const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          if (!result) { std::fprintf(stderr, "bench_probe: %s\n", result.status().message().c_str()); return 1; }
          seconds.push_back(s);
          last = std::move(result.value());
        }
        std::sort(seconds.begin(), seconds.end());
        const double median = seconds[seconds.size() / 2];
        const uint64_t all_rays = last.counters["rays_primary"] + last.counters["rays_reflection"] +
                                  last.counters["rays_refraction"];
        const uint64_t peak = peak_rss_bytes();
        std::printf("%-24s %-8s %7llu %9.3f %8.3f %8.3f %10.0f %8llu %10.2f %7llu %10s %10s %9zu %10s\n",
                    std::filesystem::path(path).filename().string().c_str(), to_string(type),
                    static_cast<unsigned long long>(rays), median, last.trace_seconds, last.cut_seconds,
                    double(all_rays) / last.trace_seconds,
                    static_cast<unsigned long long>(last.counters["rays_ground_shadow"]), double(last.counters["page_visits"]) / double(all_rays),
                    static_cast<unsigned long long>(last.counters["pages_read"]),
                    format_bytes(last.counters["bytes_read"]).c_str(),
                    format_bytes(last.counters["cache_peak_bytes"]).c_str(), last.cuts[0].cells.size(),
                    format_bytes(peak).c_str());
        std::fflush(stdout);
        char row[1024];
        std::snprintf(row, sizeof row,
                      "%s  {\"store\": \"%s\", \"material\": \"%s\", \"test_rays\": %llu, \"rays_traced\": %llu, "
                      "\"median_seconds\": %.6f, \"trace_seconds\": %.6f, \"cut_seconds\": %.6f, \"pages_read\": %llu, "
                      "\"bytes_read\": %llu, \"cache_peak_bytes\": %llu, \"cache_bytes\": %llu, \"cells_marked\": %zu, "
                      "\"peak_rss_bytes\": %llu, \"memory_limit\": %llu, \"repeats\": %d}",
                      first ? "" : ",\n", path.c_str(), to_string(type), static_cast<unsigned long long>(rays),
                      static_cast<unsigned long long>(all_rays), median, last.trace_seconds, last.cut_seconds,
                      static_cast<unsigned long long>(last.counters["pages_read"]),
                      static_cast<unsigned long long>(last.counters["bytes_read"]),
                      static_cast<unsigned long long>(last.counters["cache_peak_bytes"]),
                      static_cast<unsigned long long>(config.cache_bytes), last.cuts[0].cells.size(),
                      static_cast<unsigned long long>(peak), static_cast<unsigned long long>(memory_limit), repeats);
        json += row;
        first = false;
      }
    }
  }
  json += "\n]\n";
  if (!json_path.empty()) {
    std::ofstream f(json_path);
    f << json;
    if (!f) { std::fprintf(stderr, "bench_probe: cannot write %s\n", json_path.c_str()); return 1; }
  }
  return 0;
}
