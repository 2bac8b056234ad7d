#!/usr/bin/env bash
# Scans registered on their targets against the synthetic truth (docs/range.md, "On
# surveyed targets"): the small synthetic site with its simulated laser scans; every
# layer's scans imported without their poses into one project with the surveyed
# markers, each registered by `strata register scan --targets` on the targets its
# station measured (S<n>_targets.csv), and its pose compared with the true pose file:
# the rotation error (angle of R_true^T R) and the station error (the scanner's origin).
# Twice: with the markers as surveyed, and with their true positions. No photos are
# processed: the targets alone fix the pose.
#
# Usage: bench/scan_targets.sh [--keep DIR]
# Writes bench/results/scan-targets-<UTC date>.json. Needs python3.
set -euo pipefail
cd "$(dirname "$0")/.."
keep=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --keep) keep="$2"; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
strata=$PWD/${STRATA_BUILD_DIR:-build}/src/cli/strata
[[ -x "$strata" ]] || { echo "bench/scan_targets.sh: build strata first ($strata)" >&2; exit 1; }
if [[ -n "$keep" ]]; then work=$keep; rm -rf "$work"; mkdir -p "$work"
else work=$(mktemp -d /tmp/strata-targets.XXXXXX); trap 'rm -rf "$work"' EXIT; fi

data=$work/data
"$strata" -q synth "$data" --size small --scans
crs=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['crs'])" "$data/site.json")
# register_all NAME MARKERS: a project with every layer, MARKERS, and every scan
# registered on its targets; fits.csv lines "set,layer,scan,true pose,fit json".
register_all() {
  local site=$work/$1
  "$strata" -q init "$site" --crs "$crs"
  tail -n +2 "$data/layers.csv" | while IFS=, read -r l unit _; do
    "$strata" -q unit add "$site" "$unit"
    "$strata" -q layer add "$site" "$l" --unit "$unit"
  done
  "$strata" -q import markers "$site" "$2"
  mkdir -p "$work/fits"
  tail -n +2 "$data/scans.csv" | while IFS=, read -r l file pose sigma _; do
    "$strata" -q import scan "$site" --layer "$l" --sigma "$sigma" "$data/$file"
    local name; name=$(basename "$file")
    local fit=$work/fits/$1-$l-${name%.ply}.json
    "$strata" -q register scan "$site" --layer "$l" --scan "$name" --targets "$data/${file%.ply}_targets.csv" \
      --json > "$fit"
    echo "$1,$l,$name,$data/$pose,$fit" >> "$work/fits.csv"
  done
}
# surveyed: the markers as surveyed (3 mm of noise per axis), what a user has;
# true: the true marker positions (sigma 0.1 mm), which leaves the targets' own noise.
register_all surveyed "$data/markers.csv"
sed 's/,0,\(control\|check\)$/,0.0001,\1/' "$data/truth/markers.csv" > "$work/true_markers.csv"
register_all true "$work/true_markers.csv"

mkdir -p bench/results
out=bench/results/scan-targets-$(date -u +%Y%m%d).json
python3 - "$work/fits.csv" "$out" <<'PY'
import json, math, sys

def matrix(path):
    v = [float(x) for line in open(path) if not line.lstrip().startswith("#") for x in line.split()]
    return [v[4 * r:4 * r + 4] for r in range(4)]

def rotation_error(a, b):  # angle of A^T B for the rotation parts (B's scale removed)
    s = abs(sum(b[0][i] * (b[1][(i + 1) % 3] * b[2][(i + 2) % 3] - b[1][(i + 2) % 3] * b[2][(i + 1) % 3])
                for i in range(3))) ** (1 / 3)
    trace = sum(a[k][i] * b[k][i] / s for i in range(3) for k in range(3))
    return math.acos(max(-1.0, min(1.0, (trace - 1) / 2)))

rows = []
for line in open(sys.argv[1]):
    markers, layer, scan, pose, fit = line.strip().split(",")
    truth = matrix(pose)
    q = json.load(open(fit))
    m = [q["transform"][4 * r:4 * r + 4] for r in range(4)]
    station = math.dist([truth[r][3] for r in range(3)], [m[r][3] for r in range(3)])
    rows.append({"markers": markers, "layer": layer, "scan": scan, "targets": len(q["targets"]),
                 "inliers": q["inliers"], "rms_mm": 1000 * q["rms_m"], "scale_ppm": 1e6 * (q["scale"] - 1),
                 "rotation_error_mrad": 1000 * rotation_error(truth, m), "station_error_mm": 1000 * station,
                 "sigma_t_mm": 1000 * q["sigma_translation_m"], "sigma_r_mrad": 1000 * q["sigma_rotation_rad"]})
summary = {}
for markers in ("surveyed", "true"):
    sel = [r for r in rows if r["markers"] == markers]
    rot = sorted(r["rotation_error_mrad"] for r in sel)
    sta = sorted(r["station_error_mm"] for r in sel)
    summary[markers] = {"scans": len(sel), "rotation_error_mrad_median": rot[len(rot) // 2],
                        "rotation_error_mrad_max": rot[-1], "station_error_mm_median": sta[len(sta) // 2],
                        "station_error_mm_max": sta[-1],
                        "sigma_r_mrad_median": sorted(r["sigma_r_mrad"] for r in sel)[len(sel) // 2]}
json.dump({"summary": summary, "scans": rows}, open(sys.argv[2], "w"), indent=1)
for r in rows:
    print("{markers} markers, {layer} {scan}: {inliers}/{targets} targets, RMS {rms_mm:.2f} mm, scale "
          "{scale_ppm:+.0f} ppm, rotation {rotation_error_mrad:.2f} mrad, station {station_error_mm:.2f} mm "
          "(sigma {sigma_t_mm:.2f} mm / {sigma_r_mrad:.2f} mrad)".format(**r))
print(json.dumps(summary, indent=1))
PY
echo "bench/scan_targets.sh: wrote $out"
