#!/usr/bin/env bash
# An RGB-D-only layer against the synthetic truth (docs/range.md, "Depth sequences,
# measured"): the small synthetic site with its simulated hand-held depth sequences;
# one project holding only the layer's depth sequence (no photos, no scans), imported
# with the drifting poses the device recorded, registered (`strata register depth`:
# frame-to-model tracking, loop closure, re-registration) and fused (`strata process`).
# Drift of the recorded, tracked and final poses against the true ones
# (bench/eval_depth_drift.py); the layer's DTM against the truth (bench/eval_surface.py).
#
# --no-poses: the sequence imported without its recorded poses (and the surveyed
#   markers imported): tracked from its colour frames' features, placed on the markers
#   its colour frames see. --marker-loop: the synthetic camera's wider loop that sees
#   the markers (synth --depth-offset 1.0). --data DIR: use the site `strata synth`
#   already wrote there (with the same options) instead of generating it. --start features|recorded
#   and --datum auto|device|markers are passed to `strata register depth`. --tag NAME
#   is added to the result's file name.
#
# Usage: bench/depth.sh [--layer L4] [--frames N] [--keep DIR] [--no-poses] [--marker-loop]
#                       [--data DIR] [--start S] [--datum D] [--tag NAME] [--no-process]
# Writes bench/results/depth-<UTC date>[-NAME].json. Needs python3-gdal and python3-numpy.
set -euo pipefail
cd "$(dirname "$0")/.."
layer=L4
keep=
frames=
no_poses=
marker_loop=
start=
datum=
tag=
reuse=
process=1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --layer) layer="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    --no-poses) no_poses=1; shift ;;
    --marker-loop) marker_loop=1; shift ;;
    --start) start="$2"; shift 2 ;;
    --datum) datum="$2"; shift 2 ;;
    --tag) tag="$2"; shift 2 ;;
    --data) reuse="$2"; shift 2 ;;
    --no-process) process=; shift ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
strata=$PWD/${STRATA_BUILD_DIR:-build}/src/cli/strata
[[ -x "$strata" ]] || { echo "bench/depth.sh: build strata first ($strata)" >&2; exit 1; }
if [[ -n "$keep" ]]; then work=$keep; rm -rf "$work"; mkdir -p "$work"
else work=$(mktemp -d /tmp/strata-depth.XXXXXX); trap 'rm -rf "$work"' EXIT; fi

data=$work/data
if [[ -n "$reuse" ]]; then data=$(realpath "$reuse")
else "$strata" -q synth "$data" --size small --depth ${frames:+--depth-frames "$frames"} ${marker_loop:+--depth-offset 1.0}
fi
crs=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['crs'])" "$data/site.json")
origin=$(python3 -c "import json,sys; print(','.join(repr(v) for v in json.load(open(sys.argv[1]))['origin']))" "$data/site.json")
unit=$(awk -F, -v l="$layer" '$1 == l { print $2 }' "$data/layers.csv")
seq=$data/depth/$layer
timed() {  # timed NAME CMD...: wall seconds into $work/NAME.seconds
  local name=$1; shift
  local t0; t0=$(date +%s.%N)
  "$@"
  python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$t0" "$(date +%s.%N)" > "$work/$name.seconds"
}

p=$work/depth
"$strata" -q init "$p" --crs "$crs" --origin "$origin"
"$strata" -q unit add "$p" "$unit"
"$strata" -q layer add "$p" "$layer" --unit "$unit"
noise_k=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['depth']['noise_k'])" "$data/site.json")
poses=(--poses "$seq/poses_recorded.txt")
if [[ -n "$no_poses" ]]; then poses=(); "$strata" -q import markers "$p" "$data/markers.csv"; fi
timed import "$strata" -q import depth "$p" --layer "$layer" --intrinsics "$seq/intrinsics.txt" \
  "${poses[@]}" --colour "$seq/colour" --noise-k "$noise_k" "$seq"/depth/*.png
cpu_register=$work/register.cpu
timed register /usr/bin/time -o "$cpu_register" -f "%U %S" "$strata" -q register depth "$p" --layer "$layer" \
  ${start:+--start "$start"} ${datum:+--datum "$datum"} --json > "$work/register.json"
/usr/bin/python3 bench/eval_depth_drift.py "$work/register.json" "$seq/poses_true.txt" > "$work/drift.json"
echo null > "$work/surface.json"; echo null > "$work/regions.json"; echo '{}' > "$work/process.json"
echo 0 > "$work/process.seconds"
if [[ -n "$process" ]]; then
  timed process "$strata" -q process "$p" --layer "$layer" --json > "$work/process.json"
  /usr/bin/python3 bench/eval_surface.py "$p/products/$layer/dtm.tif" "$data/truth/$layer/surface.tif" \
    "$data/site.json" > "$work/surface.json"
  /usr/bin/python3 bench/eval_regions.py "$data/truth/$layer/surface.tif" "$data/site.json" \
    depth="$p/products/$layer/dtm.tif" > "$work/regions.json"
fi

mkdir -p bench/results
out=bench/results/depth-$(date -u +%Y%m%d)${tag:+-$tag}.json
command="bench/depth.sh --layer $layer${frames:+ --frames $frames}${no_poses:+ --no-poses}${marker_loop:+ --marker-loop}"
command+="${start:+ --start $start}${datum:+ --datum $datum}"
[[ -z "$process" ]] && command+=" --no-process"
command+="${tag:+ --tag $tag}"
python3 - "$work" "$layer" "$out" "$command" "$data" <<'PY'
import json, sys
work, layer, out, command = sys.argv[1:5]
site = json.load(open(sys.argv[5] + "/site.json"))
q = json.load(open(f"{work}/process.json"))
d = q.get("dense", {})
res = {"layer": layer, "size": "small", "depth": site["depth"],
       "command": command,
       "seconds": {k: float(open(f"{work}/{k}.seconds").read()) for k in ("import", "register", "process")},
       "register_cpu_seconds": sum(float(v) for v in open(f"{work}/register.cpu").read().split()[-2:]),
       "drift": json.load(open(f"{work}/drift.json")),
       "dense": {k: d.get(k) for k in ("voxel_size_m", "completeness", "scans_fused", "scan_points",
                                        "scan_weight_share", "unit_sigma_m")},
       "dtm_sigma": q.get("products", {}).get("dtm", {}).get("sigma"),
       "surface": json.load(open(f"{work}/surface.json")),
       "regions": json.load(open(f"{work}/regions.json"))}
json.dump(res, open(out, "w"), indent=2)
print(json.dumps(res, indent=2))
PY
echo "wrote $out"
