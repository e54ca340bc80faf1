// A store's record that its mesh's content hash was read and matched, so
// that later checks of an unchanged mesh need not read the whole file again.
//
// Checking a store against its mesh hashes the mesh: 250 MB for the 10M
// teapot (about 1.5 s), 2.5 GB at 100M (about 2 s warm, far more cold), on
// every `raylod run`. Like git's index and make, raylod trusts a file's
// status instead when it can:
//
//   STORE.checked   the store file it vouches for (device, inode, size,
//                   mtime) and the mesh's device, inode, size, mtime and
//                   ctime at the moment its content hash was read.
//
// A later check that finds the same store file and the same mesh status
// skips the hash. ctime cannot be set from user space: any write, truncate,
// `touch -d`, chmod or rename of the mesh changes it, and replacing the mesh
// changes its inode, so those all fall back to hashing. A record is written
// only for a mesh whose ctime is at least kSettleNs older than the moment
// its hash began: a write in the same timestamp tick as the last one could
// otherwise leave the status unchanged (git's "racily clean" case).
// `raylod build --verify` always hashes.
#pragma once

#include <sys/stat.h>

#include <cstdint>
#include <filesystem>
#include <optional>

#include "core/status.h"

namespace raylod {

constexpr uint64_t kSettleNs = 1000000000ull;  // 1 s: far above any file system's timestamp tick

// The status of a file that identifies its content for the record.
struct FileStatus {
  uint64_t device = 0, inode = 0, bytes = 0, mtime_ns = 0, ctime_ns = 0;
  bool operator==(const FileStatus&) const = default;
};
StatusOr<FileStatus> file_status(const std::filesystem::path& path);
FileStatus file_status_of(const struct stat& st);

// CLOCK_REALTIME in nanoseconds, the clock file timestamps come from.
uint64_t realtime_ns();

struct SourceRecord {
  FileStatus store;  // ctime not compared: reading a store does not change it, but a rename of it does
  FileStatus mesh;
  uint64_t hash = 0;  // the mesh's content hash, as the store header records it
};

std::filesystem::path source_record_path(const std::filesystem::path& store);

// Writes the record for `store` (atomically) if mesh.ctime_ns + kSettleNs <=
// hash_started_ns, else removes any old one. Returns whether one was written.
// Failing to write (a read-only folder) is not an error: checks then hash.
bool note_source_checked(const std::filesystem::path& store, const FileStatus& mesh, uint64_t hash,
                         uint64_t hash_started_ns);

// True if `store`'s record vouches that a mesh with status `mesh` still has
// content hash `hash`: the record reads, names this very store file, and its
// mesh status and hash are the same.
bool source_record_vouches(const std::filesystem::path& store, const FileStatus& mesh, uint64_t hash);

}  // namespace raylod
