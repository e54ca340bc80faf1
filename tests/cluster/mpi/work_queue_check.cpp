// Run under mpirun by ctest (tests/CMakeLists.txt): every rank takes indices
// from one cluster::WorkQueue until none are left, and rank 0 checks what
// the ranks were given. Usage:
//   work_queue_check COUNT AHEAD STOP
// AHEAD 1: the queue asks ahead (WorkQueue's ask_ahead). STOP >= 0: the last
// rank stops after taking STOP indices, as a rank that fails does.
// Without STOP every index must be given to exactly one rank; with it, at
// most one, and the others must still end.
// Exit status 0 when every check holds; the failures are printed.
#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "core/cluster.h"

using namespace raylod;

int main(int argc, char** argv) {
  cluster::Session session(argc, argv);
  if (argc != 4) {
    std::fprintf(stderr, "usage: work_queue_check COUNT AHEAD STOP\n");
    return 2;
  }
  const uint64_t count = std::strtoull(argv[1], nullptr, 10);
  const bool ahead = std::atoi(argv[2]) != 0;
  const long stop_after = std::atol(argv[3]);
  const bool stops = stop_after >= 0 && cluster::rank() == cluster::size() - 1 && cluster::size() > 1;
  std::vector<uint64_t> mine;
  {
    cluster::WorkQueue queue(count, ahead);
    while (!(stops && long(mine.size()) == stop_after)) {
      const auto i = queue.next();
      if (!i) break;
      mine.push_back(*i);
      // Each index is some work, so that every rank takes some.
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    }
    if (stops) queue.stop();
  }
  std::string bytes(mine.size() * sizeof(uint64_t), '\0');
  if (!bytes.empty()) std::memcpy(bytes.data(), mine.data(), bytes.size());
  const std::vector<std::string> all = cluster::gather(bytes);
  if (!cluster::is_root()) return 0;
  int failures = 0;
  std::vector<int> given(count, 0);
  for (size_t r = 0; r < all.size(); ++r) {
    for (size_t k = 0; k + sizeof(uint64_t) <= all[r].size(); k += sizeof(uint64_t)) {
      const uint64_t i = cluster::from_bytes<uint64_t>(all[r], k);
      if (i >= count) {
        std::fprintf(stderr, "rank %zu was given %llu of %llu\n", r, (unsigned long long)i, (unsigned long long)count);
        ++failures;
        continue;
      }
      ++given[i];
    }
  }
  const bool every = stop_after < 0 || cluster::size() == 1;
  // With 100 us an index, each rank is busy with its own block long before
  // the others could take all of it.
  for (size_t r = 0; r < all.size(); ++r)
    if (every && count >= 100 * all.size() && all[r].empty()) {
      std::fprintf(stderr, "rank %zu took nothing\n", r);
      ++failures;
    }
  for (uint64_t i = 0; i < count; ++i)
    if (given[i] > 1 || (every && given[i] != 1)) {
      std::fprintf(stderr, "index %llu was given %d times\n", (unsigned long long)i, given[i]);
      ++failures;
    }
  std::printf("%zu ranks, %llu indices, ask ahead %d, stop %ld: %d failures\n", all.size(),
              (unsigned long long)count, int(ahead), stop_after, failures);
  return failures == 0 ? 0 : 1;
}
