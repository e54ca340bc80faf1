#include "streaming/mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <utility>

#include "core/system.h"

namespace raylod {

namespace {
std::string errno_text() { return std::strerror(errno); }
size_t page_size() {
  static const size_t p = size_t(::sysconf(_SC_PAGESIZE));
  return p;
}
}  // namespace

MappedFile::~MappedFile() {
  if (data_) ::munmap(const_cast<uint8_t*>(data_), size_);
}

MappedFile::MappedFile(MappedFile&& o) noexcept
    : path_(std::move(o.path_)), data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)) {}

MappedFile& MappedFile::operator=(MappedFile&& o) noexcept {
  if (this != &o) {
    if (data_) ::munmap(const_cast<uint8_t*>(data_), size_);
    path_ = std::move(o.path_);
    data_ = std::exchange(o.data_, nullptr);
    size_ = std::exchange(o.size_, 0);
  }
  return *this;
}

StatusOr<MappedFile> MappedFile::open(const std::filesystem::path& path) {
  const std::string name = path.string();
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer
  // before fstat could reject it (it changes nothing for regular files).
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return Status::error(name + ": cannot open: " + errno_text());
  struct stat st{};
  if (::fstat(fd, &st) != 0) {
    Status s = Status::error(name + ": cannot stat: " + errno_text());
    ::close(fd);
    return s;
  }
  if (const std::string what = not_regular_file_text(st.st_mode); !what.empty()) {
    ::close(fd);
    return Status::error(name + ": " + what);
  }
  MappedFile m;
  m.path_ = path;
  m.size_ = size_t(st.st_size);
  if (m.size_ > 0) {
    void* p = ::mmap(nullptr, m.size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (p == MAP_FAILED) {
      Status s = Status::error(name + ": cannot map into memory: " + errno_text());
      ::close(fd);
      return s;
    }
    m.data_ = static_cast<const uint8_t*>(p);
  }
  ::close(fd);  // the mapping keeps the file alive
  return m;
}

namespace {
void advise_range(const uint8_t* data, size_t size, size_t begin, size_t end, int advice) {
  if (!data) return;
  const size_t ps = page_size();
  begin = begin / ps * ps;  // madvise needs a page-aligned start
  end = std::min(end, size);
  if (end > begin) ::madvise(const_cast<uint8_t*>(data) + begin, end - begin, advice);
}
}  // namespace

void MappedFile::advise_sequential(size_t begin, size_t end) const {
  advise_range(data_, size_, begin, end, MADV_SEQUENTIAL);
}

void MappedFile::advise_random(size_t begin, size_t end) const {
  advise_range(data_, size_, begin, end, MADV_RANDOM);
}

void MappedFile::release(size_t begin, size_t end) const {
  if (!data_) return;
  const size_t ps = page_size();
  begin = (begin + ps - 1) / ps * ps;  // whole pages only
  end = std::min(end, size_) / ps * ps;
  if (end > begin) ::madvise(const_cast<uint8_t*>(data_) + begin, end - begin, MADV_DONTNEED);
}

SpillFile::~SpillFile() {
  if (data_) ::munmap(const_cast<uint8_t*>(data_), written_);
  if (fd_ >= 0) ::close(fd_);
}

SpillFile::SpillFile(SpillFile&& o) noexcept
    : what_(std::move(o.what_)), fd_(std::exchange(o.fd_, -1)), buffer_(std::move(o.buffer_)),
      written_(std::exchange(o.written_, 0)), data_(std::exchange(o.data_, nullptr)) {}

SpillFile& SpillFile::operator=(SpillFile&& o) noexcept {
  if (this != &o) {
    this->~SpillFile();
    new (this) SpillFile(std::move(o));
  }
  return *this;
}

StatusOr<SpillFile> SpillFile::create(std::string what) {
  const std::filesystem::path dir = temporary_folder();
  std::string templ = (dir / "raylod-spill-XXXXXX").string();
  int fd = ::mkstemp(templ.data());
  if (fd < 0) return Status::error(what + ": cannot create a scratch file in " + dir.string() + ": " + errno_text());
  ::unlink(templ.c_str());
  SpillFile f;
  f.what_ = std::move(what);
  f.fd_ = fd;
  f.buffer_.reserve(1 << 20);
  return f;
}

Status SpillFile::flush() {
  const uint8_t* p = buffer_.data();
  size_t left = buffer_.size();
  while (left > 0) {
    ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::error(what_ + ": cannot write scratch file: " + errno_text());
    }
    p += n;
    left -= size_t(n);
  }
  buffer_.clear();
  return Status::ok();
}

Status SpillFile::append(const void* bytes, size_t count) {
  if (data_ || fd_ < 0) return Status::error(what_ + ": scratch file appended to after map()");
  const auto* b = static_cast<const uint8_t*>(bytes);
  if (buffer_.size() + count > buffer_.capacity()) RAYLOD_RETURN_IF_ERROR(flush());
  if (count > buffer_.capacity()) {
    buffer_.assign(b, b + count);
    RAYLOD_RETURN_IF_ERROR(flush());
  } else {
    buffer_.insert(buffer_.end(), b, b + count);
  }
  written_ += count;
  return Status::ok();
}

Status SpillFile::map() {
  if (fd_ < 0) return Status::error(what_ + ": scratch file is not open");
  if (data_) return Status::ok();
  RAYLOD_RETURN_IF_ERROR(flush());
  buffer_ = {};
  if (written_ == 0) return Status::ok();
  void* p = ::mmap(nullptr, written_, PROT_READ, MAP_SHARED, fd_, 0);
  if (p == MAP_FAILED) return Status::error(what_ + ": cannot map scratch file: " + errno_text());
  data_ = static_cast<const uint8_t*>(p);
  return Status::ok();
}

}  // namespace raylod
