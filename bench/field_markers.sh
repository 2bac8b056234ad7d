#!/usr/bin/env bash
# Georeferencing with markers as the field clicks them: a synthetic layer whose markers
# are objects about 10 cm across, clicked at their visible centre in every photo that
# sees them (the clicked point moves 2 cm per axis with the view), a fifth of the clicks
# 20-80 px off, the survey rounded to 0.1 m, imported as another program's OpenDroneMap
# gcp_list, coded-target detection off. Scores strata's cameras against the truth
# (absolute centres: this measures the georeference) and lists each marker's dispersion.
#
# Usage: bench/field_markers.sh [--strata BIN] [--layer L1] [--spread M] [--gross F] [--round M]
# Writes bench/results/field-markers-<UTC timestamp>.json and latest-field-markers.json.
set -euo pipefail
cd "$(dirname "$0")/.."
strata=build/src/cli/strata
layer=L1
spread=0.02
gross=0.2
round=0.1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --strata) strata="$2"; shift 2 ;;
    --layer) layer="$2"; shift 2 ;;
    --spread) spread="$2"; shift 2 ;;
    --gross) gross="$2"; shift 2 ;;
    --round) round="$2"; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done
bash scripts/setup.sh
/usr/bin/python3 -c 'import numpy' 2>/dev/null || {
  sudo_cmd=; [[ $(id -u) -ne 0 ]] && sudo_cmd=sudo
  $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get install -y -q python3-numpy >/dev/null
}
[[ -x "$strata" ]] || { cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null; cmake --build build --target strata; }

work=$(mktemp -d /tmp/strata-field-markers.XXXXXX)
trap 'rm -rf "$work"' EXIT
data="$work/data"
"$strata" synth "$data" --size small --stages 1 >/dev/null
/usr/bin/python3 bench/field_markers.py clicks "$data" "$layer" "$work/gcp_list.txt" \
  --spread "$spread" --gross "$gross" --round "$round" > "$work/clicks.json"
site="$work/site"
crs=$(head -1 "$data/gcp_list.txt")
"$strata" init "$site" --crs "$crs" >/dev/null
unit=$(awk -F, -v l="$layer" '$1 == l {print $2}' "$data/layers.csv")
"$strata" unit add "$site" "$unit" >/dev/null
"$strata" layer add "$site" "$layer" --unit "$unit" >/dev/null
"$strata" import photos "$site" --layer "$layer" "$data/photos/$layer"/*.jpg >/dev/null
"$strata" import markers "$site" "$work/gcp_list.txt" --skip-missing-images >/dev/null
start=$(date +%s.%N)
"$strata" process "$site" --layer "$layer" --until sparse --no-targets --json > "$work/quality.json" 2> "$work/process.log" || {
  echo "bench: strata process failed:"; tail -5 "$work/process.log"; exit 1; }
end=$(date +%s.%N)
"$strata" export cameras "$site" --layer "$layer" --format csv --out "$work/cameras.csv" >/dev/null
/usr/bin/python3 bench/field_markers.py score "$data" "$layer" "$work/cameras.csv" "$work/quality.json" > "$work/score.json"
stamp=$(date -u +%Y%m%dT%H%MZ)
mkdir -p bench/results
/usr/bin/python3 - "$work/clicks.json" "$work/score.json" "$end" "$start" "$strata" > "bench/results/field-markers-$stamp.json" <<'EOF'
import json, sys
clicks = json.load(open(sys.argv[1]))
score = json.load(open(sys.argv[2]))
score["clicks"] = clicks
score["sparse_seconds"] = float(sys.argv[3]) - float(sys.argv[4])
score["strata"] = sys.argv[5]
print(json.dumps(score, indent=1))
EOF
cp "bench/results/field-markers-$stamp.json" bench/results/latest-field-markers.json
cat "bench/results/field-markers-$stamp.json"
grep -i "georeference" "$work/process.log" | head -20 || true
