#!/usr/bin/env bash
# An RGB-D-only layer against the synthetic truth (docs/range.md, "Depth sequences,
# measured"): the small synthetic site with its simulated hand-held depth sequences;
# one project holding only the layer's depth sequence (no photos, no scans), imported
# with the drifting poses the device recorded, registered (`strata register depth`:
# frame-to-model tracking, loop closure, re-registration) and fused (`strata process`).
# Drift of the recorded, tracked and final poses against the true ones
# (bench/eval_depth_drift.py); the layer's DTM against the truth (bench/eval_surface.py).
#
# Usage: bench/depth.sh [--layer L4] [--frames N] [--keep DIR]
# Writes bench/results/depth-<UTC date>.json. Needs python3-gdal and python3-numpy.
set -euo pipefail
cd "$(dirname "$0")/.."
layer=L4
keep=
frames=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --layer) layer="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
strata=$PWD/${STRATA_BUILD_DIR:-build}/src/cli/strata
[[ -x "$strata" ]] || { echo "bench/depth.sh: build strata first ($strata)" >&2; exit 1; }
if [[ -n "$keep" ]]; then work=$keep; rm -rf "$work"; mkdir -p "$work"
else work=$(mktemp -d /tmp/strata-depth.XXXXXX); trap 'rm -rf "$work"' EXIT; fi

data=$work/data
"$strata" -q synth "$data" --size small --depth ${frames:+--depth-frames "$frames"}
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
timed import "$strata" -q import depth "$p" --layer "$layer" --intrinsics "$seq/intrinsics.txt" \
  --poses "$seq/poses_recorded.txt" --colour "$seq/colour" --noise-k "$noise_k" "$seq"/depth/*.png
timed register "$strata" -q register depth "$p" --layer "$layer" --json > "$work/register.json"
timed process "$strata" -q process "$p" --layer "$layer" --json > "$work/process.json"
/usr/bin/python3 bench/eval_depth_drift.py "$work/register.json" "$seq/poses_true.txt" > "$work/drift.json"
/usr/bin/python3 bench/eval_surface.py "$p/products/$layer/dtm.tif" "$data/truth/$layer/surface.tif" \
  "$data/site.json" > "$work/surface.json"
/usr/bin/python3 bench/eval_regions.py "$data/truth/$layer/surface.tif" "$data/site.json" \
  depth="$p/products/$layer/dtm.tif" > "$work/regions.json"

mkdir -p bench/results
out=bench/results/depth-$(date -u +%Y%m%d).json
python3 - "$work" "$layer" "$out" "${frames:-}" <<'PY'
import json, sys
work, layer, out, frames = sys.argv[1:]
site = json.load(open(f"{work}/data/site.json"))
q = json.load(open(f"{work}/process.json"))
d = q.get("dense", {})
res = {"layer": layer, "size": "small", "depth": site["depth"],
       "command": f"bench/depth.sh --layer {layer}" + (f" --frames {frames}" if frames else ""),
       "seconds": {k: float(open(f"{work}/{k}.seconds").read()) for k in ("import", "register", "process")},
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
