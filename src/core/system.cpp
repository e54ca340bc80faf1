#include "core/system.h"


#include <fcntl.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <sys/stat.h>
#if defined(__linux__)
#include <sys/prctl.h>
#include <sys/syscall.h>
#endif
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cmath>
#include <csignal>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <mutex>
#include <random>
#include <sstream>
#include <vector>

namespace raylod {
namespace {

uint64_t read_status_kib(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const size_t n = std::char_traits<char>::length(key);
  while (std::getline(in, line)) {
    if (line.compare(0, n, key) == 0) return std::strtoull(line.c_str() + n, nullptr, 10) * 1024ull;
  }
  return 0;
}

}  // namespace

uint64_t peak_rss_bytes() { return read_status_kib("VmHWM:"); }
uint64_t current_rss_bytes() { return read_status_kib("VmRSS:"); }

ScopedSmallPages::ScopedSmallPages() {
#if defined(__linux__) && defined(PR_SET_THP_DISABLE)
  changed_ = prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0) == 0 && prctl(PR_SET_THP_DISABLE, 1, 0, 0, 0) == 0;
#endif
}

ScopedSmallPages::~ScopedSmallPages() {
#if defined(__linux__) && defined(PR_SET_THP_DISABLE)
  if (changed_) prctl(PR_SET_THP_DISABLE, 0, 0, 0, 0);
#endif
}

namespace {
std::mutex kept_free_mutex;
int kept_free_users = 0;
}  // namespace

ScopedKeptFreeMemory::ScopedKeptFreeMemory() {
#if defined(__GLIBC__)
  std::lock_guard<std::mutex> lock(kept_free_mutex);
  if (kept_free_users++ == 0) {
    mallopt(M_MMAP_MAX, 0);
    mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
  }
#endif
}

ScopedKeptFreeMemory::~ScopedKeptFreeMemory() {
#if defined(__GLIBC__)
  std::lock_guard<std::mutex> lock(kept_free_mutex);
  if (--kept_free_users == 0) {
    mallopt(M_MMAP_MAX, 65536);              // glibc's defaults
    mallopt(M_TRIM_THRESHOLD, 128 * 1024);
    malloc_trim(0);
  }
#endif
}

uint64_t physical_memory_bytes() {
  long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : (uint64_t(4) << 30);
}

const char* missing_cpu_feature() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  __builtin_cpu_init();
#if defined(__SSE3__)
  if (!__builtin_cpu_supports("sse3")) return "sse3";
#endif
#if defined(__SSSE3__)
  if (!__builtin_cpu_supports("ssse3")) return "ssse3";
#endif
#if defined(__SSE4_1__)
  if (!__builtin_cpu_supports("sse4.1")) return "sse4.1";
#endif
#if defined(__SSE4_2__)
  if (!__builtin_cpu_supports("sse4.2")) return "sse4.2";
#endif
#if defined(__POPCNT__)
  if (!__builtin_cpu_supports("popcnt")) return "popcnt";
#endif
#if defined(__AVX__)
  if (!__builtin_cpu_supports("avx")) return "avx";
#endif
#if defined(__AVX2__)
  if (!__builtin_cpu_supports("avx2")) return "avx2";
#endif
#if defined(__FMA__)
  if (!__builtin_cpu_supports("fma")) return "fma";
#endif
#endif
  return nullptr;
}

StatusOr<uint64_t> parse_size(const std::string& text) {
  const std::string quoted = "'" + text + "'";
  // Digits first: from_chars takes no sign, space, point or exponent, so
  // "0.5", "1e9", "+1G" and " 1G" stop early or fail and are rejected below
  // rather than truncated to some other size.
  uint64_t value = 0;
  const char* begin = text.data();
  const char* end = begin + text.size();
  auto [digits_end, ec] = std::from_chars(begin, end, value);
  if (digits_end == begin)
    return Status::error(quoted + " is not a size (expected a whole number of bytes with an optional K, M, G or T suffix, e.g. 512M or 2G)");
  if (ec == std::errc::result_out_of_range)
    return Status::error(quoted + " is too large (more than 2^64 - 1 bytes)");
  std::string unit(digits_end, end);
  for (auto& ch : unit) ch = char(std::toupper(static_cast<unsigned char>(ch)));
  int shift = 0;
  if (unit.empty() || unit == "B") shift = 0;
  else if (unit == "K" || unit == "KB" || unit == "KIB") shift = 10;
  else if (unit == "M" || unit == "MB" || unit == "MIB") shift = 20;
  else if (unit == "G" || unit == "GB" || unit == "GIB") shift = 30;
  else if (unit == "T" || unit == "TB" || unit == "TIB") shift = 40;
  else if (!unit.empty() && (unit[0] == '.' || unit[0] == ',')) {
    // A fraction: say it in the next smaller unit ("1.5M" -> 1536K).
    std::string number(begin, end);
    for (char& ch : number) if (ch == ',') ch = '.';
    char* rest = nullptr;
    const double x = std::strtod(number.c_str(), &rest);
    std::string suffix(rest ? rest : "");
    for (auto& ch : suffix) ch = char(std::toupper(static_cast<unsigned char>(ch)));
    const std::string units = "BKMGT";
    const size_t u = suffix.empty() ? 0 : units.find(suffix[0]);
    if (u != std::string::npos && u > 0 && std::isfinite(x) && x > 0) {
      const double smaller = x * 1024.0;
      const double whole = std::round(smaller);
      char amount[32];
      std::snprintf(amount, sizeof amount, "%.0f", whole);
      const std::string in_smaller = std::string(amount) + (u == 1 ? "" : std::string(1, units[u - 1]));
      return Status::error(quoted + " is not a whole number of bytes (write " + (whole == smaller ? "" : "about ") +
                           in_smaller + " for " + text + ")");
    }
    return Status::error(quoted + " is not a whole number of bytes (write e.g. 1536M for 1.5G)");
  }
  else return Status::error(quoted + ": unknown size unit '" + std::string(digits_end, end) + "' (use K, M, G or T)");
  if (value == 0) return Status::error(quoted + ": the size must be at least 1 byte");
  if (value > (UINT64_MAX >> shift)) return Status::error(quoted + " is too large (more than 2^64 - 1 bytes)");
  return value << shift;
}

std::string not_regular_file_text(unsigned mode) {
  if (S_ISREG(mode)) return "";
  if (S_ISDIR(mode)) return "is a directory, not a regular file";
  if (S_ISFIFO(mode)) return "is a named pipe (FIFO), not a regular file";
  if (S_ISCHR(mode)) return "is a character device, not a regular file";
  if (S_ISBLK(mode)) return "is a block device, not a regular file";
  if (S_ISSOCK(mode)) return "is a socket, not a regular file";
  return "is not a regular file";
}

Status check_regular_file(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR) return Status::error(path.string() + ": no such file");
    return Status::error(path.string() + ": cannot access: " + std::strerror(errno));
  }
  if (const std::string what = not_regular_file_text(st.st_mode); !what.empty())
    return Status::error(path.string() + ": " + what);
  return Status::ok();
}

std::string format_bytes(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) { v /= 1024; ++u; }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.2f %s", v, units[u]);
  return buf;
}

namespace {

// This machine's name as it goes into temporaries' names: no '-' (the
// names' field separator) and no '/'.
const std::string& host_tag() {
  static const std::string tag = [] {
    char name[256] = {};
    if (::gethostname(name, sizeof name - 1) != 0 || !name[0]) return std::string("localhost");
    std::string t(name);
    for (char& c : t)
      if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_') c = '_';
    return t;
  }();
  return tag;
}

// True if `rest` (what follows ".tmp-" in a temporary's name) starts with
// "PID@HOST-" for a process of this machine that no longer exists (not this
// one). A process of another machine sharing the folder is never judged
// dead: its pid means nothing here. Names without "@HOST" (raylod before
// 2026-11) are taken as this machine's.
bool pid_prefix_is_dead(const std::string& rest) {
  const size_t end = rest.find_first_not_of("0123456789");
  if (end == 0 || end == std::string::npos || (rest[end] != '-' && rest[end] != '@')) return false;
  if (rest[end] == '@') {
    const size_t dash = rest.find('-', end);
    if (dash == std::string::npos || rest.compare(end + 1, dash - end - 1, host_tag()) != 0) return false;
  }
  const long pid = std::strtol(rest.substr(0, end).c_str(), nullptr, 10);
  if (pid <= 0 || pid == long(getpid())) return false;
  return ::kill(pid_t(pid), 0) != 0 && errno == ESRCH;  // alive, or not ours to judge: false
}

}  // namespace

namespace {

std::filesystem::path follow_symlinks(std::filesystem::path p);  // below

// Whether a and b name one file: the same device and inode if both exist,
// else the same absolute, normalised path.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  std::error_code ec;
  if (std::filesystem::exists(a, ec) && std::filesystem::exists(b, ec)) {
    const bool same = std::filesystem::equivalent(a, b, ec);
    if (!ec) return same;
  }
  // A symlink whose target does not exist yet names that target (an output
  // written through it lands there): followed first, as weakly_canonical
  // leaves a component that does not exist as it is.
  auto resolved = [&](const std::filesystem::path& p) {
    return std::filesystem::weakly_canonical(follow_symlinks(std::filesystem::absolute(p, ec)), ec).lexically_normal();
  };
  return resolved(a) == resolved(b);
}

}  // namespace

Status check_outputs_apart(const std::vector<FileRole>& outputs, const std::vector<FileRole>& inputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const FileRole& out = outputs[i];
    if (out.path.empty()) continue;
    for (const FileRole& in : inputs)
      if (!in.path.empty() && same_file(out.path, in.path))
        return Status::error(out.path.string() + ": " + out.role + " would replace " + in.role +
                             "; choose another output");
    for (size_t j = i + 1; j < outputs.size(); ++j)
      if (!outputs[j].path.empty() && same_file(out.path, outputs[j].path))
        return Status::error(out.path.string() + ": given as both " + out.role + " and " + outputs[j].role);
  }
  return {};
}

std::string temporary_stem(const std::string& filename) {
  if (filename.size() <= 127) return filename;
  char hash[18];
  std::snprintf(hash, sizeof hash, "~%016llx",
                static_cast<unsigned long long>(fnv1a64(filename.data(), filename.size())));
  return filename.substr(0, 110) + hash;
}

const std::string& process_tag() {
  static const std::string tag = std::to_string(getpid()) + "@" + host_tag();
  return tag;
}

bool is_dead_process_temporary(const std::string& filename) {
  const size_t at = filename.find(".tmp-");
  return at != std::string::npos && at > 0 && pid_prefix_is_dead(filename.substr(at + 5));
}

size_t remove_stale_temporaries(const std::filesystem::path& destination) {
  // Temporaries are named DEST.tmp-PID@HOST-N-R; one whose process is gone
  // (a kill -9 during a write, a crash) is never renamed and can be removed.
  const std::string prefix = temporary_stem(destination.filename().string()) + ".tmp-";
  std::filesystem::path dir = destination.parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  size_t removed = 0;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    if (!pid_prefix_is_dead(name.substr(prefix.size()))) continue;
    // AtomicDirectory's temporaries are folders (never followed if a link).
    std::error_code rm;
    if (std::filesystem::is_directory(std::filesystem::symlink_status(it->path(), rm)))
      removed += std::filesystem::remove_all(it->path(), rm) > 0;
    else if (std::filesystem::remove(it->path(), rm))
      ++removed;
  }
  return removed;
}

namespace {

// The temporaries being written, for the handler of SIGTERM, SIGINT and
// SIGHUP: mpirun ends the other ranks with SIGTERM when one fails, and a
// terminal's Ctrl-C is SIGINT. A slot is free (kFree), being filled
// (kFilling), names a live temporary file (kFile) or folder (kFolder, an
// AtomicDirectory's), a folder its commit() is renaming (kCommitting: the
// handler leaves it, and if the process dies then, the next run's clean-up
// removes it), or a folder the handler is removing (kRemoving). The
// handler reads only lock-free atomics and calls only async-signal-safe
// functions (unlink, openat, getdents64, unlinkat, raise).
enum SlotState : int { kFree, kFilling, kFile, kFolder, kCommitting, kRemoving };
struct TemporarySlot {
  std::atomic<int> state{kFree};
  char path[4096];
};
TemporarySlot g_temporaries[64];

// Removes `name` (relative to dir_fd) and, if it is a folder, what is in it,
// `depth` levels down at most, with system calls only (async-signal-safe).
// A file that another thread creates meanwhile can leave the folder behind,
// as can a system other than Linux (the folder must then be empty): the
// next run's remove_stale_temporaries takes it.
void remove_tree_at(int dir_fd, const char* name, int depth) {
  if (::unlinkat(dir_fd, name, 0) == 0 || errno == ENOENT) return;
#if defined(__linux__) && defined(SYS_getdents64)
  if (depth > 0) {
    const int fd = ::openat(dir_fd, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd >= 0) {
      alignas(8) char buf[4096];
      // Entries removed while the folder is read may hide others: read it
      // again until a pass finds nothing (a bounded number of times).
      for (int pass = 0; pass < 8; ++pass) {
        bool found = false;
        ::lseek(fd, 0, SEEK_SET);
        long n;
        while ((n = ::syscall(SYS_getdents64, fd, buf, sizeof buf)) > 0)
          for (long at = 0; at < n;) {
            // struct linux_dirent64: ino (8 bytes), off (8), reclen (2), type (1), name.
            unsigned short reclen = 0;
            std::memcpy(&reclen, buf + at + 16, sizeof reclen);
            const char* entry = buf + at + 19;
            at += reclen;
            if (entry[0] == '.' && (entry[1] == 0 || (entry[1] == '.' && entry[2] == 0))) continue;
            remove_tree_at(fd, entry, depth - 1);
            found = true;
          }
        if (!found) break;
      }
      ::close(fd);
    }
  }
#endif
  ::unlinkat(dir_fd, name, AT_REMOVEDIR);
}

void remove_temporaries_and_die(int sig) {
  for (TemporarySlot& slot : g_temporaries) {
    int state = slot.state.load(std::memory_order_acquire);
    if (state == kFile) ::unlink(slot.path);
    if (state == kFolder && slot.state.compare_exchange_strong(state, kRemoving, std::memory_order_acq_rel))
      remove_tree_at(AT_FDCWD, slot.path, 8);
  }
  // SA_RESETHAND restored the default action: the signal, blocked while
  // this runs, ends the process as it would have without the handler.
  ::raise(sig);
}

// Installed once, for signals whose action is still the default (one set
// to be ignored, as under nohup, stays ignored).
void install_temporary_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    for (int sig : {SIGTERM, SIGINT, SIGHUP}) {
      struct sigaction old {};
      if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler != SIG_DFL) continue;
      struct sigaction sa {};
      sa.sa_handler = remove_temporaries_and_die;
      sigemptyset(&sa.sa_mask);
      sa.sa_flags = SA_RESETHAND;
      ::sigaction(sig, &sa, nullptr);
    }
  });
}

// A slot for `path` (a file, or a folder if `folder`), or -1 if every slot
// is taken or the path is too long (the temporary is then left to the next
// run's clean-up, as before).
int register_temporary(const std::filesystem::path& path, bool folder = false) {
  const std::string& p = path.native();
  if (p.size() >= sizeof(TemporarySlot::path)) return -1;
  for (int i = 0; i < int(std::size(g_temporaries)); ++i) {
    int expected = kFree;
    TemporarySlot& slot = g_temporaries[i];
    if (!slot.state.compare_exchange_strong(expected, kFilling, std::memory_order_acq_rel)) continue;
    std::memcpy(slot.path, p.c_str(), p.size() + 1);
    slot.state.store(folder ? kFolder : kFile, std::memory_order_release);
    return i;
  }
  return -1;
}

void release_temporary(int& slot) {
  if (slot >= 0) g_temporaries[slot].state.store(kFree, std::memory_order_release);
  slot = -1;
}

// Takes a folder's slot from the handler for commit(): from then on a
// signal leaves the folder alone. If the handler is removing it already,
// the process is about to end (the handler re-raises the signal): wait.
void hold_folder_from_handler(int slot) {
  if (slot < 0) return;
  for (;;) {
    int expected = kFolder;
    if (g_temporaries[slot].state.compare_exchange_strong(expected, kCommitting, std::memory_order_acq_rel)) return;
    ::usleep(1000);
  }
}

// Gives a folder's slot back to the handler (what is at its path is to be
// removed).
void return_folder_to_handler(int slot) {
  if (slot >= 0) g_temporaries[slot].state.store(kFolder, std::memory_order_release);
}

}  // namespace

namespace {

// The file a chain of symlinks ends at (relative links taken from their own
// directory); `p` itself if it is not a link, or after 40 links (a loop,
// which the write then reports).
std::filesystem::path follow_symlinks(std::filesystem::path p) {
  namespace fs = std::filesystem;
  for (int i = 0; i < 40; ++i) {
    std::error_code ec;
    if (!fs::is_symlink(fs::symlink_status(p, ec))) return p;
    const fs::path next = fs::read_symlink(p, ec);
    if (ec) return p;
    p = next.is_absolute() ? next : p.parent_path() / next;
  }
  return p;
}

// A temporary's name for `beside`: BESIDE.tmp-PID@HOST-N-R (N counts this
// process's temporaries, R is random).
std::filesystem::path temporary_beside(const std::filesystem::path& beside) {
  static std::atomic<uint64_t> counter{0};
  std::random_device rd;
  std::filesystem::path temp = beside.parent_path() / temporary_stem(beside.filename().string());
  temp += ".tmp-" + process_tag() + "-" + std::to_string(counter++) + "-" + std::to_string(rd() & 0xffff);
  return temp;
}

// fsyncs a folder, so that the renames into it last (best effort).
void sync_folder(const std::filesystem::path& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

bool is_pass_through_output(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);  // through symlinks
  return !ec && fs::exists(st) && !fs::is_regular_file(st) && !fs::is_directory(st);
}

int register_scratch_file(const std::filesystem::path& path) {
  // A quarter of the slots stay for AtomicOutput's and AtomicDirectory's
  // temporaries: a scene of many stores stages a mesh for each.
  int used = 0;
  for (const TemporarySlot& slot : g_temporaries) used += slot.state.load(std::memory_order_acquire) != kFree;
  if (used >= int(std::size(g_temporaries)) * 3 / 4) return -1;
  install_temporary_handlers();
  return register_temporary(path);
}

void release_scratch_file(int& slot) { release_temporary(slot); }

AtomicOutput::AtomicOutput(std::filesystem::path destination) : dest_(std::move(destination)) {
  namespace fs = std::filesystem;
  std::error_code ec;
  pass_through_ = is_pass_through_output(dest_);
  target_ = pass_through_ ? dest_ : follow_symlinks(dest_);
  // A device's directory (/dev) is no place for a temporary.
  const fs::path beside = pass_through_ ? temporary_folder() / ("raylod-" + dest_.filename().string()) : target_;
  remove_stale_temporaries(beside);
  temp_ = temporary_beside(beside);
  install_temporary_handlers();
  slot_ = register_temporary(temp_);
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) {
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
  }
  release_temporary(slot_);
}

Status AtomicOutput::commit() {
  if (pass_through_) {
    const std::string dest = dest_.string();
    std::ifstream in(temp_, std::ios::binary);
    if (!in) return Status::write_failed(dest, dest + ": output was not written", errno);
    const int out = ::open(dest_.c_str(), O_WRONLY | O_CLOEXEC);
    if (out < 0) return Status::write_failed(dest, dest + ": cannot open for writing: " + std::strerror(errno), errno);
    std::vector<char> buf(1 << 16);
    int write_errno = 0;
    while (in && write_errno == 0) {
      in.read(buf.data(), std::streamsize(buf.size()));
      const char* p = buf.data();
      for (std::streamsize left = in.gcount(); left > 0 && write_errno == 0;) {
        const ssize_t n = ::write(out, p, size_t(left));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) { write_errno = n < 0 ? errno : EIO; break; }
        p += n;
        left -= n;
      }
    }
    ::close(out);
    std::error_code ec;
    std::filesystem::remove(temp_, ec);
    committed_ = true;
    release_temporary(slot_);
    if (write_errno != 0)
      return Status::write_failed(dest, dest + ": write failed: " + std::strerror(write_errno), write_errno);
    return Status::ok();
  }
  int fd = ::open(temp_.c_str(), O_RDONLY);
  if (fd < 0) return Status::write_failed(dest_.string(), dest_.string() + ": output was not written", errno);
  bool synced = ::fsync(fd) == 0;
  const int sync_errno = errno;
  ::close(fd);
  if (!synced)
    return Status::write_failed(dest_.string(), dest_.string() + ": could not flush to disk (disk full?)", sync_errno);
  // A file replaced gives the new one its permissions (a read-only image
  // stays read-only), as a folder replaced does (AtomicDirectory).
  struct stat old {};
  if (::stat(target_.c_str(), &old) == 0 && S_ISREG(old.st_mode)) ::chmod(temp_.c_str(), old.st_mode & 0777);
  std::error_code ec;
  std::filesystem::rename(temp_, target_, ec);
  if (ec)
    return Status::write_failed(dest_.string(), dest_.string() + ": could not rename into place: " + ec.message(),
                                ec.value());
  committed_ = true;
  release_temporary(slot_);
  // Make the rename itself durable.
  auto dir = target_.parent_path().empty() ? std::filesystem::path(".") : target_.parent_path();
  int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (dfd >= 0) { ::fsync(dfd); ::close(dfd); }
  return Status::ok();
}

bool folder_is_writable(const std::filesystem::path& dir) {
  const std::filesystem::path probe = dir / (".raylod-write-test-" + std::to_string(::getpid()));
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return errno == EEXIST;  // a leftover of this pid's: the folder takes files
  ::close(fd);
  ::unlink(probe.c_str());
  return true;
}

std::filesystem::path temporary_folder() {
  // Decided once per process (its writability is probed with a file).
  static const std::filesystem::path folder = [] {
    std::error_code ec;
    std::filesystem::path dir = std::filesystem::temp_directory_path(ec);
    // One that does not exist or takes no files: /tmp, as for one not set.
    return ec || dir.empty() || !folder_is_writable(dir) ? std::filesystem::path("/tmp") : dir;
  }();
  return folder;
}

Status check_output_path(const std::filesystem::path& path, const std::string& role) {
  if (path.empty()) return Status::error(role + ": no file name given");
  const std::string who = path.string() + ": " + role + ": ";
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return Status::error(who + "is a directory");
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    return Status::error(who + dir.string() + " is not a directory");
  if (!std::filesystem::is_directory(dir, ec)) return Status::error(who + "directory " + dir.string() + " does not exist");
  if (is_pass_through_output(path)) return {};
  const std::string name = path.filename().string();
  if (name.size() > 255)
    return Status::error(path.string().substr(0, 60) + "...: " + role + ": the file name is " +
                         std::to_string(name.size()) + " bytes, more than the 255 a file name may have");
  if (!folder_is_writable(dir)) return Status::error(who + "the folder " + dir.string() + " takes no files (not writable)");
  return {};
}

AtomicDirectory::AtomicDirectory(std::filesystem::path destination) : dest_(std::move(destination)) {
  namespace fs = std::filesystem;
  std::error_code ec;
  // A symlink is followed, also one whose folder does not exist yet: the
  // folder is made where it points, and the link stays.
  target_ = follow_symlinks(dest_);
  remove_stale_temporaries(target_);
  temp_ = temporary_beside(target_);
}

AtomicDirectory::~AtomicDirectory() {
  if (created_ && !committed_) {
    std::error_code ec;
    std::filesystem::remove_all(temp_, ec);
  }
  release_temporary(slot_);
}

Status AtomicDirectory::create() {
  const std::string dest = dest_.string();
  // Registered first: a signal between the two finds nothing to remove.
  install_temporary_handlers();
  if (slot_ < 0) slot_ = register_temporary(temp_, true);
  std::error_code ec;
  if (!std::filesystem::create_directory(temp_, ec) || ec) {
    const int err = ec ? ec.value() : EEXIST;
    return Status::write_failed(dest, dest + ": cannot create the temporary folder " + temp_.string() + ": " +
                                    (ec ? ec.message() : std::string("it exists")),
                                err);
  }
  created_ = true;
  return Status::ok();
}

Status AtomicDirectory::commit() {
  namespace fs = std::filesystem;
  const std::string dest = dest_.string();
  if (!created_ || committed_) return Status::error(dest + ": no temporary folder to rename into place");
  sync_folder(temp_);
  // From here a signal leaves the folders alone (the handler could
  // otherwise be removing the temporary while it is renamed), and this
  // thread takes none until both renames are done.
  hold_folder_from_handler(slot_);
  sigset_t block, previous;
  sigemptyset(&block);
  for (int sig : {SIGTERM, SIGINT, SIGHUP}) sigaddset(&block, sig);
  ::pthread_sigmask(SIG_BLOCK, &block, &previous);
  std::error_code ec;
  const bool replace = fs::exists(fs::symlink_status(target_, ec));
  // The folder replaced keeps its permissions (the new one was made with
  // the process's umask).
  if (struct stat old; replace && ::stat(target_.c_str(), &old) == 0 && S_ISDIR(old.st_mode))
    ::chmod(temp_.c_str(), old.st_mode & 0777);
  int err = 0;
  bool old_at_temp = false;  // the folder replaced is now at temp_
  fs::path aside;            // ...or there
  bool done = false;
#if defined(__linux__) && defined(RENAME_EXCHANGE) && defined(RENAME_NOREPLACE)
  // One rename: the new folder in place and the old one at the temporary's
  // name, or (nothing there) the new folder in place unless something came.
  if (::renameat2(AT_FDCWD, temp_.c_str(), AT_FDCWD, target_.c_str(), replace ? RENAME_EXCHANGE : RENAME_NOREPLACE) == 0) {
    done = true;
    old_at_temp = replace;
  } else if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP) {
    err = errno;
    done = true;
  }
#endif
  if (!done && !replace) {
    if (::rename(temp_.c_str(), target_.c_str()) != 0) err = errno;
  } else if (!done) {
    // Moved aside, the new one renamed in (the old one back on failure).
    aside = temporary_beside(target_);
    if (::rename(target_.c_str(), aside.c_str()) != 0) {
      err = errno;
      aside.clear();
    } else if (::rename(temp_.c_str(), target_.c_str()) != 0) {
      err = errno;
      ::rename(aside.c_str(), target_.c_str());
      aside.clear();
    }
  }
  ::pthread_sigmask(SIG_SETMASK, &previous, nullptr);
  if (err != 0) {
    return_folder_to_handler(slot_);
    return Status::write_failed(dest, dest + ": could not rename the finished folder into place: " + std::strerror(err),
                                err);
  }
  committed_ = true;
  sync_folder(target_.parent_path());
  // The folder replaced: removed (a signal meanwhile removes the rest).
  const fs::path replaced = old_at_temp ? temp_ : aside;
  if (old_at_temp) {
    return_folder_to_handler(slot_);
    fs::remove_all(temp_, ec);
  } else if (!aside.empty()) {
    int aside_slot = register_temporary(aside, true);
    fs::remove_all(aside, ec);
    release_temporary(aside_slot);
  }
  if (!replaced.empty() && (ec || fs::exists(fs::symlink_status(replaced, ec))))
    leftover_ = "the folder replaced, moved to " + replaced.string() + ", could not be removed" +
                (ec ? ": " + ec.message() : std::string());
  release_temporary(slot_);
  return Status::ok();
}

std::filesystem::path default_cache_dir() {
  if (const char* d = std::getenv("RAYLOD_CACHE_DIR"); d && *d) return d;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) return std::filesystem::path(x) / "raylod";
  if (const char* h = std::getenv("HOME"); h && *h) return std::filesystem::path(h) / ".cache" / "raylod";
  return temporary_folder() / "raylod-cache";
}

Status write_temporary(const AtomicOutput& out, std::initializer_list<std::string_view> pieces,
                       void (*between)(size_t)) {
  const std::string dest = out.destination().string();
  errno = 0;
  std::ofstream f(out.temp_path(), std::ios::binary);
  if (!f) return Status::write_failed(dest, dest + ": cannot open for writing: " + std::strerror(errno), errno);
  size_t i = 0;
  for (std::string_view piece : pieces) {
    f.write(piece.data(), std::streamsize(piece.size()));
    if (between && ++i < pieces.size()) {
      f.flush();
      between(i - 1);
    }
  }
  f.close();
  if (!f) return Status::write_failed(dest, dest + ": write failed: " + std::strerror(errno), errno);
  return {};
}

Status write_temporary(const AtomicOutput& out, std::string_view bytes) { return write_temporary(out, {bytes}); }

Status write_file_atomic(const std::filesystem::path& path, const std::string& text) {
  AtomicOutput out(path);
  RAYLOD_RETURN_IF_ERROR(write_temporary(out, text));
  return out.commit();
}

uint64_t fnv1a64(const void* data, size_t bytes, uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) { h ^= p[i]; h *= 0x100000001b3ull; }
  return h;
}

}  // namespace raylod
