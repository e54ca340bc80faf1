#include "streaming/source_record.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <sstream>

#include "core/system.h"

namespace raylod {
namespace {

constexpr char kTitle[] = "raylod source check record";

uint64_t to_ns(const struct timespec& t) { return uint64_t(t.tv_sec) * 1000000000ull + uint64_t(t.tv_nsec); }

std::string format_status(const FileStatus& s) {
  return std::to_string(s.device) + " " + std::to_string(s.inode) + " " + std::to_string(s.bytes) + " " +
         std::to_string(s.mtime_ns) + " " + std::to_string(s.ctime_ns);
}

bool parse_status(std::istream& in, FileStatus& s) {
  return bool(in >> s.device >> s.inode >> s.bytes >> s.mtime_ns >> s.ctime_ns);
}

std::optional<SourceRecord> read_record(const std::filesystem::path& store) {
  std::ifstream in(source_record_path(store));
  if (!in) return std::nullopt;
  std::string title, key;
  std::getline(in, title);
  if (title != kTitle) return std::nullopt;
  SourceRecord r;
  if (!(in >> key) || key != "store" || !parse_status(in, r.store)) return std::nullopt;
  if (!(in >> key) || key != "mesh" || !parse_status(in, r.mesh)) return std::nullopt;
  if (!(in >> key) || key != "hash" || !(in >> r.hash)) return std::nullopt;
  if (!(in >> key) || key != "end") return std::nullopt;  // a torn or truncated record is ignored
  return r;
}

bool same_store_file(const FileStatus& a, const FileStatus& b) {
  return a.device == b.device && a.inode == b.inode && a.bytes == b.bytes && a.mtime_ns == b.mtime_ns;
}

}  // namespace

StatusOr<FileStatus> file_status(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return Status::error(path.string() + ": " + std::strerror(errno));
  return file_status_of(st);
}

FileStatus file_status_of(const struct stat& st) {
  FileStatus s;
  s.device = uint64_t(st.st_dev);
  s.inode = uint64_t(st.st_ino);
  s.bytes = uint64_t(st.st_size);
  s.mtime_ns = to_ns(st.st_mtim);
  s.ctime_ns = to_ns(st.st_ctim);
  return s;
}

uint64_t realtime_ns() {
  struct timespec t {};
  ::clock_gettime(CLOCK_REALTIME, &t);
  return to_ns(t);
}

std::filesystem::path source_record_path(const std::filesystem::path& store) {
  std::filesystem::path p = store;
  p += ".checked";
  return p;
}

bool note_source_checked(const std::filesystem::path& store, const FileStatus& mesh, uint64_t hash,
                         uint64_t hash_started_ns) {
  std::error_code ec;
  auto st = file_status(store);
  if (!st.is_ok() || mesh.ctime_ns + kSettleNs > hash_started_ns) {
    std::filesystem::remove(source_record_path(store), ec);
    return false;
  }
  std::ostringstream text;
  text << kTitle << "\nstore " << format_status(*st) << "\nmesh " << format_status(mesh) << "\nhash " << hash
       << "\nend\n";
  return write_file_atomic(source_record_path(store), text.str()).is_ok();
}

bool source_record_vouches(const std::filesystem::path& store, const FileStatus& mesh, uint64_t hash) {
  auto record = read_record(store);
  if (!record) return false;
  auto st = file_status(store);
  return st.is_ok() && same_store_file(record->store, *st) && record->mesh == mesh && record->hash == hash;
}

}  // namespace raylod
