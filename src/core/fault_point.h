// Fault injection for tests: named points at which the process kills itself
// with SIGKILL, exactly like `kill -9` (no destructors, no atexit handlers, no
// cleanup), so that tests can check that every output survives a kill at a
// bad moment: the next run uses nothing partial and leaves no orphans
// (tests/info/fault_injection_test.cpp).
//
// fault_point(name) does nothing unless the environment variable
// RAYLOD_FAULT_POINT equals `name`, or `name:error`: then it returns true
// and the caller fails as its I/O there would have failed (the process
// lives on, to show how a failure is reported and cleaned up). The variable
// is read once per process and cached, so an unarmed point costs one string
// compare. Points sit at a
// handful of coarse moments (once per file written), never in per-triangle or
// per-ray loops. For testing only: nothing in normal use sets the variable.
//
// The points (name: where the process dies):
//   build.binned         store build, after binning (pass 2), before the store's
//                        temporary is created
//   build.pages          store build, mid-way through writing the pages into the
//                        store's temporary (no header yet)
//   build.before_rename  store build, the temporary complete (header, pages,
//                        tables), before it is fsynced and renamed into place
//   cut.before_rename    a cut file (the cache entry's .cut in `run`, the -o of
//                        `probe`) written to its temporary, before the rename
//   draco.partial        a Draco file (the simplified mesh `run` stages in the
//                        cache folder) half written to its temporary
//   cache.before_meta    a cache entry's .drc and .cut renamed into place, its
//                        .json (which makes it an entry) not yet written
//   run.render           `run`, after simplify, before rendering: the staged
//                        simplified meshes are in the cache folder, in use
//   image.before_rename  an image written to its temporary and read back,
//                        before the rename (also as image.before_rename:error:
//                        the rename fails)
//   report.files         `report`, its pictures and meshes written to the
//                        report's temporary folder, before report.json and
//                        REPORT.md (also as report.files:error: the report
//                        fails there)
#pragma once

namespace raylod {

// Kills the process with SIGKILL if RAYLOD_FAULT_POINT is `name`; true if
// it is `name:error` (the caller then fails), else false.
bool fault_point(const char* name);

}  // namespace raylod
