#!/bin/bash
# Reproduces the README's "Accuracy across meshes" table: every scene at the
# defaults (deviation criterion) and with --criterion diagonal, each as
#   raylod run SCENE [--mesh FILE] --no-cache --compare --stats-json ...
# and prints one markdown row per scene and view: triangles kept, reduction,
# PSNR against the full render of the same mesh, and the noise floor (the
# full render at seed + 1 against seed).
#
# usage: tools/accuracy.sh [--raylod BIN] [--keep DIR] [--no-default] [-- EXTRA RUN OPTIONS]
#   --raylod BIN    the raylod binary (default build/raylod)
#   --keep DIR      keep images, difference images and stats in DIR (default: a
#                   temporary folder, removed at the end)
#   --no-default    skip the default scene (it generates a 10M-triangle teapot,
#                   250 MB, and its 1.3 GB store on first use)
#   EXTRA           options added to every run (e.g. --tolerance 0.25)
#
# Larger meshes are read from ../shared: the OpenCASCADE tessellations are made
# by ../shared/tools/make-cad-tests.sh (into the work folder), the bunny from
# ../shared/data/stanford, the ABC parts from ../shared/data/abc (their scenes
# made by raylod scene), five more OpenCASCADE sample parts tessellated here
# with occt-draw. Rows whose input is missing are skipped with a note.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
shared=$repo/../shared
raylod=$repo/build/raylod
keep=""
with_default=1
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --raylod) raylod=$2; shift 2 ;;
    --keep) keep=$2; shift 2 ;;
    --no-default) with_default=0; shift ;;
    --) shift; extra=("$@"); break ;;
    -h|--help) sed -n '2,21p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "accuracy.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$raylod" ] || { echo "accuracy.sh: $raylod is not an executable (build first, or pass --raylod)" >&2; exit 2; }
command -v python3 > /dev/null || { echo "accuracy.sh: needs python3 to read the stats JSON" >&2; exit 2; }

if [ -n "$keep" ]; then
  work=$keep
  mkdir -p "$work"
else
  work=$(mktemp -d /tmp/raylod-accuracy-XXXXXX)
  trap 'rm -rf "$work"' EXIT
fi

# The fine OpenCASCADE tessellations.
cad=$work/cad
if [ ! -f "$cad/crankarm_fine.stl" ] && [ -x "$shared/tools/make-cad-tests.sh" ]; then
  mkdir -p "$cad"
  bash "$shared/tools/make-cad-tests.sh" "$cad" > "$cad/make.log" 2>&1 ||
    echo "note: make-cad-tests.sh failed (see $cad/make.log); CAD rows with fine meshes skipped" >&2
fi

# name | view | scene | mesh override (empty: the scene's)
rows=()
[ $with_default = 1 ] && rows+=("teapot, 10,004,976 (default scene)|default|$repo/data/default_scene.json|")
rows+=(
  "pump cover, 437,936|whole|$repo/data/cad/pump_topcover_coarse.json|$cad/pump_topcover_fine.stl"
  "pump cover, 437,936|close-up|$repo/data/cad/pump_topcover_closeup.json|$cad/pump_topcover_fine.stl"
  "crank arm, 125,912|whole|$repo/data/cad/crankarm_coarse.json|$cad/crankarm_fine.stl"
  "crank arm, 125,912|close-up|$repo/data/cad/crankarm_closeup.json|$cad/crankarm_fine.stl"
  "crank arm coarse, 8,244|whole|$repo/data/cad/crankarm_coarse.json|"
  "pump cover coarse, 24,288|close-up|$repo/data/cad/pump_topcover_closeup.json|"
  "Stanford bunny scan, 69,451|whole|$repo/data/scan/bunny_scene.json|"
  "glass bottle, 1,054,066|paper's|$repo/data/paper_bottle_scene.json|"
  "glass teapot + mirror bottle, 2,200,560|default|$repo/data/glass_scene.json|"
)
# The triangle count a binary STL's header declares, with thousands separators.
stl_triangles() {
  python3 -c "import struct,sys; f=open(sys.argv[1],'rb'); f.seek(80); print('{:,}'.format(struct.unpack('<I', f.read(4))[0]))" "$1"
}

# Parts of the ABC dataset (../shared/data/abc), in scenes that `raylod
# scene` frames around each (Z up; 1280 x 960, 4 spp, glossy steel; abc3
# also as a mirror and as glass).
if [ -d "$shared/data/abc" ]; then
  mkdir -p "$work/abc"
  for spec in abc1:glossy abc3:glossy abc5:glossy abc3:mirror abc3:glass; do
    part=${spec%%:*} material=${spec#*:}
    stl=$shared/data/abc/$part.stl
    [ -f "$stl" ] || continue
    name=$part; view="whole (raylod scene --up z)"
    if [ "$material" != glossy ]; then
      name=$part-$material; view="whole, $material (raylod scene --up z --material $material)"
    fi
    if "$raylod" scene "$stl" --up z --material "$material" -o "$work/abc/$name.json" > "$work/abc/$name.log" 2>&1; then
      count=$(stl_triangles "$stl")
      rows+=("ABC $part.stl, $count|$view|$work/abc/$name.json|")
    else
      echo "note: raylod scene failed for $stl (see $work/abc/$name.log)" >&2
    fi
  done
fi

# More of OpenCASCADE's sample parts (Debian occt-misc, which the script
# above installs), tessellated as the script tessellates its fine meshes
# (incmesh 0.005, angular deflection 2 degrees) and framed by `raylod scene`
# (Z up, glossy): parts no default was tuned on (about 4 minutes to mesh).
occ=/usr/share/opencascade/data/occ
if command -v occt-draw > /dev/null && [ -f "$occ/Pump_Nut.brep" ]; then
  mkdir -p "$work/occ"
  parts="Pump_Nut:pump_nut Motor-c:motor bottle:occ_bottle Axis_of_bearing:axis_of_bearing hammer:hammer"
  missing=0
  for p in $parts; do [ -f "$work/occ/${p#*:}.stl" ] || missing=1; done
  if [ $missing = 1 ]; then
    {
      echo "pload MODELING DATAEXCHANGE"
      for p in $parts; do
        echo "restore $occ/${p%%:*}.brep s"
        echo "incmesh s 0.005 -a 2"
        echo "writestl s $work/occ/${p#*:}.stl 1"
      done
      echo "exit"
    } > "$work/occ/tess.tcl"
    occt-draw -b -f "$work/occ/tess.tcl" > "$work/occ/tess.log" 2>&1 ||
      echo "note: occt-draw failed (see $work/occ/tess.log)" >&2
  fi
  for p in $parts; do
    name=${p#*:} stl=$work/occ/${p#*:}.stl
    [ -f "$stl" ] || continue
    if "$raylod" scene "$stl" --up z -o "$work/occ/$name.json" > "$work/occ/$name.log" 2>&1; then
      count=$(stl_triangles "$stl")
      rows+=("OpenCASCADE ${p%%:*}.brep, $count|whole (raylod scene --up z)|$work/occ/$name.json|")
      # A close-up: the eye at 40% of its distance, the view's centre moved
      # a tenth of the way towards it.
      python3 - "$work/occ/$name.json" "$work/occ/$name-close.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
e, l = s["camera"]["eye"], s["camera"]["look_at"]
s["camera"]["eye"] = [l[i] + 0.4 * (e[i] - l[i]) for i in range(3)]
s["camera"]["look_at"] = [l[i] + 0.1 * (e[i] - l[i]) for i in range(3)]
json.dump(s, open(sys.argv[2], "w"), indent=1)
PY
      rows+=("OpenCASCADE ${p%%:*}.brep, $count|close-up (eye at 40%)|$work/occ/$name-close.json|")
    else
      echo "note: raylod scene failed for $stl (see $work/occ/$name.log)" >&2
    fi
  done
fi

summary() {  # stats.json -> "triangles (reduction)|psnr|floor|within"
  python3 - "$1" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
floor = s.get("noise_floor", {}).get("psnr")
print("{:,} ({:.1f}x)|{:.2f}|{}|{}".format(
    s["triangles_out"], s["reduction"], s["psnr"],
    "{:.2f}".format(floor) if floor is not None else "n/a",
    "yes" if s.get("within_noise_floor") else "no"))
PY
}

echo "| mesh | view | deviation: triangles | PSNR dB | diagonal: triangles | PSNR dB | floor dB |"
echo "|---|---|---:|---:|---:|---:|---:|"
i=0
for row in "${rows[@]}"; do
  IFS='|' read -r name view scene mesh <<< "$row"
  if [ -n "$mesh" ] && [ ! -f "$mesh" ]; then
    echo "note: $name ($view) skipped: $mesh is missing" >&2
    continue
  fi
  if ! grep -q generate "$scene" && ! python3 - "$scene" <<'PY'
import json, os, sys
s = json.load(open(sys.argv[1]))
m = s["objects"][0]["mesh"]
sys.exit(0 if not isinstance(m, str) or os.path.exists(os.path.join(os.path.dirname(sys.argv[1]), m)) else 1)
PY
  then
    echo "note: $name ($view) skipped: the scene's mesh is missing" >&2
    continue
  fi
  i=$((i + 1))
  cells=()
  for crit in deviation diagonal; do
    out=$work/$i-$crit
    mkdir -p "$out"
    args=("$scene" --no-cache --compare -q --criterion "$crit" -o "$out/image.png" --stats-json "$out/stats.json")
    [ -n "$mesh" ] && args+=(--mesh "$mesh")
    if ! "$raylod" run "${args[@]}" "${extra[@]}" > "$out/log.txt" 2>&1; then
      echo "note: $name ($view, $crit) failed: $(tail -1 "$out/log.txt")" >&2
      cells+=("failed|||")
      continue
    fi
    cells+=("$(summary "$out/stats.json")")
  done
  IFS='|' read -r dt dp floor dwithin <<< "${cells[0]}"
  IFS='|' read -r gt gp _ gwithin <<< "${cells[1]:-|||}"
  mark() { [ "$1" = no ] && echo " (below)" || true; }
  echo "| $name | $view | $dt | $dp$(mark "$dwithin") | $gt | $gp$(mark "$gwithin") | $floor |"
done
