// Memory the Draco encoder takes on top of the mesh it encodes, per triangle:
// the figure behind kDracoEncodeBytesPerTriangle (src/simplify/collapse.h),
// which the run's memory budget adds to a simplified mesh's estimate.
//
//   build/tools/bench_draco_memory [--side N] [--speed S]
//
// Encodes an N x N grid (2 N^2 triangles, (N+1)^2 vertices with normals, as a
// simplified mesh has about half as many vertices as triangles) with the
// options raylod's simplify uses, in a child process so that the peak
// resident size (VmHWM) is the encoder's alone, and prints the peak's growth
// over the resident size before encoding.
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>

#include "streaming/draco_io.h"

namespace {

long status_kib(const char* key) {
  std::ifstream f("/proc/self/status");
  std::string k;
  long v = 0;
  while (f >> k) {
    if (k == key) {
      f >> v;
      return v;
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int side = 2000, speed = 5;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--side" || a == "--speed") && i + 1 < argc) {
      (a == "--side" ? side : speed) = std::atoi(argv[++i]);
    } else {
      std::printf("usage: bench_draco_memory [--side N] [--speed S]\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (side < 2) side = 2;
  int fds[2];
  if (pipe(fds) != 0) return 1;
  const pid_t pid = fork();
  if (pid == 0) {
    using namespace raylod;
    IndexedMesh m;
    const uint32_t n = uint32_t(side);
    for (uint32_t y = 0; y <= n; ++y)
      for (uint32_t x = 0; x <= n; ++x) {
        m.positions.push_back(Vec3(float(x) * 1e-3f, float(y) * 1e-3f, 1e-4f * float((x * y) % 7)));
        m.normals.push_back(glm::normalize(Vec3(0.01f * float(x % 5), 0.01f * float(y % 3), 1.0f)));
      }
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x) {
        const uint32_t a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
        m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
      }
    const long before = status_kib("VmRSS:");
    DracoOptions o;  // as simplify_cut_to_draco: a position error target, normals by tolerance
    o.max_position_error = 1e-6;
    o.normal_bits = 0;
    o.max_normal_error = 0.01;
    o.speed = speed;
    auto encoded = encode_draco("grid.drc", m, o);
    const long peak = status_kib("VmHWM:");
    char line[256];
    std::snprintf(line, sizeof line, "%zu triangles, %zu vertices, speed %d: %s; encoder peak %.1f MiB over the mesh, %.1f bytes per triangle\n",
                  m.indices.size() / 3, m.positions.size(), speed,
                  encoded.is_ok() ? (std::to_string(encoded->bytes.size()) + " bytes").c_str() : "failed",
                  double(peak - before) / 1024.0, double(peak - before) * 1024.0 / double(m.indices.size() / 3));
    ssize_t w = write(fds[1], line, std::strlen(line));
    _exit(encoded.is_ok() && w > 0 ? 0 : 1);
  }
  close(fds[1]);
  char buf[512] = {};
  const ssize_t got = read(fds[0], buf, sizeof buf - 1);
  int status = 0;
  waitpid(pid, &status, 0);
  if (got > 0) std::fputs(buf, stdout);
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : 1;
}
