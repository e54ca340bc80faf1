// Running on several processes with MPI (`mpirun -np N raylod ...`): the
// only code that includes mpi.h (cluster.cpp). Built without MPI
// (RAYLOD_WITH_MPI off), or started without mpirun, this is one process:
// rank 0 of 1, every collective returns at once with the caller's own data.
//
// Every collective here waits lazily for the ranks to meet (a non-blocking
// MPI call tested every few hundred microseconds, with sleeps between): a
// rank waiting for the store build or for a slower rank does not spin a core
// that the busy rank on the same node needs. Once all have met, a large
// payload (gather, broadcast, gather_blocks) moves in blocking calls: Open
// MPI moves a large message only while a call polls it, and with naps
// between the tests a 4K frame's 50 MB took 0.15 s between two ranks.
//
// Failures: a command that works on several ranks calls enlist() first; its
// first collective on every rank is agree(). A rank that fails sooner (bad
// arguments, a views file) then meets the others in that agree() through
// cli::fail (settle_failure), so the job ends cleanly with one error, printed
// by rank 0. A failure at a stage boundary is agreed the same way. A rank
// that fails anywhere else ends the job with MPI_Abort, its error printed by
// itself.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <utility>
#include <functional>
#include <string>
#include <type_traits>
#include <vector>

#include "core/status.h"

namespace raylod::cluster {

// Starts MPI when the process was started by mpirun (and raylod was built
// with MPI); ends it when destroyed. One per process, in main.
class Session {
 public:
  Session(int& argc, char**& argv);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
};

int rank();
int size();
inline bool active() { return size() > 1; }
inline bool is_root() { return rank() == 0; }
// Whether raylod was built with MPI (RAYLOD_WITH_MPI).
bool built_with_mpi();

// Called by a command that works across ranks (run, render, probe), before
// anything it does can fail: its failures are then settled among the ranks.
void enlist();
bool enlisted();

// Collective, before any command runs: an error on every rank if some rank
// was started with other arguments than rank 0's (mpirun's `A : B` form;
// they would meet in different collectives and hang, or gather parts of
// different images). It leaves the ranks as if no collective had run, so a
// command's first failure settles as it otherwise would (settle_failure).
Status same_command_line(int argc, char** argv);

// Collective: OK on every rank if `mine` is OK on every rank, else the error
// of the lowest failing rank on every rank (its message), preceded by "rank
// R of N: " unless every rank failed. Marks the failure as agreed.
Status agree(const Status& mine);
bool failure_agreed();
// cli::fail's part: for an enlisted command on several ranks, settles a
// failure that was not agreed yet -- through agree() if no collective has
// run (the others meet it in their first agree()), else by ending the job
// (MPI_Abort, the error printed by this rank after `prefix`, naming the
// rank). Returns the error to print, or nullopt on ranks other than 0, which
// print nothing.
std::optional<Status> settle_failure(const Status& status, const std::string& prefix);

// Ends the whole job at once (MPI_Abort), after printing the line `message`
// from this rank; one process: exits with `code`.
[[noreturn]] void abort_job(const std::string& message, int code);

// Where this rank's messages go: stderr on rank 0; on the others, progress
// and log lines are dropped (their stdout and stderr are /dev/null after
// Session starts) and only error_output() reaches the terminal.
std::FILE* error_output();

// Collective: runs `step` on rank 0 first (a store build, a mesh written to
// the shared cache), the others waiting, then on the other ranks (which find
// its result); the ranks agree after each half.
template <class Step>
Status rank0_first(Step&& step) {
  Status s = is_root() ? step() : Status::ok();
  s = agree(s);
  if (!s || !active()) return s;
  return agree(is_root() ? Status::ok() : step());
}

// Collectives on byte strings (rank order). gather: every rank's string on
// rank 0 (empty elsewhere); allgather: on every rank; broadcast: rank 0's
// string to every rank.
std::vector<std::string> gather(const std::string& mine);
std::vector<std::string> allgather(const std::string& mine);
void broadcast(std::string& data);
void barrier();

// A run of `count` elements at element offset `first` of a buffer.
struct Block {
  uint64_t first = 0, count = 0;
};
// Collective: copies every rank's blocks of `buffer` (elements of
// `element_bytes`) into the same places of rank 0's buffer, without packing
// them: rank R's blocks are blocks_of(R), which every rank must compute
// alike, in increasing order, disjoint between ranks. A frame's tiles
// gathered row by row (render) go straight from each rank's image into rank
// 0's. The ranks first meet lazily; then the data moves in blocking calls.
// The buffer must hold every rank's blocks on rank 0, and this rank's on
// the others.
void gather_blocks(void* buffer, size_t element_bytes, const std::function<std::vector<Block>(int rank)>& blocks_of);
// gather_blocks' messages: `blocks` in order, in lists of at most `most`
// elements each (a block split where a list fills up).
std::vector<std::vector<Block>> split_blocks(std::span<const Block> blocks, uint64_t most);

// What Open MPI is told before MPI_Init when raylod chooses its transport:
// on one node (OMPI_COMM_WORLD_LOCAL_SIZE equal to OMPI_COMM_WORLD_SIZE),
// shared memory only (OMPI_MCA_pml=ob1, OMPI_MCA_btl=self,vader), which
// spares MPI_Init probing the network stacks (UCX, OFI). Nothing if the
// user chose a transport (OMPI_MCA_pml, _btl or _mtl set, as `mpirun --mca`
// does), the job spans nodes, it was not started by Open MPI's mpirun, or
// RAYLOD_MPI_AUTO_TRANSPORT=0. `env` reads a variable (nullptr if unset).
std::vector<std::pair<std::string, std::string>> single_node_transport(
    const std::function<const char*(const char*)>& env);

// Plain values as byte strings.
template <class T>
std::string to_bytes(const T& value) {
  static_assert(std::is_trivially_copyable_v<T>);
  return std::string(reinterpret_cast<const char*>(&value), sizeof(T));
}
template <class T>
T from_bytes(const std::string& bytes, size_t offset = 0) {
  static_assert(std::is_trivially_copyable_v<T>);
  T value{};
  if (offset + sizeof(T) <= bytes.size()) std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}
template <class T>
void broadcast_value(T& value) {
  std::string b = to_bytes(value);
  broadcast(b);
  value = from_bytes<T>(b);
}

// The share [begin, end) of `count` items rank `r` of `n` takes: contiguous
// and in rank order, the first count % n ranks one more.
std::pair<uint64_t, uint64_t> share(uint64_t count, int r, int n);

// Hands out the indices 0..count-1 to the ranks, one per request (a rank
// asks for the next when it is done with its last). Each rank starts with a
// contiguous block (share()) and takes it in increasing order, so that
// neighbouring items (an orbit's neighbouring views, which need mostly the
// same pages) run on one rank one after the other; a rank whose block is
// used up takes the last item of the block with the most left. Rank 0 keeps
// the ledger and answers the other ranks from a thread; without
// MPI_THREAD_MULTIPLE the indices are dealt round robin instead (rank r
// takes r, r + n, ...). One process takes them in order. Construction and
// destruction are collective.
// With ask_ahead, a rank other than 0 asks for its next index as soon as it
// is given one, so that the answer (a round trip to rank 0's thread, which
// naps up to a millisecond between looks) arrives while it works: for many
// small items (a frame's runs of tiles), where a rank asking 200 times took
// 0.2 s longer than asking 12 times. Each such rank then holds one index in
// reserve, which the others cannot take: not for a few large items (views).
class WorkQueue {
 public:
  explicit WorkQueue(uint64_t count, bool ask_ahead = false);
  ~WorkQueue();
  WorkQueue(const WorkQueue&) = delete;
  WorkQueue& operator=(const WorkQueue&) = delete;
  // The next index for this rank, or nullopt when every index is handed out
  // (or after stop()).
  std::optional<uint64_t> next();
  // This rank takes no more work (it failed); on rank 0, nobody gets more.
  void stop();
  bool dynamic() const;
  // How many indices have been handed out: on rank 0 of a dynamic queue, to
  // every rank (what a progress display of the whole job counts); elsewhere,
  // to this rank.
  uint64_t handed_out();

 private:
  std::optional<uint64_t> next_index();
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace raylod::cluster
