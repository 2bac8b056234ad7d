#!/usr/bin/env bash
# Range scans against the synthetic truth (docs/range.md, "Measured"): one layer of the
# small synthetic site with its simulated laser scans, as three projects:
#   photos  the layer's photos alone (as scripts/example.sh builds a project)
#   both    a copy of it with the layer's scans imported (--transform, the true poses):
#           the depth maps are reused from the copied cache, the fusion is redone
#   scans   the scans alone (no photos): a scans-only layer
# With --register, a fourth (docs/range.md, "Registration"):
#   registered  a copy of photos with the scans imported WITHOUT their poses, placed by
#           `strata register scan` (ICP against the layer's photo surface), then fused;
#           each scan's registration error against its true pose, and this DTM against
#           the one of `both` (the same scans at their true poses).
# Each layer's DTM against the truth (bench/eval_surface.py: median, p95 of |error|,
# completeness over the trench) and the completeness on the steep trench sides and the
# sheltered ground between the wall stones (bench/eval_regions.py).
#
# Usage: bench/range.sh [--layer L4] [--register] [--keep DIR]
# Writes bench/results/range-<UTC date>.json (range-register-<UTC date>.json with --register). Needs python3-gdal and python3-numpy.
set -euo pipefail
cd "$(dirname "$0")/.."
layer=L4
keep=
register=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --layer) layer="$2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    --register) register=1; shift ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
strata=$PWD/${STRATA_BUILD_DIR:-build}/src/cli/strata
[[ -x "$strata" ]] || { echo "bench/range.sh: build strata first ($strata)" >&2; exit 1; }
if [[ -n "$keep" ]]; then work=$keep; rm -rf "$work"; mkdir -p "$work"
else work=$(mktemp -d /tmp/strata-range.XXXXXX); trap 'rm -rf "$work"' EXIT; fi

data=$work/data
"$strata" -q synth "$data" --size small --scans
crs=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['crs'])" "$data/site.json")
origin=$(python3 -c "import json,sys; print(','.join(repr(v) for v in json.load(open(sys.argv[1]))['origin']))" "$data/site.json")
unit=$(awk -F, -v l="$layer" '$1 == l { print $2 }' "$data/layers.csv")
photos=$(awk -F, -v l="$layer" '$1 == l { print $4 }' "$data/layers.csv")

# new_project DIR: a project with the site's origin (the scans' poses are in its site
# frame), the layer's unit and the layer.
new_project() {
  "$strata" -q init "$1" --crs "$crs" --origin "$origin"
  "$strata" -q unit add "$1" "$unit"
  "$strata" -q layer add "$1" "$layer" --unit "$unit"
}
# import_scans DIR [raw]: every scan of the layer with its true pose and noise
# (scans.csv); with raw, without the pose (unregistered).
import_scans() {
  tail -n +2 "$data/scans.csv" | while IFS=, read -r l file pose sigma _; do
    [[ "$l" == "$layer" ]] || continue
    local given=(--transform "$data/$pose")
    [[ "${2:-}" == raw ]] && given=()
    "$strata" -q import scan "$1" --layer "$layer" "${given[@]}" --sigma "$sigma" "$data/$file"
  done
}
timed() {  # timed NAME CMD...: wall seconds into $work/NAME.seconds
  local name=$1; shift
  local t0; t0=$(date +%s.%N)
  "$@"
  python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$t0" "$(date +%s.%N)" > "$work/$name.seconds"
}

new_project "$work/photos"
"$strata" -q import photos "$work/photos" --layer "$layer" "$data/$photos"/*.jpg
"$strata" -q import markers "$work/photos" "$data/markers.csv"
ls "$data/$photos" > "$work/names.txt"
awk 'NR == FNR { keep[$1] = 1; next } FNR == 1 || ($6 in keep)' "$work/names.txt" "$data/gcp_list.txt" > "$work/gcp_list.txt"
"$strata" -q import markers "$work/photos" "$work/gcp_list.txt"
timed photos "$strata" -q process "$work/photos" --layer "$layer" --json > "$work/photos.json"

cp -a "$work/photos" "$work/both"
import_scans "$work/both"
timed both "$strata" -q process "$work/both" --layer "$layer" --json > "$work/both.json"

new_project "$work/scans"
import_scans "$work/scans"
timed scans "$strata" -q process "$work/scans" --layer "$layer" --json > "$work/scans.json"

projects="photos both scans"
if [[ -n "$register" ]]; then
  cp -a "$work/photos" "$work/registered"
  import_scans "$work/registered" raw
  timed register "$strata" -q register scan "$work/registered" --layer "$layer" --json > "$work/register.json"
  timed registered "$strata" -q process "$work/registered" --layer "$layer" --json > "$work/registered.json"
  projects="$projects registered"
  /usr/bin/python3 bench/eval_surface.py "$work/registered/products/$layer/dtm.tif" \
    "$work/both/products/$layer/dtm.tif" "$data/site.json" > "$work/registered_vs_both.json"
fi

truth=$data/truth/$layer/surface.tif
for p in $projects; do
  /usr/bin/python3 bench/eval_surface.py "$work/$p/products/$layer/dtm.tif" "$truth" "$data/site.json" > "$work/$p.surface.json"
done
/usr/bin/python3 bench/eval_regions.py "$truth" "$data/site.json" photos="$work/photos/products/$layer/dtm.tif" \
  both="$work/both/products/$layer/dtm.tif" scans="$work/scans/products/$layer/dtm.tif" \
  ${register:+registered="$work/registered/products/$layer/dtm.tif"} > "$work/regions.json"

mkdir -p bench/results
out=bench/results/range${register:+-register}-$(date -u +%Y%m%d).json
python3 - "$work" "$layer" "$out" "$projects" <<'PY'
import json, math, os, sys
work, layer, out, projects = sys.argv[1:]
site = json.load(open(f"{work}/data/site.json"))
res = {"layer": layer, "size": "small", "scans": site["scans"],
       "command": f"bench/range.sh --layer {layer}" + (" --register" if "registered" in projects else ""),
       "projects": {}}
for p in projects.split():
    q = json.load(open(f"{work}/{p}.json"))
    d = q.get("dense", {})
    res["projects"][p] = {
        "process_seconds": float(open(f"{work}/{p}.seconds").read()),
        "dense": {k: d.get(k) for k in ("voxel_size_m", "completeness", "scans_fused", "scan_points",
                                         "scan_weight_share", "unit_sigma_m", "gsd_m")},
        "dtm_sigma": q.get("products", {}).get("dtm", {}).get("sigma"),
        "ortho": q.get("products", {}).get("ortho") is not None,
        "surface": json.load(open(f"{work}/{p}.surface.json")),
    }
res["regions"] = json.load(open(f"{work}/regions.json"))

def matrix(text_rows):
    return [[float(v) for v in row.split()] for row in text_rows if row.strip() and not row.startswith("#")]

def pose_error(true, reg):
    # Rotation angle of R_true^T R_reg (mrad) and the station's displacement (mm).
    R = [[sum(true[k][i] * reg[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    c = max(-1.0, min(1.0, (R[0][0] + R[1][1] + R[2][2] - 1) / 2))
    dt = math.dist([true[i][3] for i in range(3)], [reg[i][3] for i in range(3)])
    return 1000 * math.acos(c), 1000 * dt

if "registered" in projects:
    reg = json.load(open(f"{work}/register.json"))
    poses = {}
    for line in open(f"{work}/data/scans.csv").read().splitlines()[1:]:
        l, file, pose = line.split(",")[:3]
        if l == layer:
            poses[os.path.basename(file)] = pose
    rows = []
    for s in reg["scans"]:
        true = matrix(open(f"{work}/data/{poses[s['scan']]}").read().splitlines())
        m = [s["transform"][4 * r:4 * r + 4] for r in range(4)]
        rot_mrad, station_mm = pose_error(true, m)
        rows.append({"scan": s["scan"], "rotation_error_mrad": rot_mrad, "station_error_mm": station_mm,
                     "rms_mm": 1000 * s["rms_m"], "inlier_share": s["inlier_share"],
                     "sigma_translation_mm": 1000 * s["sigma_translation_m"],
                     "sigma_rotation_mrad": 1000 * s["sigma_rotation_rad"], "seconds": s["seconds"]})
    res["registration"] = {"against": reg["against"], "seconds": float(open(f"{work}/register.seconds").read()),
                           "scans": rows,
                           "dtm_registered_vs_true_pose": json.load(open(f"{work}/registered_vs_both.json"))}
json.dump(res, open(out, "w"), indent=2)
print(json.dumps(res, indent=2))
PY
echo "wrote $out"
