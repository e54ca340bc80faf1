#!/usr/bin/env bash
# One ctest case of raylod under mpirun (tests/CMakeLists.txt registers them
# when RAYLOD_WITH_MPI is on): runs CASE with NP ranks and the same command
# in one process, and compares the outputs byte for byte.
#   mpi_check.sh MPIEXEC RAYLOD NP CASE
# CASE: render (one frame, with a depth AOV) | run (one view: image, cut and
# mesh; and `raylod probe`'s cut) | views (3 views, a cut each) | shared-cut
# (3 views, one cut) | fail (a bad views file and an unreadable mesh: non-zero
# exit, the error printed once by rank 0, no image written) | fail-rank (one
# rank fails: its mesh unreadable, rank 0's image write, one view's image
# write; and ranks started with other arguments: non-zero exit, the error
# with the rank printed once by rank 0, no image and no temporary written) | kill-rank (the last rank killed with
# SIGKILL while writing an image: the job ends, no complete image of that
# view, and the next run removes the dead rank's temporary) | corrupt-store
# (a page of the store damaged: the job ends with the checksum error, no
# image; the next run rebuilds the store and renders what one process does).
# Everything happens in a temporary folder removed on exit, pass or fail.
set -euo pipefail
mpiexec="$1" raylod="$2" np="$3" case="$4"
root="${RAYLOD_TEST_TMP:-${TMPDIR:-/tmp}}"
mkdir -p "$root"
tmp="$(mktemp -d "$root/mpi-$case-np$np.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"

# More ranks than cores (CI machines have 2), and as root in containers.
export OMPI_MCA_rmaps_base_oversubscribe=1
mpi() { "$mpiexec" --allow-run-as-root --oversubscribe -np "$np" "$raylod" "$@" --threads 1; }
one() { "$raylod" "$@" --threads 1; }
fail() { echo "FAIL: $*" >&2; exit 1; }
same() { cmp "$1" "$2" >/dev/null || fail "$1 and $2 differ"; echo "same bytes: $1 $2"; }

# A 6k-triangle teapot (a file, so that both runs use one store) at 96 x 64:
# 6 tiles of 32 x 32.
"$raylod" gen teapot --triangles 6000 -o mesh.ply >/dev/null 2>&1
cat > scene.json <<'JSON'
{"camera": {"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0], "fov_y": 34, "width": 96, "height": 64},
 "materials": {"red": {"type": "glossy", "color": [0.7, 0.2, 0.1], "specular": [0.4, 0.4, 0.4], "shininess": 40},
               "floor": {"type": "mirror", "reflectance": 0.5}},
 "objects": [{"mesh": "mesh.ply", "material": "red"}],
 "ground": {"height": 0, "size": 30, "material": "floor"},
 "lights": [{"type": "point", "position": [5, 9, 5], "intensity": 120}],
 "spp": 2, "max_depth": 2, "seed": 5}
JSON
cat > views.json <<'JSON'
[{"eye": [6.5, 4.8, 8.5], "look_at": [0.2, 1.3, 0]},
 {"eye": [-8.5, 4.8, 6.5], "look_at": [0.2, 1.3, 0], "width": 48, "height": 32},
 {"eye": [3.0, 2.5, 4.0], "look_at": [0.2, 1.3, 0], "fov_y": 40}]
JSON
mkdir -p mpi one

# The simplified meshes and cuts of a cache, by name (names are their keys).
cache_files() { (cd "$1/simplified" && ls -- *.cut *.drc 2>/dev/null | sort); }
same_caches() {
  local a b
  a="$(cache_files "$1")" b="$(cache_files "$2")"
  [ -n "$a" ] || fail "no simplified mesh in $1"
  [ "$a" = "$b" ] || fail "the caches hold different meshes: [$a] against [$b]"
  for f in $a; do same "$1/simplified/$f" "$2/simplified/$f"; done
}

case "$case" in
  render)
    # mpirun first: rank 0 builds nothing here (render reads the mesh), but
    # every rank loads it and renders its tiles.
    mpi render scene.json -o mpi/frame.png --aov depth -q
    one render scene.json -o one/frame.png --aov depth -q
    same mpi/frame.png one/frame.png
    same mpi/frame.depth.exr one/frame.depth.exr
    ;;
  run)
    # mpirun first, so that rank 0 builds the store while the others wait.
    RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json -o mpi/view.png --rays 600 --export-mesh mpi/mesh.glb -q
    RAYLOD_CACHE_DIR="$tmp/cache-one" one run scene.json -o one/view.png --rays 600 --export-mesh one/mesh.glb -q
    same mpi/view.png one/view.png
    same mpi/mesh.glb one/mesh.glb
    same_caches cache-mpi cache-one
    RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi probe scene.json --rays 700 -o mpi/probe.cut >/dev/null 2>&1
    RAYLOD_CACHE_DIR="$tmp/cache-one" one probe scene.json --rays 700 -o one/probe.cut >/dev/null 2>&1
    same mpi/probe.cut one/probe.cut
    ;;
  views|shared-cut)
    extra=()
    [ "$case" = shared-cut ] && extra=(--shared-cut)
    RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json --views views.json -o mpi/v_##.png --rays 500 "${extra[@]}" \
      --stats-json mpi/stats.json -q
    RAYLOD_CACHE_DIR="$tmp/cache-one" one run scene.json --views views.json -o one/v_##.png --rays 500 "${extra[@]}" -q
    for i in 00 01 02; do same "mpi/v_$i.png" "one/v_$i.png"; done
    [ ! -e mpi/v_03.png ] || fail "a fourth image"
    same_caches cache-mpi cache-one
    # Rank 0's statistics hold every view, each saying which rank rendered it.
    grep -q '"ranks": '"$np" mpi/stats.json || fail "stats.json does not give $np ranks"
    [ "$(grep -c '"rank":' mpi/stats.json)" -eq 3 ] || fail "stats.json does not have 3 views with their rank"
    ;;
  fail)
    # A bad element in the views file: every rank fails before any work.
    printf '[{"eye": [6.5, 4.8, 8.5], "look_at": [0, 1, 0]}, {"eye": [1, 2], "look_at": [0, 1, 0]}]' > bad.json
    status=0
    out="$(RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json --views bad.json -o mpi/v_##.png -q 2>&1)" || status=$?
    [ "$status" -ne 0 ] || fail "a bad views file exited 0"
    [ "$(grep -c 'raylod run: error: .*bad.json: \[1\].eye: expected an array of 3 numbers' <<<"$out")" -eq 1 ] ||
      fail "the error is not printed once: $out"
    # An unreadable mesh: rank 0's store build fails, the others learn it at the barrier.
    printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\0\0\0\0' > broken.ply
    sed 's/mesh.ply/broken.ply/' scene.json > broken.json
    for command in "run broken.json --views views.json -o mpi/v_##.png" "run broken.json -o mpi/v.png" \
                   "render broken.json -o mpi/v.png"; do
      status=0
      # shellcheck disable=SC2086  # the command is words without spaces
      out="$(RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi $command -q 2>&1)" || status=$?
      [ "$status" -ne 0 ] || fail "$command with a broken mesh exited 0"
      [ "$(grep -c "raylod ${command%% *}: error: .*broken.ply: truncated" <<<"$out")" -eq 1 ] ||
        fail "$command: the error is not printed once: $out"
    done
    [ -z "$(ls -A mpi)" ] || fail "images were written: $(ls mpi)"
    echo "every failure exited non-zero with one error and no image"
    ;;
  fail-rank)
    # No file but the images asked for: no temporaries (NAME.tmp-...), no partial image.
    no_temporaries() {
      local left
      left="$(find mpi -name '*.tmp-*')"
      [ -z "$left" ] || fail "temporaries left: $left"
    }
    # A status and stderr of the last command: non-zero, and the error once, from rank 0.
    expect_error() {
      [ "$status" -ne 0 ] || fail "$1: exited 0"
      [ "$(grep -c -- "$2" <<<"$out")" -eq 1 ] || fail "$1: '$2' is not printed once: $out"
    }
    printf 'ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\0\0\0\0' > broken.ply
    # The last rank alone reads a broken mesh: the same command line in
    # another folder (-wdir), whose scene.json names it. It fails loading,
    # the others wait at the agreement, rank 0 names it.
    last=$((np - 1))
    mkdir -p other/mpi
    cp broken.ply other/
    sed 's/"mesh.ply"/"broken.ply"/' scene.json > other/scene.json
    status=0
    out="$("$mpiexec" --allow-run-as-root --oversubscribe -np "$last" "$raylod" render scene.json -o mpi/f.png -q --threads 1 : \
           -np 1 -wdir "$tmp/other" "$raylod" render scene.json -o mpi/f.png -q --threads 1 2>&1)" || status=$?
    expect_error "render, a broken mesh on rank $last" "raylod render: error: rank $last of $np: .*broken.ply: truncated"
    [ ! -e mpi/f.png ] || fail "render with a broken mesh on rank $last wrote mpi/f.png"
    [ -z "$(ls -A other/mpi)" ] || fail "rank $last wrote into other/mpi"
    no_temporaries
    # Ranks started with other arguments (mpirun's A : B form) would meet in
    # other collectives: refused before any work, rank 0 saying which.
    status=0
    out="$("$mpiexec" --allow-run-as-root --oversubscribe -np "$last" "$raylod" render scene.json -o mpi/f.png -q --threads 1 : \
           -np 1 "$raylod" run scene.json --orbit 2 -o mpi/o_#.png -q --threads 1 2>&1)" || status=$?
    expect_error "ranks with other arguments" "raylod: error: rank $last of $np: started with other arguments than rank 0's"
    [ -z "$(ls -A mpi)" ] || fail "ranks with other arguments wrote $(ls -A mpi)"
    no_temporaries
    # The same when the odd rank would end at once (--help, --version):
    # raylod's own error, not mpirun's for a rank that left without MPI.
    for early in --version --help; do
      status=0
      out="$("$mpiexec" --allow-run-as-root --oversubscribe -np "$last" "$raylod" render scene.json -o mpi/f.png -q --threads 1 : \
             -np 1 "$raylod" "$early" 2>&1)" || status=$?
      expect_error "a rank started with $early" "raylod: error: rank $last of $np: started with other arguments than rank 0's"
      [ -z "$(ls -A mpi)" ] || fail "a rank started with $early: the others wrote $(ls -A mpi)"
    done
    # The frame's name is a folder: refused before rendering, once. (A
    # write failing after the render, on whichever rank, is the run --views
    # case below.)
    mkdir mpi/g.png
    status=0
    out="$(mpi render scene.json -o mpi/g.png -q 2>&1)" || status=$?
    expect_error "render, the frame's name a folder" "raylod render: error: mpi/g.png: the image: is a directory"
    [ -z "$(ls -A mpi/g.png)" ] || fail "something was written into mpi/g.png"
    rmdir mpi/g.png
    no_temporaries
    # View 1's name is a folder: every view's name is checked before any
    # work, so nothing is rendered or written.
    mkdir mpi/v_01.png
    status=0
    out="$(RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json --views views.json -o mpi/v_##.png --rays 500 -q 2>&1)" ||
      status=$?
    expect_error "run --views, view 1's name a folder" "raylod run: error: mpi/v_01.png: the image: is a directory"
    [ -z "$(ls -A mpi/v_01.png)" ] || fail "something was written into mpi/v_01.png"
    rmdir mpi/v_01.png
    [ -z "$(ls -A mpi)" ] || fail "view 1's name a folder: images were written: $(ls -A mpi)"
    # An image's write fails after its render, on whichever rank renders
    # it (the fault point fails it as a failed rename would): the job fails
    # with that rank's error once, and leaves no image and no temporary.
    status=0
    out="$(RAYLOD_CACHE_DIR="$tmp/cache-mpi" "$mpiexec" --allow-run-as-root --oversubscribe -np "$np" \
           -x RAYLOD_FAULT_POINT=image.before_rename:error \
           "$raylod" run scene.json --views views.json -o mpi/v_##.png --rays 500 -q --threads 1 2>&1)" || status=$?
    expect_error "run --views, the writes failing" \
      "raylod run: error: \(rank [0-9]* of $np: \)\?mpi/v_0[0-2].png: could not rename into place"
    [ -z "$(ls -A mpi)" ] || fail "the writes failing: images were written: $(ls -A mpi)"
    no_temporaries
    echo "every failure of one rank exited non-zero with that rank's error once and no partial image"
    ;;
  kill-rank)
    # The last rank dies (SIGKILL, as a lost node) after writing its first
    # image to a temporary: mpirun ends the job (no rank waits forever).
    last=$((np - 1))
    status=0
    out="$(RAYLOD_CACHE_DIR="$tmp/cache-mpi" "$mpiexec" --allow-run-as-root --oversubscribe \
           -np "$last" "$raylod" run scene.json --orbit 8 -o mpi/v_##.png --rays 300 -q --threads 1 : \
           -np 1 -x RAYLOD_FAULT_POINT=image.before_rename \
           "$raylod" run scene.json --orbit 8 -o mpi/v_##.png --rays 300 -q --threads 1 2>&1)" || status=$?
    [ "$status" -ne 0 ] || fail "a killed rank: the job exited 0"
    grep -q "rank $last .*signal 9" <<<"$out" || fail "mpirun does not say rank $last was killed: $out"
    left="$(find mpi -name '*.tmp-*')"
    [ -n "$left" ] || fail "the killed rank left no temporary (did it render a view?)"
    # Its view has no image, only the temporary; the next run removes it.
    for t in $left; do [ ! -e "${t%%.tmp-*}" ] || fail "${t%%.tmp-*} was written by a killed rank"; done
    RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json --orbit 8 -o mpi/v_##.png --rays 300 -q
    [ -z "$(find mpi -name '*.tmp-*')" ] || fail "the next run left temporaries: $(find mpi -name '*.tmp-*')"
    [ "$(find mpi -name 'v_*.png' | wc -l)" -eq 8 ] || fail "the next run did not write the 8 images"
    echo "a killed rank ended the job; the next run removed its temporary"
    ;;
  corrupt-store)
    # The store built by one process, then one byte of its page data (the
    # file's last part) changed: the ranks' probes read the page and fail.
    one build mesh.ply -q >/dev/null 2>&1
    size=$(stat -c %s mesh.ply.raylod)
    printf '\xa5' | dd of=mesh.ply.raylod bs=1 seek=$((size - 5000)) conv=notrunc status=none
    status=0
    out="$(RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json --views views.json -o mpi/v_##.png --rays 500 -q 2>&1)" ||
      status=$?
    [ "$status" -ne 0 ] || fail "a corrupt store: exited 0"
    [ "$(grep -c 'raylod run: error: .*mesh.ply.raylod: page 0 .*checksum mismatch' <<<"$out")" -eq 1 ] ||
      fail "a corrupt store: the checksum error is not printed once: $out"
    [ -e mesh.ply.raylod.corrupt ] || fail "the corruption was not recorded beside the store"
    [ -z "$(ls -A mpi)" ] || fail "images or temporaries were written: $(ls -A mpi)"
    # The next run's check (rank 0) rebuilds the store; the images are one process's.
    RAYLOD_CACHE_DIR="$tmp/cache-mpi" mpi run scene.json --views views.json -o mpi/v_##.png --rays 500 -q
    [ ! -e mesh.ply.raylod.corrupt ] || fail "the store was not rebuilt"
    RAYLOD_CACHE_DIR="$tmp/cache-one" one run scene.json --views views.json -o one/v_##.png --rays 500 -q
    for i in 00 01 02; do same "mpi/v_$i.png" "one/v_$i.png"; done
    echo "a corrupt store ended the job with its error; the next run rebuilt it"
    ;;
  *) fail "unknown case $case" ;;
esac
