// raylod run's staged-write fallback: when the cache's disk refuses the staged
// simplified mesh, the run stages it in the system's temporary folder and
// renders without caching. The decision (staged_write_refused) reads the
// Status's code and path, never its message.
#include <cerrno>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "pipeline/pipeline.h"
#include "streaming/draco_io.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

TEST(StagedWrite, ATypedWriteFailureOfTheStagedFileIsRefused) {
  const fs::path staged = "/cache/simplified/simplified-1-0.drc.tmp-1-0-7.drc";
  const Status full = Status::write_failed(staged.string(), staged.string() + ": write failed (disk full?)", ENOSPC);
  EXPECT_EQ(full.code(), StatusCode::kNoSpace);
  EXPECT_TRUE(staged_write_refused(full, staged));
  const Status read_only = Status::write_failed(staged.string(), staged.string() + ": cannot create output file", EROFS);
  EXPECT_EQ(read_only.code(), StatusCode::kWriteFailed);
  EXPECT_TRUE(staged_write_refused(read_only, staged));
  // Context added on the way up keeps the code and the path.
  const Status wrapped = full.with_context("simplify");
  EXPECT_EQ(wrapped.code(), StatusCode::kNoSpace);
  EXPECT_EQ(wrapped.path(), staged.string());
  EXPECT_TRUE(staged_write_refused(wrapped, staged));
}

TEST(StagedWrite, AMessageNamingTheFileIsNotAWriteFailure) {
  const fs::path staged = "/cache/simplified/simplified-1-0.drc.tmp-1-0-7.drc";
  // What the old message match took for a refused write: the encoder's or
  // the store's errors that happen to name the staged path.
  EXPECT_FALSE(staged_write_refused(Status::error(staged.string() + ": Draco encoding failed: bad mesh"), staged));
  EXPECT_FALSE(staged_write_refused(Status::error("page 3 of " + staged.string() + ": checksum mismatch"), staged));
  // A write failure of another file, and success, are not either.
  EXPECT_FALSE(staged_write_refused(Status::write_failed("/tmp/other.drc", "/tmp/other.drc: write failed", ENOSPC),
                                    staged));
  EXPECT_FALSE(staged_write_refused(Status::ok(), staged));
}

IndexedMesh one_triangle() {
  IndexedMesh m;
  m.positions = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  m.indices = {0, 1, 2};
  return m;
}

TEST(StagedWrite, WriteDracoTypesItsFailures) {
  const fs::path dir = test::scratch_dir("staged-write");
  DracoOptions options;
  // The folder is gone: the output cannot be created.
  const fs::path gone = dir / "gone" / "x.drc";
  auto written = write_draco(gone, one_triangle(), options);
  ASSERT_FALSE(written.is_ok());
  EXPECT_TRUE(written.status().is_write_failure()) << written.status().message();
  EXPECT_EQ(written.status().path(), gone.string());
  EXPECT_TRUE(staged_write_refused(written.status(), gone));
  // A bad mesh names the file too, but is no write failure.
  IndexedMesh bad = one_triangle();
  bad.indices = {0, 1, 7};
  const fs::path here = dir / "bad.drc";
  written = write_draco(here, bad, options);
  ASSERT_FALSE(written.is_ok());
  EXPECT_NE(written.status().message().find(here.string()), std::string::npos) << written.status().message();
  EXPECT_FALSE(staged_write_refused(written.status(), here));
  // And a good write succeeds.
  EXPECT_TRUE(write_draco(here, one_triangle(), options).is_ok());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace raylod
