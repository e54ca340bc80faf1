#include "pipeline/baselines.h"

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <unordered_map>

#include <meshoptimizer.h>

namespace raylod {
namespace {

// meshoptimizer's allocations, counted through meshopt_setAllocator, so the
// report can state the simplifier's own peak memory, not just the process's.
// Each block carries its size in a 16-byte header.
std::atomic<uint64_t> g_live{0}, g_peak{0};

void* counting_allocate(size_t bytes) {
  auto* p = static_cast<unsigned char*>(std::malloc(bytes + 16));
  if (!p) return nullptr;
  *reinterpret_cast<size_t*>(p) = bytes;
  uint64_t live = g_live.fetch_add(bytes) + bytes;
  uint64_t peak = g_peak.load();
  while (live > peak && !g_peak.compare_exchange_weak(peak, live)) {}
  return p + 16;
}

void counting_deallocate(void* ptr) {
  if (!ptr) return;
  auto* p = static_cast<unsigned char*>(ptr) - 16;
  g_live.fetch_sub(*reinterpret_cast<size_t*>(p));
  std::free(p);
}

}  // namespace

const char* to_string(Baseline b) {
  return b == Baseline::VertexClustering ? "vertex clustering (meshopt_simplifySloppy)"
                                         : "quadric edge collapse (meshopt_simplify)";
}

BaselineResult run_baseline(Baseline method, const TriangleMesh& input, uint64_t target_triangles) {
  static std::once_flag once;
  std::call_once(once, [] { meshopt_setAllocator(counting_allocate, counting_deallocate); });
  g_live = 0;
  g_peak = 0;

  BaselineResult r;
  std::vector<uint32_t> out(input.indices.size());
  const size_t target_indices = size_t(std::max<uint64_t>(target_triangles, 1)) * 3;
  auto t0 = std::chrono::steady_clock::now();
  size_t n = 0;
  float error = 0;
  if (method == Baseline::VertexClustering) {
    // target_error 1 = no error bound: the triangle count decides.
    n = meshopt_simplifySloppy(out.data(), input.indices.data(), input.indices.size(), &input.positions[0].x,
                               input.positions.size(), sizeof(Vec3), target_indices, 1.0f, &error);
  } else {
    n = meshopt_simplify(out.data(), input.indices.data(), input.indices.size(), &input.positions[0].x,
                         input.positions.size(), sizeof(Vec3), target_indices, 1.0f, 0, &error);
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.resize(n);
  r.peak_bytes = input.bytes() + out.size() * sizeof(uint32_t) + g_peak.load();

  // Keep only the vertices the result uses (smaller BVH input, honest render cost).
  std::vector<uint32_t> remap(input.positions.size(), UINT32_MAX);
  r.mesh.material = input.material;
  r.mesh.name = input.name + " (" + to_string(method) + ")";
  r.mesh.indices.reserve(out.size());
  for (uint32_t i : out) {
    if (remap[i] == UINT32_MAX) {
      remap[i] = uint32_t(r.mesh.positions.size());
      r.mesh.positions.push_back(input.positions[i]);
      if (!input.normals.empty()) r.mesh.normals.push_back(input.normals[i]);
    }
    r.mesh.indices.push_back(remap[i]);
  }
  return r;
}

}  // namespace raylod
