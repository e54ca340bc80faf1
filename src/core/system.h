// Process and machine facts: memory, sizes, temp-file-and-rename output.
#pragma once

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "core/status.h"

namespace raylod {

// Peak resident set size of this process in bytes (VmHWM), 0 if unknown.
uint64_t peak_rss_bytes();
// Current resident set size in bytes (VmRSS), 0 if unknown.
uint64_t current_rss_bytes();
// Physical memory of the machine in bytes.
uint64_t physical_memory_bytes();

// While one lives, memory this process touches for the first time is not
// backed by transparent huge pages (Linux: prctl PR_SET_THP_DISABLE; nothing
// elsewhere). Embree advises huge pages for its BVH build blocks, and the
// kernel then zeroes every 2 MiB page on its first touch, most of which the
// build never uses: on a 9.4M-triangle mesh the build took 2.0 s instead of
// 2.8 to 3.4 s without them, and tracing the finished BVH was no slower.
class ScopedSmallPages {
 public:
  ScopedSmallPages();
  ~ScopedSmallPages();
  ScopedSmallPages(const ScopedSmallPages&) = delete;
  ScopedSmallPages& operator=(const ScopedSmallPages&) = delete;

 private:
  bool changed_ = false;  // the process allowed huge pages before
};

// While one lives (the first of several nested or concurrent ones decides),
// memory this process frees stays with the allocator (glibc: large blocks
// come from the heap rather than their own mappings, and the heap is not
// trimmed), so a stage that allocates and frees the same large blocks over
// and over touches fresh pages once, not on every call. When the last one
// goes, glibc's limits are set back and free memory is returned to the
// system (malloc_trim). Draco's encoder sizes a symbol histogram by the
// quantisation range on every call (128 MiB at 25 bits); see draco_io.cpp.
// Limits: it acts on the whole process while it lives; glibc's per-thread
// arenas still map a block larger than their 64 MiB heaps, so blocks that
// large allocated on worker threads gain less (measured on the 100M glass
// view's 10-part encode: 1.16M -> 0.68M page faults, not all of them); and
// "set back" means glibc's default values, which also ends its adaptive
// mmap threshold (and overrides GLIBC_TUNABLES' malloc settings) for the
// rest of the process.
class ScopedKeptFreeMemory {
 public:
  ScopedKeptFreeMemory();
  ~ScopedKeptFreeMemory();
  ScopedKeptFreeMemory(const ScopedKeptFreeMemory&) = delete;
  ScopedKeptFreeMemory& operator=(const ScopedKeptFreeMemory&) = delete;
};

// The first instruction set extension this build was compiled to use
// (CMake's RAYLOD_X86_LEVEL) that the CPU running it lacks, e.g. "sse4.2";
// nullptr when the CPU has them all, or the build asks for none.
const char* missing_cpu_feature();

// Parses a size in bytes: a positive whole number with an optional unit,
// "1000000", "512M", "2G", "1GiB" (B, K, M, G, T and their KB/KiB spellings,
// any case; powers of 1024). Fractions ("1.5G", "0.5"), signs, exponents, 0
// and sizes past 2^64 - 1 bytes are errors that quote the text.
StatusOr<uint64_t> parse_size(const std::string& text);
// Formats bytes for people: "1.50 GiB".
std::string format_bytes(uint64_t bytes);

// Checks, without opening it, that path names a regular file (symbolic links
// followed): opening a FIFO blocks until a writer comes, a device such as
// /dev/zero never ends, and a directory is not data. The error names the path
// and what it is instead: "f.ply: is a named pipe (FIFO), not a regular file",
// "d: is a directory, not a regular file", "m.ply: no such file".
Status check_regular_file(const std::filesystem::path& path);
// What a file of this st_mode is, for the messages above: "is a directory,
// not a regular file", ...; empty for a regular file.
std::string not_regular_file_text(unsigned mode);

// A file a command reads or writes, and what it is to the command ("the
// scene file", "-o", "--stats-json"), for check_outputs_apart.
struct FileRole {
  std::filesystem::path path;
  std::string role;
};
// Refuses outputs that would replace one of the inputs or each other: the
// same file (device and inode, through links and other spellings of the
// path) or, for files that do not exist yet, the same absolute path. An
// atomic write would otherwise rename its result over the input it is
// still reading, e.g. `raylod build MESH -o MESH`.
Status check_outputs_apart(const std::vector<FileRole>& outputs, const std::vector<FileRole>& inputs);

// Output written atomically: write to a temporary sibling, fsync, rename over
// the destination on commit(). Destroying without commit() removes the
// temporary, so a failure never leaves a half-written file under the real name.
// A process ended by SIGTERM, SIGINT or SIGHUP (mpirun ending the other ranks
// of a failed job, Ctrl-C) removes its live temporaries first (a handler is
// installed for those signals whose action is the default); one killed
// outright (SIGKILL) leaves them to remove_stale_temporaries.
// Temporaries are named DEST.tmp-PID@HOST-N-R: the process and the machine
// (hostname, '-' and other characters than letters, digits, '.' and '_'
// made '_'), so that processes of several machines writing to one shared
// folder (raylod under mpirun) never take each other's temporaries for a
// dead process's.
// A DEST name too long to take that suffix within a file name's 255 bytes
// is shortened first (temporary_stem).
const std::string& process_tag();  // "PID@HOST"
// The part of a temporary's name before its suffix (".tmp-PID@HOST-N-R",
// ".runs-PID", up to 127 bytes with a long host name): `filename` itself, or
// where longer than 127 bytes its first 110 bytes, '~' and 16 hex digits of a
// hash of the whole name, so that every writer and cleaner of one
// destination agrees on it.
std::string temporary_stem(const std::string& filename);
// Removes DEST.tmp-PID@HOST-* files of this machine left by processes that
// no longer exist (a kill -9 during an atomic write), and such folders with
// everything in them (AtomicDirectory's); returns how many. AtomicOutput
// and AtomicDirectory call it for their destination.
size_t remove_stale_temporaries(const std::filesystem::path& destination);
// True if `filename` is an atomic write's temporary (NAME.tmp-PID@HOST-...,
// nested ones included, or NAME.tmp-PID-... of older versions) whose process,
// of this machine, no longer exists.
bool is_dead_process_temporary(const std::string& filename);

// Whether `path` (through symlinks) exists and is neither a regular file nor
// a directory: a device such as /dev/null, a FIFO, a socket, /dev/stdout's
// terminal or pipe. Such an output is written into, never replaced
// (AtomicOutput).
bool is_pass_through_output(const std::filesystem::path& path);

// A file of this process's own, not a temporary of AtomicOutput's (a staged
// simplified mesh, a link to a cached one), that SIGTERM, SIGINT or SIGHUP
// removes as they remove AtomicOutput's temporaries while it is registered.
// Returns the slot, or -1 if every slot is taken (the file is then left to
// the next run's clean-up); release_scratch_file gives the slot back.
int register_scratch_file(const std::filesystem::path& path);
void release_scratch_file(int& slot);

// An output written whole or not at all: to a temporary, then renamed over
// the destination. A symlink is followed to the file it names, which is
// replaced in its own directory (the link stays). A destination that exists
// and is neither a regular file nor a directory (a device such as
// /dev/null, a FIFO, /dev/stdout's terminal or pipe) is never replaced: the
// temporary, then in the system's temporary directory, is copied into it.
class AtomicOutput {
 public:
  explicit AtomicOutput(std::filesystem::path destination);
  ~AtomicOutput();
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;

  // Path to write to (a temporary name beside the file replaced).
  const std::filesystem::path& temp_path() const { return temp_; }
  const std::filesystem::path& destination() const { return dest_; }
  // fsyncs the temporary and renames it to the destination (or copies it
  // into a device, FIFO or socket, and removes it).
  Status commit();

 private:
  std::filesystem::path dest_, temp_;
  std::filesystem::path target_;  // the file renamed over: dest_, or the file its symlinks name
  bool pass_through_ = false;     // dest_ is a device, FIFO or socket
  bool committed_ = false;
  int slot_ = -1;  // in the signal handler's table of live temporaries
};

// A folder of outputs written whole or not at all, as AtomicOutput writes a
// file: its files go into a temporary folder beside the destination,
// DEST.tmp-PID@HOST-N-R (made by create(), not its parents), and commit()
// puts that folder in the destination's place. A destination that exists,
// which the caller has judged may be replaced, is exchanged with it in one
// rename (Linux renameat2 RENAME_EXCHANGE; elsewhere, or on a file system
// without it, moved aside to a temporary name first) and then removed.
// Destroying without commit() removes the temporary folder and everything
// in it; so does SIGTERM, SIGINT or SIGHUP while it lives (the handler
// AtomicOutput installs), and one left by a process killed outright is
// removed by the next AtomicDirectory (or remove_stale_temporaries) of the
// same destination. Symlinks: a destination that is a symlink to a folder
// is resolved, and the folder it names is replaced (the link stays).
class AtomicDirectory {
 public:
  explicit AtomicDirectory(std::filesystem::path destination);
  ~AtomicDirectory();
  AtomicDirectory(const AtomicDirectory&) = delete;
  AtomicDirectory& operator=(const AtomicDirectory&) = delete;

  // Makes the temporary folder; a failure names the destination.
  Status create();
  // The folder to write into (beside the folder replaced).
  const std::filesystem::path& temp_path() const { return temp_; }
  // The folder replaced: the destination, or the folder its symlinks name.
  const std::filesystem::path& target() const { return target_; }
  // Renames the temporary folder to the destination, exchanging it with
  // the folder there if there is one, which is then removed. The folder
  // replaced gives the new one its permissions.
  Status commit();
  // After commit(): empty, or what is left of the folder replaced where it
  // could not be removed whole (a file in it that may not be deleted), for
  // the caller to warn about.
  const std::string& leftover() const { return leftover_; }

 private:
  std::filesystem::path dest_, target_, temp_;
  std::string leftover_;
  bool created_ = false, committed_ = false;
  int slot_ = -1;  // in the signal handler's table of live temporaries
};

// raylod's cache directory: $RAYLOD_CACHE_DIR, else $XDG_CACHE_HOME/raylod,
// else ~/.cache/raylod, else (no HOME) raylod-cache in temporary_folder()
// (created on demand by the callers).
std::filesystem::path default_cache_dir();
// The checks every output file gets before any work: a name given, not a
// directory, a folder that exists, a file name of at most 255 bytes, and a
// folder this process can create files in (devices and FIFOs, written in
// place, pass the last two). `role` names the output in the message
// ("PATH: the cut (-o): directory D does not exist").
Status check_output_path(const std::filesystem::path& path, const std::string& role);
// Whether this process can create files in `dir` (a probe file, removed at
// once): a permission check that also sees read-only mounts and immutable
// folders.
bool folder_is_writable(const std::filesystem::path& dir);
// The folder for scratch files: $TMPDIR where it names an existing folder,
// else /tmp (std::filesystem::temp_directory_path throws for a TMPDIR that
// does not exist).
std::filesystem::path temporary_folder();

// Writes bytes to out's temporary (created or truncated) and closes it; a
// failure is a write_failed status naming the destination and the system's
// reason. The caller commits.
Status write_temporary(const AtomicOutput& out, std::string_view bytes);
// The same for bytes in pieces, written in order; between(i), if given, runs
// once piece i is flushed to the file (a fault point, core/fault_point.h).
Status write_temporary(const AtomicOutput& out, std::initializer_list<std::string_view> pieces,
                       void (*between)(size_t) = nullptr);
// Writes text to path atomically (AtomicOutput).
Status write_file_atomic(const std::filesystem::path& path, const std::string& text);

// FNV-1a 64-bit hash, for keys and content fingerprints (not security).
uint64_t fnv1a64(const void* data, size_t bytes, uint64_t seed = 0xcbf29ce484222325ull);

}  // namespace raylod
