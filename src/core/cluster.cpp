// MPI behind cluster.h; without RAYLOD_WITH_MPI, one process.
#include "core/cluster.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <climits>
#include <cstdlib>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>
#include <thread>

#if RAYLOD_WITH_MPI
// The C API only (Open MPI's and MPICH's headers add C++ bindings otherwise).
#define OMPI_SKIP_MPICXX 1
#define MPICH_SKIP_MPICXX 1
#include <mpi.h>
#endif

namespace raylod::cluster {

namespace {

struct World {
  int rank = 0, size = 1;
  bool mpi = false;          // MPI_Init ran
  bool multiple = false;     // MPI_THREAD_MULTIPLE provided
  bool enlisted = false;
  bool agreed = false;       // a failure was agreed among the ranks
  uint64_t collectives = 0;  // collectives this rank entered
  std::FILE* errors = stderr;
};
World& world() {
  static World w;
  return w;
}

#if RAYLOD_WITH_MPI
// Started by mpirun (Open MPI, or a PMI launcher): only then is MPI started,
// so that a plain `raylod ...` never needs an MPI runtime.
bool launched_by_mpirun() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE"})
    if (std::getenv(v)) return true;
  return false;
}

// Waits for a non-blocking MPI call without spinning a core: tests it, and
// sleeps between tests (up to 2 ms once the wait is long).
void wait_lazily(MPI_Request& request) {
  int done = 0;
  auto nap = std::chrono::microseconds(50);
  for (;;) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    std::this_thread::sleep_for(nap);
    nap = std::min(nap * 2, std::chrono::microseconds(2000));
  }
}

// Byte counts and displacements as MPI's ints.
bool fits_int(uint64_t n) { return n <= uint64_t(INT_MAX); }
#endif

}  // namespace

Session::Session(int& argc, char**& argv) {
#if RAYLOD_WITH_MPI
  if (!launched_by_mpirun()) return;
  World& w = world();
  int provided = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_MULTIPLE, &provided);
  w.mpi = true;
  w.multiple = provided >= MPI_THREAD_MULTIPLE;
  MPI_Comm_rank(MPI_COMM_WORLD, &w.rank);
  MPI_Comm_size(MPI_COMM_WORLD, &w.size);
  if (w.size > 1 && w.rank != 0) {
    // Rank 0 speaks for the job: the others' output goes to /dev/null, their
    // own errors (error_output()) to the terminal.
    std::fflush(stdout);
    std::fflush(stderr);
    const int saved = ::dup(2);
    if (saved >= 0) w.errors = ::fdopen(saved, "w");
    if (!w.errors) w.errors = stderr;
    const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (null >= 0) {
      ::dup2(null, 1);
      ::dup2(null, 2);
      ::close(null);
    }
  }
#else
  (void)argc;
  (void)argv;
#endif
}

Session::~Session() {
#if RAYLOD_WITH_MPI
  if (world().mpi) {
    std::fflush(world().errors);
    MPI_Finalize();
  }
#endif
}

int rank() { return world().rank; }
int size() { return world().size; }
bool built_with_mpi() { return RAYLOD_WITH_MPI != 0; }
void enlist() { world().enlisted = true; }
bool enlisted() { return world().enlisted; }
bool failure_agreed() { return world().agreed; }
std::FILE* error_output() { return world().errors; }

std::pair<uint64_t, uint64_t> share(uint64_t count, int r, int n) {
  const uint64_t base = count / uint64_t(n), extra = count % uint64_t(n);
  const uint64_t begin = uint64_t(r) * base + std::min<uint64_t>(uint64_t(r), extra);
  return {begin, begin + base + (uint64_t(r) < extra ? 1 : 0)};
}

Status agree(const Status& mine) {
  World& w = world();
  if (w.size == 1) return mine;
  ++w.collectives;
#if RAYLOD_WITH_MPI
  // The lowest failing rank and whether every rank failed (the minimum of
  // -failing is minus the highest), then the lowest's message to everybody.
  const int failing = mine.is_ok() ? w.size : w.rank;
  int both[2] = {failing, -failing}, reduced[2] = {w.size, -w.size};
  MPI_Request request;
  MPI_Iallreduce(both, reduced, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD, &request);
  wait_lazily(request);
  const int lowest = reduced[0];
  const bool every_rank_failed = -reduced[1] < w.size;
  if (lowest == w.size) return Status::ok();
  std::string message = mine.is_ok() ? std::string() : mine.message();
  uint64_t length = message.size();
  MPI_Ibcast(&length, 1, MPI_UINT64_T, lowest, MPI_COMM_WORLD, &request);
  wait_lazily(request);
  message.resize(length);
  if (fits_int(length)) {
    MPI_Ibcast(message.data(), int(length), MPI_CHAR, lowest, MPI_COMM_WORLD, &request);
    wait_lazily(request);
  }
  w.agreed = true;
  // A failure of some ranks only says which (the lowest): a node's disk or
  // memory, not the input, is then the likely cause.
  const std::string which = "rank " + std::to_string(lowest) + " of " + std::to_string(w.size);
  if (w.rank == lowest) return every_rank_failed ? mine : mine.with_context(which);
  return Status::error(every_rank_failed ? message : which + ": " + message);
#else
  return mine;
#endif
}

std::optional<Status> settle_failure(const Status& status, const std::string& prefix) {
  World& w = world();
  if (w.size == 1 || !w.enlisted) return status;
  Status shown = status;
  if (!w.agreed) {
    if (w.collectives == 0) {
      shown = agree(status);
    } else {
      abort_job(prefix + "rank " + std::to_string(w.rank) + " of " + std::to_string(w.size) + ": " + status.message(), 1);
    }
  }
  if (w.rank != 0) return std::nullopt;
  return shown;
}

void abort_job(const std::string& message, int code) {
  World& w = world();
  std::fprintf(w.errors, "%s\n", message.c_str());
  std::fflush(w.errors);
#if RAYLOD_WITH_MPI
  if (w.mpi) MPI_Abort(MPI_COMM_WORLD, code);
#endif
  std::exit(code);
}

std::vector<std::string> gather(const std::string& mine) {
  World& w = world();
  if (w.size == 1) return {mine};
  ++w.collectives;
#if RAYLOD_WITH_MPI
  uint64_t length = mine.size();
  std::vector<uint64_t> lengths(w.rank == 0 ? size_t(w.size) : 0);
  MPI_Request request;
  MPI_Igather(&length, 1, MPI_UINT64_T, lengths.data(), 1, MPI_UINT64_T, 0, MPI_COMM_WORLD, &request);
  wait_lazily(request);
  std::vector<std::string> out;
  std::vector<int> counts, displs;
  std::string all;
  if (w.rank == 0) {
    uint64_t total = 0;
    for (uint64_t n : lengths) {
      counts.push_back(int(n));
      displs.push_back(int(total));
      total += n;
      if (!fits_int(n) || !fits_int(total)) {
        std::fprintf(w.errors, "raylod: error: gathering %llu bytes on rank 0 is more than MPI's int counts hold\n",
                     static_cast<unsigned long long>(total));
        MPI_Abort(MPI_COMM_WORLD, 1);
      }
    }
    all.resize(total);
  } else if (!fits_int(length)) {
    std::fprintf(w.errors, "raylod: error: rank %d cannot send %llu bytes (more than MPI's int counts)\n", w.rank,
                 static_cast<unsigned long long>(length));
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  MPI_Igatherv(mine.data(), int(length), MPI_CHAR, all.data(), counts.data(), displs.data(), MPI_CHAR, 0,
               MPI_COMM_WORLD, &request);
  wait_lazily(request);
  if (w.rank == 0)
    for (int r = 0; r < w.size; ++r) out.push_back(all.substr(size_t(displs[size_t(r)]), size_t(counts[size_t(r)])));
  return out;
#else
  return {mine};
#endif
}

std::vector<std::string> allgather(const std::string& mine) {
  World& w = world();
  if (w.size == 1) return {mine};
  std::vector<std::string> parts = gather(mine);
  std::string packed;
  if (w.rank == 0)
    for (const std::string& p : parts) packed += to_bytes(uint64_t(p.size())) + p;
  broadcast(packed);
  parts.clear();
  for (size_t at = 0; at < packed.size();) {
    const uint64_t n = from_bytes<uint64_t>(packed, at);
    parts.push_back(packed.substr(at + 8, n));
    at += 8 + n;
  }
  return parts;
}

void broadcast(std::string& data) {
  World& w = world();
  if (w.size == 1) return;
  ++w.collectives;
#if RAYLOD_WITH_MPI
  uint64_t length = data.size();
  MPI_Request request;
  MPI_Ibcast(&length, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD, &request);
  wait_lazily(request);
  data.resize(length);
  // In pieces of at most 1 GiB: MPI counts are ints.
  for (uint64_t at = 0; at < length;) {
    const uint64_t n = std::min<uint64_t>(length - at, uint64_t(1) << 30);
    MPI_Ibcast(data.data() + at, int(n), MPI_CHAR, 0, MPI_COMM_WORLD, &request);
    wait_lazily(request);
    at += n;
  }
#endif
}

void barrier() {
  World& w = world();
  if (w.size == 1) return;
  ++w.collectives;
#if RAYLOD_WITH_MPI
  MPI_Request request;
  MPI_Ibarrier(MPI_COMM_WORLD, &request);
  wait_lazily(request);
#endif
}

// The queue: rank 0 holds the counter; with MPI_THREAD_MULTIPLE a thread of
// rank 0 answers requests (tag 1: "next", tag 2: "I stop") on a communicator
// of the queue's own.
struct WorkQueue::State {
  uint64_t count = 0;
  bool dynamic = false;
  std::atomic<bool> stopped{false};
  bool done = false;  // this rank was told there is no more
  uint64_t round_robin = 0;
  // Rank 0's ledger: rank r's block [next[r], end[r]) of what is left.
  std::mutex mutex;
  std::vector<uint64_t> next, end;
#if RAYLOD_WITH_MPI
  MPI_Comm comm = MPI_COMM_NULL;
  std::thread server;
#endif

  void deal(int ranks) {
    next.resize(size_t(ranks));
    end.resize(size_t(ranks));
    for (int r = 0; r < ranks; ++r) std::tie(next[size_t(r)], end[size_t(r)]) = share(count, r, ranks);
  }
  // Rank 0's next index for `rank` (itself or another): the next of its own
  // block; when that is used up, the last of the block with the most left.
  int64_t take(int rank) {
    if (stopped.load()) return -1;
    std::lock_guard lock(mutex);
    const size_t r = size_t(rank);
    if (next[r] < end[r]) return int64_t(next[r]++);
    size_t most = r;
    for (size_t q = 0; q < next.size(); ++q)
      if (end[q] - next[q] > end[most] - next[most]) most = q;
    if (next[most] == end[most]) return -1;
    return int64_t(--end[most]);
  }
};

WorkQueue::WorkQueue(uint64_t count) : state_(std::make_unique<State>()) {
  World& w = world();
  State& s = *state_;
  s.count = count;
  s.round_robin = uint64_t(w.rank);
  s.deal(w.size);
  if (w.size == 1) return;
#if RAYLOD_WITH_MPI
  s.dynamic = w.multiple;
  ++w.collectives;
  MPI_Comm_dup(MPI_COMM_WORLD, &s.comm);
  if (s.dynamic && w.rank == 0) {
    s.server = std::thread([&s, others = w.size - 1] {
      // Until every other rank has been told "no more" (or said it stops).
      int finished = 0;
      auto nap = std::chrono::microseconds(50);
      while (finished < others) {
        int flag = 0;
        MPI_Status st;
        MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, s.comm, &flag, &st);
        if (!flag) {
          std::this_thread::sleep_for(nap);
          nap = std::min(nap * 2, std::chrono::microseconds(1000));
          continue;
        }
        nap = std::chrono::microseconds(50);
        char none = 0;
        MPI_Recv(&none, 1, MPI_CHAR, st.MPI_SOURCE, st.MPI_TAG, s.comm, MPI_STATUS_IGNORE);
        if (st.MPI_TAG == 2) {
          // A rank failed: nobody gets more work; it waits for no answer.
          s.stopped.store(true);
          ++finished;
          continue;
        }
        const int64_t i = s.take(st.MPI_SOURCE);
        MPI_Send(&i, 1, MPI_INT64_T, st.MPI_SOURCE, 1, s.comm);
        if (i < 0) ++finished;
      }
    });
  }
#endif
}

WorkQueue::~WorkQueue() {
#if RAYLOD_WITH_MPI
  State& s = *state_;
  if (s.comm == MPI_COMM_NULL) return;
  // A rank that leaves early still lets the server finish.
  if (s.dynamic && world().rank != 0 && !s.done) stop();
  if (s.server.joinable()) s.server.join();
  MPI_Comm_free(&s.comm);
#endif
}

bool WorkQueue::dynamic() const { return state_->dynamic; }

std::optional<uint64_t> WorkQueue::next() {
  World& w = world();
  State& s = *state_;
  if (s.done) return std::nullopt;
  if (w.size == 1 || (w.rank == 0 && s.dynamic)) {
    const int64_t i = s.take(0);
    if (i < 0) s.done = true;
    return i < 0 ? std::nullopt : std::optional<uint64_t>(uint64_t(i));
  }
  if (!s.dynamic) {
    if (s.stopped.load() || s.round_robin >= s.count) {
      s.done = true;
      return std::nullopt;
    }
    const uint64_t i = s.round_robin;
    s.round_robin += uint64_t(w.size);
    return i;
  }
#if RAYLOD_WITH_MPI
  char none = 0;
  int64_t i = -1;
  MPI_Send(&none, 1, MPI_CHAR, 0, 1, s.comm);
  MPI_Request request;
  MPI_Irecv(&i, 1, MPI_INT64_T, 0, 1, s.comm, &request);
  wait_lazily(request);
  if (i < 0) {
    s.done = true;
    return std::nullopt;
  }
  return uint64_t(i);
#else
  return std::nullopt;
#endif
}

void WorkQueue::stop() {
  World& w = world();
  State& s = *state_;
  s.stopped.store(true);
  if (s.done) return;
  s.done = true;
#if RAYLOD_WITH_MPI
  if (s.dynamic && w.size > 1 && w.rank != 0) {
    char none = 0;
    MPI_Send(&none, 1, MPI_CHAR, 0, 2, s.comm);
  }
#else
  (void)w;
#endif
}

}  // namespace raylod::cluster
