// `raylod build` on a mesh file: fingerprints (size, mtime, content hash),
// the up-to-date check, and the two reader passes through open_mesh. The
// algorithm itself is in octree_build.cpp and never opens files.
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <future>

#include "core/system.h"
#include "streaming/octree_store.h"
#include "streaming/distinct_keys.h"
#include "streaming/gltf_io.h"
#include "streaming/source_record.h"

namespace raylod {
namespace {

StatusOr<uint64_t> hash_file(const std::filesystem::path& path) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::error(path.string() + ": cannot open: " + std::strerror(errno));
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_SEQUENTIAL);
  std::vector<char> buffer(4 << 20);
  ContentHasher hasher;
  for (;;) {
    ssize_t r = ::read(fd, buffer.data(), buffer.size());
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      Status s = Status::error(path.string() + ": read failed: " + std::strerror(errno));
      ::close(fd);
      return s;
    }
    if (r == 0) break;
    hasher.update(buffer.data(), size_t(r));
  }
  ::close(fd);
  return hasher.digest();
}

// flock() on the mesh file while its store is checked and built: concurrent
// builds (three `raylod run` of one scene) build the store once, and the
// others then find it current. The mesh itself is locked, not a lock file
// beside the store, so that nothing is left behind; a mesh that cannot be
// locked (not a regular file, a file system without flock) is built unlocked.
class BuildLock {
 public:
  explicit BuildLock(const std::filesystem::path& mesh) {
    fd_ = ::open(mesh.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);  // O_NONBLOCK: a FIFO must not block here
    struct stat st {};
    if (fd_ >= 0 && (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode))) {
      ::close(fd_);
      fd_ = -1;
    }
    if (fd_ >= 0)
      while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
      }
  }
  ~BuildLock() {
    if (fd_ >= 0) ::close(fd_);  // releases the lock
  }
  BuildLock(const BuildLock&) = delete;
  BuildLock& operator=(const BuildLock&) = delete;

 private:
  int fd_ = -1;
};

bool same_file_state(const SourceFingerprint& a, const SourceFingerprint& b) {
  return a.bytes == b.bytes && a.mtime_ns == b.mtime_ns;
}

}  // namespace

StatusOr<SourceFingerprint> fingerprint_file(const std::filesystem::path& mesh, bool with_hash) {
  // One mesh of a glTF file: the file's state, under the mesh's own name.
  const MeshRef ref = parse_mesh_ref(mesh);
  const std::filesystem::path& path = ref.file;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return Status::error(path.string() + ": " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return Status::error(path.string() + ": " + not_regular_file_text(st.st_mode));
  SourceFingerprint fp;
  std::error_code ec;
  auto abs = std::filesystem::weakly_canonical(std::filesystem::absolute(path), ec);
  fp.path = (ec ? std::filesystem::absolute(path) : abs).string();
  if (ref.gltf_mesh >= 0) fp.path = gltf_mesh_path(fp.path, ref.gltf_mesh).string();
  fp.status = file_status_of(st);
  if (with_hash) {
    RAYLOD_ASSIGN_OR_RETURN(fp.hash, hash_file(path));
  }
  // A .gltf's mesh lives in the .bin files beside it: they join the
  // fingerprint (sizes summed, the latest times, inodes and hashes mixed
  // in), so that editing one changes it as editing the .gltf would. A
  // missing one is left out (the reader says it is missing).
  auto format = mesh_format_from_extension(path);
  if (format.is_ok() && *format == MeshFormat::Gltf) {
    const std::vector<std::filesystem::path> buffers = gltf_external_buffers(path);
    fp.status = with_external_buffers(fp.status, buffers);
    if (with_hash)
      for (const std::filesystem::path& buffer : buffers) {
        std::error_code not_regular;
        if (!std::filesystem::is_regular_file(buffer, not_regular)) continue;  // with_external_buffers leaves it out too
        RAYLOD_ASSIGN_OR_RETURN(const uint64_t h, hash_file(buffer));
        fp.hash = mix64_finalise(fp.hash ^ mix64_finalise(h));
      }
  }
  fp.bytes = fp.status.bytes;
  fp.mtime_ns = fp.status.mtime_ns;
  return fp;
}

bool store_is_current(const std::filesystem::path& mesh, const std::filesystem::path& store,
                      const StoreOptions& options, std::string* reason, bool rehash, BuildReport* opened) {
  auto say = [&](std::string r) {
    if (reason) *reason = std::move(r);
    return false;
  };
  std::error_code ec;
  if (!std::filesystem::exists(store, ec)) return say("no store yet");
  if (auto corrupt = store_corruption(store))
    return say("a reader found it corrupt: " + *corrupt + " (recorded in " + corruption_record_path(store).string() + ")");
  auto store_status = file_status(store);
  if (!store_status.is_ok()) return say(store_status.status().message());
  // Full open: header and table checksums. Kept for the caller if it is current.
  auto open_store = OctreeStore::open(store);
  if (!open_store.is_ok()) return say("the existing store is unusable (" + open_store.status().message() + ")");
  std::shared_ptr<OctreeStore> store_open = std::move(open_store.value());
  const StoreHeader& h = store_open->header();
  auto current = [&](std::string r) {
    if (reason) *reason = std::move(r);
    if (opened) {
      opened->opened = store_open;
      opened->opened_status = *store_status;
    }
    return true;
  };
  auto fp = fingerprint_file(mesh, false);
  if (!fp.is_ok()) return say(fp.status().message());
  if (h.source_path != fp->path) return say("the store was built from another mesh (" + h.source_path + ")");
  if (h.source_bytes != fp->bytes)
    return say("the mesh changed size (" + std::to_string(h.source_bytes) + " -> " + std::to_string(fp->bytes) + " bytes)");
  // Another modification time alone (touch, a copy without -p, a checkout
  // of the same bytes) is not a change: the content hash below decides, and
  // the store, and every simplified mesh cached from it, stays.
  // A store is reused under any memory limit for which a fresh build would
  // make the same store (reuse_limit_lo/hi), so the output never depends on
  // which limit built it.
  const uint64_t limit = resolved_memory_limit(options);
  if (h.options.max_depth != options.max_depth || h.options.page_triangles != options.page_triangles)
    return say("the store was built with other options (--max-depth " + std::to_string(h.options.max_depth) + ")");
  if (limit < h.reuse_limit_lo || limit > h.reuse_limit_hi)
    return say("the store was built under --memory-limit " + describe_memory_limit(h.options.memory_limit) +
               ", and a build under " + describe_memory_limit(options.memory_limit) + " makes a " +
               (limit < h.reuse_limit_lo ? "coarser" : "finer") + " one");
  const FileStatus& before = fp->status;
  if (!rehash && source_record_vouches(store, before, h.source_hash))
    return current("up to date (same options; the mesh's size, times and inode are those of its last content check, " +
                   source_record_path(store).filename().string() + ")");
  const uint64_t started = realtime_ns();
  auto hashed = fingerprint_file(mesh, true);
  if (!hashed.is_ok()) return say(hashed.status().message());
  if (hashed->hash != h.source_hash) return say("the mesh's content changed (content hash differs)");
  auto after = fingerprint_file(mesh, false);
  auto store_after = file_status(store);
  if (after.is_ok() && after->status == before && store_after.is_ok() && *store_after == *store_status)
    note_source_checked(store, before, h.source_hash, started);
  return current(fp->mtime_ns == h.source_mtime_ns
                     ? "up to date (same mesh size, modification time, content hash and options)"
                     : "up to date (same mesh size, content hash and options; only its modification time changed)");
}

StatusOr<BuildReport> build_store(const std::filesystem::path& mesh, const std::filesystem::path& store,
                                  const StoreOptions& options) {
  return build_store(mesh, store, options, false);
}

StatusOr<BuildReport> build_store(const std::filesystem::path& mesh, const std::filesystem::path& store,
                                  const StoreOptions& options, bool force, bool verify,
                                  const std::function<void(const std::string& reason)>& before_building) {
  BuildLock lock(parse_mesh_ref(mesh).file);
  // A build killed earlier (kill -9) left its temporary beside the store;
  // the store it was to replace may be current, so no build would remove it.
  remove_stale_temporaries(store);
  std::string reason = "--force";
  BuildReport report;
  if (!force && store_is_current(mesh, store, options, &reason, verify, &report)) {
    report.reused = true;
    report.reason = reason;
    auto verified = verify ? verify_store_pages(store) : StatusOr<uint64_t>(uint64_t(0));
    if (verified.is_ok()) {
      if (verify) report.reason += "; --verify: the checksums of all " + std::to_string(*verified) + " pages match";
      report.peak_rss = peak_rss_bytes();
      return report;
    }
    reason = "--verify: " + verified.status().message();
    report.opened.reset();
  }
  if (before_building) before_building(reason);
  RAYLOD_ASSIGN_OR_RETURN(SourceFingerprint fp, fingerprint_file(mesh, false));
  const uint64_t hash_started = realtime_ns();
  uint64_t content_hash = 0;
  // Hash the file on another thread while pass 1 parses it (both read the
  // page cache; neither keeps it resident).
  auto hash = std::async(std::launch::async, [&] {
    return fingerprint_file(mesh, true);
  });
  const std::string changed = mesh.string() + ": the mesh changed while building " + store.string() +
                              " (the store was left as it was); run raylod build again";
  auto opener = [&]() -> StatusOr<std::unique_ptr<MeshReader>> { return open_mesh(mesh); };
  // Called after both passes, before the store is written: the file must be
  // the one hashed and the one both passes read, or nothing is committed.
  auto built = build_store_from_stream(opener, fp, store, options, [&]() -> StatusOr<uint64_t> {
    auto h = hash.get();
    if (!h.is_ok()) return h.status();
    auto now = fingerprint_file(mesh, false);
    if (!same_file_state(*h, fp) || !now.is_ok() || !same_file_state(*now, fp)) return Status::error(changed);
    content_hash = h->hash;
    return h->hash;
  });
  if (hash.valid()) hash.wait();
  if (!built.is_ok()) return built.status();
  // The corruption record was about the replaced file; remove it with the store it named.
  std::error_code ec;
  std::filesystem::remove(corruption_record_path(store), ec);
  // A change after the passes does not make this store wrong for the mesh it
  // read (its fingerprint says which); it is never removed here, since another
  // process may be using it, but the caller is told.
  auto after = fingerprint_file(mesh, false);
  if (!after.is_ok() || !same_file_state(*after, fp)) return Status::error(changed);
  if (after->status == fp.status)
    note_source_checked(store, fp.status, content_hash, hash_started);
  else
    std::filesystem::remove(source_record_path(store), ec);
  built->reason = reason;
  return built;
}

}  // namespace raylod
