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

// Returns once every rank has called it, waiting lazily (the MPI part of
// barrier(); broadcast and gather_blocks meet this way before they move
// their payload in blocking calls).
void meet_lazily() {
  MPI_Request request;
  MPI_Ibarrier(MPI_COMM_WORLD, &request);
  wait_lazily(request);
}

// Byte counts and displacements as MPI's ints.
bool fits_int(uint64_t n) { return n <= uint64_t(INT_MAX); }
#endif

}  // namespace

Session::Session(int& argc, char**& argv) {
#if RAYLOD_WITH_MPI
  if (!launched_by_mpirun()) return;
  World& w = world();
  // On one node, shared memory (single_node_transport): MPI_Init and
  // MPI_Finalize 0.32 -> 0.15 s here, a 4K frame over 2 ranks 1.71x -> 1.78x
  // (README, "Running on a cluster").
  for (const auto& [name, value] : single_node_transport([](const char* v) { return std::getenv(v); }))
    ::setenv(name.c_str(), value.c_str(), 0);
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

std::vector<std::pair<std::string, std::string>> single_node_transport(
    const std::function<const char*(const char*)>& env) {
  const char* size = env("OMPI_COMM_WORLD_SIZE");
  const char* local = env("OMPI_COMM_WORLD_LOCAL_SIZE");
  if (!size || !local || std::string(size) != std::string(local)) return {};
  if (const char* off = env("RAYLOD_MPI_AUTO_TRANSPORT"); off && std::string(off) == "0") return {};
  for (const char* v : {"OMPI_MCA_pml", "OMPI_MCA_btl", "OMPI_MCA_mtl"})
    if (env(v)) return {};
  return {{"OMPI_MCA_pml", "ob1"}, {"OMPI_MCA_btl", "self,vader"}};
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

Status same_command_line(int argc, char** argv) {
  World& w = world();
  if (w.size == 1) return Status::ok();
  std::string mine;
  for (int i = 1; i < argc; ++i) mine.append(argv[i]).push_back('\0');
  std::string root = mine;
  broadcast(root);
  const Status agreed = agree(root == mine ? Status::ok()
                                           : Status::error("started with other arguments than rank 0's; under "
                                                           "mpirun every rank must run the same command line"));
  // Every rank met both collectives here, before any command.
  w.collectives = 0;
  w.agreed = false;
  return agreed;
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
  // Every rank's length to every rank, waited for lazily: once it is in,
  // every rank has arrived, and the payload moves at full speed (a blocking
  // call polls Open MPI's progress without the naps between tests, which
  // throttled a 4K frame's 50 MB from rank 1 to 0.15 s).
  uint64_t length = mine.size();
  std::vector<uint64_t> lengths(size_t(w.size));
  MPI_Request request;
  MPI_Iallgather(&length, 1, MPI_UINT64_T, lengths.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD, &request);
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
  MPI_Gatherv(mine.data(), int(length), MPI_CHAR, all.data(), counts.data(), displs.data(), MPI_CHAR, 0,
              MPI_COMM_WORLD);
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
  if (length == 0) return;
  // Every rank has arrived once a lazy barrier is through; then the payload
  // moves in blocking calls at full speed (as in gather).
  meet_lazily();
  // In pieces of at most 1 GiB: MPI counts are ints.
  for (uint64_t at = 0; at < length;) {
    const uint64_t n = std::min<uint64_t>(length - at, uint64_t(1) << 30);
    MPI_Bcast(data.data() + at, int(n), MPI_CHAR, 0, MPI_COMM_WORLD);
    at += n;
  }
#endif
}

std::vector<std::vector<Block>> split_blocks(std::span<const Block> blocks, uint64_t most) {
  most = std::max<uint64_t>(most, 1);
  std::vector<std::vector<Block>> out;
  uint64_t in_message = most;  // full: the first block starts a message
  for (Block b : blocks) {
    while (b.count > 0) {
      if (in_message == most) {
        out.emplace_back();
        in_message = 0;
      }
      const uint64_t n = std::min(b.count, most - in_message);
      out.back().push_back({b.first, n});
      in_message += n;
      b.first += n;
      b.count -= n;
    }
  }
  return out;
}

void gather_blocks(void* buffer, size_t element_bytes, const std::function<std::vector<Block>(int rank)>& blocks_of) {
  World& w = world();
  if (w.size == 1) return;
  ++w.collectives;
#if RAYLOD_WITH_MPI
  meet_lazily();
  MPI_Datatype element;
  MPI_Type_contiguous(int(element_bytes), MPI_BYTE, &element);
  MPI_Type_commit(&element);
  // One message's runs as an MPI type over the buffer (byte offsets).
  auto type_of = [&](const std::vector<Block>& runs) {
    std::vector<int> counts;
    std::vector<MPI_Aint> offsets;
    for (const Block& b : runs) {
      counts.push_back(int(b.count));
      offsets.push_back(MPI_Aint(b.first * element_bytes));
    }
    MPI_Datatype type;
    MPI_Type_create_hindexed(int(runs.size()), counts.data(), offsets.data(), element, &type);
    MPI_Type_commit(&type);
    return type;
  };
  // At most 1 GiB per message: MPI's counts and type sizes are ints.
  const uint64_t most = std::max<uint64_t>(1, (uint64_t(1) << 30) / element_bytes);
  constexpr int kTag = 7;
  std::vector<MPI_Datatype> types;
  std::vector<MPI_Request> requests;
  if (w.rank == 0) {
    for (int r = 1; r < w.size; ++r) {
      const std::vector<Block> blocks = blocks_of(r);
      for (const auto& runs : split_blocks(blocks, most)) {
        types.push_back(type_of(runs));
        requests.emplace_back();
        MPI_Irecv(buffer, 1, types.back(), r, kTag, MPI_COMM_WORLD, &requests.back());
      }
    }
  } else {
    const std::vector<Block> blocks = blocks_of(w.rank);
    for (const auto& runs : split_blocks(blocks, most)) {
      types.push_back(type_of(runs));
      requests.emplace_back();
      MPI_Isend(buffer, 1, types.back(), 0, kTag, MPI_COMM_WORLD, &requests.back());
    }
  }
  MPI_Waitall(int(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  for (MPI_Datatype& t : types) MPI_Type_free(&t);
  MPI_Type_free(&element);
#else
  (void)buffer;
  (void)element_bytes;
  (void)blocks_of;
#endif
}

void barrier() {
  World& w = world();
  if (w.size == 1) return;
  ++w.collectives;
#if RAYLOD_WITH_MPI
  meet_lazily();
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
  uint64_t taken = 0;  // indices this rank was given
  uint64_t round_robin = 0;
  // Rank 0's ledger: rank r's block [next[r], end[r]) of what is left.
  std::mutex mutex;
  std::vector<uint64_t> next, end;
#if RAYLOD_WITH_MPI
  MPI_Comm comm = MPI_COMM_NULL;
  std::thread server;
  // A rank's request sent and not yet waited for (ask_ahead), and where its
  // answer goes.
  bool ask_ahead = false, asked = false;
  MPI_Request answer = MPI_REQUEST_NULL;
  int64_t answered = -1;

  void ask() {
    char none = 0;
    MPI_Send(&none, 1, MPI_CHAR, 0, 1, comm);
    MPI_Irecv(&answered, 1, MPI_INT64_T, 0, 1, comm, &answer);
    asked = true;
  }
  // The answer to the request sent (-1: no more).
  int64_t wait_answer() {
    wait_lazily(answer);
    asked = false;
    return answered;
  }
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

WorkQueue::WorkQueue(uint64_t count, bool ask_ahead) : state_(std::make_unique<State>()) {
  World& w = world();
  State& s = *state_;
  s.count = count;
#if RAYLOD_WITH_MPI
  s.ask_ahead = ask_ahead;
#else
  (void)ask_ahead;
#endif
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

uint64_t WorkQueue::handed_out() {
  State& s = *state_;
  std::lock_guard lock(s.mutex);
  if (s.dynamic && world().rank == 0) {
    uint64_t left = 0;
    for (size_t r = 0; r < s.next.size(); ++r) left += s.end[r] - s.next[r];
    return s.count - left;
  }
  return s.taken;
}

std::optional<uint64_t> WorkQueue::next() {
  std::optional<uint64_t> i = next_index();
  if (i) {
    std::lock_guard lock(state_->mutex);
    ++state_->taken;
  }
  return i;
}

std::optional<uint64_t> WorkQueue::next_index() {
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
  if (!s.asked) s.ask();
  const int64_t i = s.wait_answer();
  if (i < 0) {
    s.done = true;  // rank 0 counted this rank as finished
    return std::nullopt;
  }
  if (s.ask_ahead) s.ask();
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
    // A request asked ahead is answered first; if the answer was "no more",
    // rank 0 has counted this rank as finished already.
    if (s.asked && s.wait_answer() < 0) return;
    char none = 0;
    MPI_Send(&none, 1, MPI_CHAR, 0, 2, s.comm);
  }
#else
  (void)w;
#endif
}

}  // namespace raylod::cluster
