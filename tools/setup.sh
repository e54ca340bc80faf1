#!/usr/bin/env bash
# One-stop set-up for raylod on Debian 12. Idempotent.
#   tools/setup.sh run    install what is missing, build, render the embedded default scene
#   tools/setup.sh test   install what is missing, build, run the test suite
#   tools/setup.sh build  install what is missing and build only
set -euo pipefail
cd "$(dirname "$0")/.."

mode="${1:-run}"
build_dir="${RAYLOD_BUILD_DIR:-build}"
packages=(cmake g++ make pkg-config time
          libopenmesh-dev libdraco-dev libglm-dev libopenimageio-dev openimageio-tools
          libtbb-dev libembree-dev libgtest-dev libgmock-dev libbenchmark-dev
          nlohmann-json3-dev libmeshoptimizer-dev fonts-dejavu-core)

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
    ctest --test-dir "$build_dir" --output-on-failure -j"$(nproc)" --timeout 1500
    ;;
  *) echo "usage: tools/setup.sh [run|test|build]" >&2; exit 2 ;;
esac
