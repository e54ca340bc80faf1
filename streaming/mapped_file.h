// Read-only memory maps of input files, and unlinked scratch files that are
// written once and then mapped (the vertex tables of text formats). Both keep
// data in the page cache rather than in the process heap, so the OS can page
// it out under memory pressure.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/status.h"

namespace raylod {

// A whole file mapped read-only. An empty file maps to size() == 0 and
// data() == nullptr. Move-only.
class MappedFile {
 public:
  MappedFile() = default;
  ~MappedFile();
  MappedFile(MappedFile&& other) noexcept;
  MappedFile& operator=(MappedFile&& other) noexcept;
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  // Errors name the file: "mesh.ply: cannot open: No such file or directory",
  // "f.ply: is a named pipe (FIFO), not a regular file" (only regular files
  // are mapped; a FIFO is rejected without waiting for a writer).
  static StatusOr<MappedFile> open(const std::filesystem::path& path);

  const uint8_t* data() const { return data_; }
  size_t size() const { return size_; }
  std::string_view text() const { return {reinterpret_cast<const char*>(data_), size_}; }
  const std::filesystem::path& path() const { return path_; }

  // Access-pattern hints (madvise) for the whole pages in [begin, end);
  // no-ops on an empty map.
  void advise_sequential(size_t begin = 0, size_t end = SIZE_MAX) const;
  void advise_random(size_t begin = 0, size_t end = SIZE_MAX) const;
  // Drops this process's mapping of the whole pages inside [begin, end): the
  // data stays in the page cache but no longer counts towards this process's
  // resident set. Used behind a sequential cursor to keep RSS bounded.
  void release(size_t begin, size_t end) const;

 private:
  std::filesystem::path path_;
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
};

// An anonymous scratch file in the temporary directory ($TMPDIR or /tmp),
// unlinked at creation so nothing is left behind even on a crash. Data is
// appended through a 1 MiB buffer; map() then makes it readable in place.
class SpillFile {
 public:
  SpillFile() = default;
  ~SpillFile();
  SpillFile(SpillFile&& other) noexcept;
  SpillFile& operator=(SpillFile&& other) noexcept;
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  // `what` names the owner in error messages ("mesh.obj vertex table").
  static StatusOr<SpillFile> create(std::string what);
  Status append(const void* bytes, size_t count);
  // Flushes and maps what was written; append() is not allowed afterwards.
  Status map();

  const uint8_t* data() const { return data_; }
  size_t size() const { return written_; }

 private:
  Status flush();
  std::string what_;
  int fd_ = -1;
  std::vector<uint8_t> buffer_;
  size_t written_ = 0;
  const uint8_t* data_ = nullptr;
};

}  // namespace raylod
