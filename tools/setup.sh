#!/usr/bin/env bash
# One-stop set-up for raylod on Debian 12. Idempotent.
#   tools/setup.sh run    install what is missing, build, render the embedded default scene
#   tools/setup.sh test   install what is missing, build, run the test suite
#   tools/setup.sh build  install what is missing and build only
#   tools/setup.sh sanitize  the test suite and a CLI smoke test on bad inputs under
#                            ASan + UBSan (build-sanitize), then the fuzz targets (as fuzz)
#   tools/setup.sh fuzz   build the libFuzzer targets with clang (build-fuzz) and run each briefly
# Build folders: RAYLOD_BUILD_DIR (build), RAYLOD_SANITIZE_BUILD_DIR (build-sanitize),
# RAYLOD_FUZZ_BUILD_DIR (build-fuzz).
set -euo pipefail
cd "$(dirname "$0")/.."

mode="${1:-run}"
case "$mode" in
  run|test|build|sanitize|fuzz) ;;
  *) echo "usage: tools/setup.sh [run|test|build|sanitize|fuzz]" >&2; exit 2 ;;
esac
build_dir="${RAYLOD_BUILD_DIR:-build}"
sanitize_dir="${RAYLOD_SANITIZE_BUILD_DIR:-build-sanitize}"
fuzz_dir="${RAYLOD_FUZZ_BUILD_DIR:-build-fuzz}"
packages=(cmake g++ make pkg-config time
          libopenmesh-dev libdraco-dev libglm-dev libopenimageio-dev openimageio-tools
          libtbb-dev libembree-dev libgtest-dev libgmock-dev libbenchmark-dev
          nlohmann-json3-dev libtinygltf-dev libmeshoptimizer-dev fonts-dejavu-core
          libopenmpi-dev openmpi-bin)
# libFuzzer comes with clang (its runtime is in libclang-rt-14-dev).
case "$mode" in sanitize|fuzz) packages+=(clang libclang-rt-14-dev) ;; esac

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# The sanitizer runtimes' settings for everything run below. Leak checking
# stays on: the suite runs clean with it (TBB's, Embree's and OpenImageIO's
# per-thread and global allocations are still reachable at exit, so LSan does
# not report them). Distinct exit codes tell a sanitizer report from raylod's
# own error exit (1); halt_on_error and -fno-sanitize-recover make any
# finding fatal.
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:halt_on_error=1:exitcode=86:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1:exitcode=87}"
# LeakSanitizer's exit-time scan does not follow __tls_get_addr's dynamic TLS
# blocks: with it on (the default), its tracer crashed ("Tracer caught signal
# 11" at the same small address every time) in the raylod process of
# Run.AViewFinerThanTheStoreGridIsWarnedAbout in 6 of 10 runs and four times
# in a row in one suite (2026-11-29; the process loads OpenImageIO's
# libraries, which hold thread-local storage, with dlopen on a thread of its
# own); with it off, 0 of 10, and the whole suite ran without a rerun.
# Memory only a dynamic TLS block points to would be reported as a leak;
# none is.
export LSAN_OPTIONS="${LSAN_OPTIONS:-intercept_tls_get_addr=0}"

# Runs raylod (the sanitizer build) on bad inputs: each must fail with exit
# status 1 and an error message naming the input, and without a sanitizer report.
smoke_bad_inputs() {
  local exe="$1" tmp
  tmp="$(mktemp -d "${TMPDIR:-/tmp}/raylod-smoke.XXXXXX")"
  trap "rm -rf '$tmp'" EXIT
  printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\0\0\0\0\0\0\0\0' \
    > "$tmp/truncated.ply"
  # Binary STL: 80-byte header, a count of 5 triangles, data for 1 (50 bytes).
  { head -c 80 /dev/zero; printf '\5\0\0\0'; head -c 50 /dev/zero; } > "$tmp/wrong-count.stl"
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n' > "$tmp/bad-index.obj"
  printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 -9 2\n' > "$tmp/bad-negative-index.obj"
  printf '{"camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0]}, "objects": [' > "$tmp/bad.json"
  printf '{"camera": {"eye": [0, 0, 5], "look_at": [0, 0, 0], "width": 1e400}}' > "$tmp/bad-number.json"
  # Garbage after the magic (and, for Draco, after a valid version and mesh header).
  garbage() { yes 'raylod garbage 0123456789 @~^ ' | head -c "$1" || true; }  # yes ends on SIGPIPE
  { printf 'DRACO'; garbage 300; } > "$tmp/garbage.drc"
  { printf 'DRACO\2\2\1\1\0\0'; garbage 300; } > "$tmp/garbage-v22.drc"
  { printf 'RLODSTOR\1\0\0\0'; garbage 200; } > "$tmp/garbage.raylod"
  # A GLB whose header claims more bytes than the file holds.
  { printf 'glTF\2\0\0\0\100\0\0\0'; printf '{}'; } > "$tmp/truncated.glb"
  # A cut file header claiming a 1 GiB payload.
  { printf 'RLODCUT\032\1\0\0\0\0\0\0\0\0\0\0\100\0\0\0\0'; head -c 72 /dev/zero; } > "$tmp/huge-claim.cut"
  local cases=(
    "info $tmp/truncated.ply|truncated.ply"
    "build $tmp/truncated.ply|truncated.ply"
    "info $tmp/wrong-count.stl|wrong-count.stl"
    "info $tmp/bad-index.obj|bad-index.obj"
    "info $tmp/bad-negative-index.obj|bad-negative-index.obj"
    "render $tmp/bad.json -o $tmp/out.png|bad.json"
    "render $tmp/bad-number.json -o $tmp/out.png|bad-number.json"
    "info $tmp/does-not-exist.ply|does-not-exist.ply"
    "render $tmp/does-not-exist.json -o $tmp/out.png|does-not-exist.json"
    "info $tmp/garbage.drc|garbage.drc"
    "info $tmp/garbage-v22.drc|garbage-v22.drc"
    "info $tmp/truncated.glb|truncated.glb"
    "info $tmp/garbage.raylod|garbage.raylod"
    "info $tmp/huge-claim.cut|huge-claim.cut"
  )
  local c args name out status failed=0
  for c in "${cases[@]}"; do
    args="${c%|*}"; name="${c##*|}"
    status=0
    # shellcheck disable=SC2086  # args is a list of words without spaces
    out="$("$exe" $args 2>&1)" || status=$?
    # LeakSanitizer's tracer crashing at exit (see the suite below): once more.
    if grep -q "LeakSanitizer has encountered a fatal error" <<<"$out"; then
      echo "setup: raylod $args: LeakSanitizer's tracer crashed at exit; running it again" >&2
      status=0
      # shellcheck disable=SC2086
      out="$("$exe" $args 2>&1)" || status=$?
    fi
    if [ "$status" -ne 1 ] || ! grep -q "error: .*$name" <<<"$out" || grep -q "Sanitizer\|runtime error:" <<<"$out"; then
      echo "setup: smoke test FAILED: raylod $args (exit status $status):" >&2
      echo "$out" >&2
      failed=1
    else
      echo "setup: smoke ok: raylod $args: $(grep -m1 'error: ' <<<"$out")"
    fi
  done
  rm -rf "$tmp"
  trap - EXIT
  return "$failed"
}

fuzz_build_and_run() {
  CXX=clang++ cmake -S . -B "$fuzz_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRAYLOD_FUZZ=ON \
    -DRAYLOD_BUILD_TESTS=OFF -DRAYLOD_BUILD_TOOLS=OFF -DRAYLOD_WITH_MPI=OFF
  cmake --build "$fuzz_dir" --target raylod_fuzz -j"$(nproc)"
  ctest --test-dir "$fuzz_dir" --output-on-failure -j"$(nproc)"
}

case "$mode" in
  sanitize)
    # RelWithDebInfo: optimised like the CI build, with line numbers in the reports.
    # The benchmarks in tools/ are not tests and are left out. So is MPI: Open
    # MPI keeps allocations past MPI_Finalize that LeakSanitizer would report
    # in every mpirun test; those run in the Release suite (`test`).
    cmake -S . -B "$sanitize_dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRAYLOD_SANITIZE=ON -DRAYLOD_BUILD_TOOLS=OFF \
      -DRAYLOD_WITH_MPI=OFF
    cmake --build "$sanitize_dir" -j"$(nproc)"
    # All tests but one: Run.MemoryLimitBelowTheFullMeshCoarsensTheCut sizes the
    # page cache from the process's RSS, which under ASan also holds the shadow
    # memory and the quarantine of freed blocks (479 MiB against 300 MiB).
    #
    # LeakSanitizer's stop-the-world tracer itself sometimes crashes at a
    # process's exit on this kind of virtual machine ("Tracer caught signal
    # 11 ... LeakSanitizer has encountered a fatal error", after the test
    # passed; google/sanitizers#1353): no leak is reported, the check did not
    # run. Seen once in each of six sanitizer suites of 633 to 638 tests
    # here (2026-11-29), and once twice in a row in the same test (a raylod
    # process it runs). So when every failed test shows that crash, those
    # tests run again, up to three times, and must pass; any other failure
    # fails the job at once.
    sanitize_log="$sanitize_dir/ctest-output.log"
    failed_log="$sanitize_dir/Testing/Temporary/LastTestsFailed.log"
    if ! ctest --test-dir "$sanitize_dir" --output-on-failure -j"$(nproc)" --timeout 3000 \
      -E '^Run\.MemoryLimitBelowTheFullMeshCoarsensTheCut$' --output-log "$sanitize_log"; then
      passed=0
      for attempt in 1 2 3; do
        failed=$(grep -c . "$failed_log" || true)
        crashes=$(grep -c "LeakSanitizer has encountered a fatal error" "$sanitize_log" || true)
        if ! [ "$failed" -gt 0 ] || ! [ "$crashes" -ge "$failed" ]; then break; fi
        # By name (the log's "N:name" lines): the tests' numbers are not
        # stable from one ctest run to the next here.
        names=$(sed 's/^[0-9]*://; s/[][\.*^$+?(){}|/]/\\&/g' "$failed_log" | paste -sd'|')
        echo "setup.sh: $failed test(s) failed with LeakSanitizer's tracer crashing at exit; running them again ($attempt of 3)" >&2
        if ctest --test-dir "$sanitize_dir" --output-on-failure --timeout 3000 -R "^($names)\$" \
          --output-log "$sanitize_log"; then
          passed=1
          break
        fi
      done
      [ "$passed" -eq 1 ] || exit 1
    fi
    smoke_bad_inputs "$sanitize_dir/raylod"
    fuzz_build_and_run
    exit 0
    ;;
  fuzz)
    fuzz_build_and_run
    exit 0
    ;;
esac

cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build_dir" -j"$(nproc)"

case "$mode" in
  build) ;;
  run)
    mkdir -p raylod-out
    "$build_dir/raylod" run --compare -o raylod-out/default.png --stats-json raylod-out/default.json
    echo "setup: wrote raylod-out/default.png"
    ;;
  test)
    # Khronos's glTF-Validator for the test that checks every .glb raylod
    # writes (tools/validate_gltf.js), into tools/gltf-validator/ (gitignored).
    # Best effort: without node or the npm registry that test skips and says so.
    if ! command -v npm >/dev/null 2>&1; then
      sudo=""
      [ "$(id -u)" -eq 0 ] || sudo="sudo"
      DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends nodejs npm \
        || echo "setup: could not install nodejs/npm; the glTF-Validator test will be skipped"
    fi
    if [ ! -d tools/gltf-validator/node_modules/gltf-validator ] && command -v npm >/dev/null 2>&1; then
      mkdir -p tools/gltf-validator
      npm install --prefix tools/gltf-validator --no-save --no-audit --no-fund gltf-validator \
        || echo "setup: npm install gltf-validator failed; the glTF-Validator test will be skipped"
    fi
    ctest --test-dir "$build_dir" --output-on-failure -j"$(nproc)" --timeout 1500
    ;;
esac
