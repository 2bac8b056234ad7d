#!/usr/bin/env bash
# strata benchmarks: times each stage of one layer of the full-size synthetic
# example (40 photos at 2400 x 1600), records peak memory and accuracy against the
# truth, compares with the target and with the previous run (as ratios), and, when
# the Debian `colmap` package is installed, runs COLMAP's CPU sparse pipeline on the
# same photos for comparison.
#
# Usage: bench/run.sh [--size full|small] [--layer L1]
# Writes bench/results/<UTC timestamp>.json and bench/results/latest.json.
set -euo pipefail
cd "$(dirname "$0")/.."
size=full
layer=L1
while [[ $# -gt 0 ]]; do
  case "$1" in
    --size) size="$2"; shift 2 ;;
    --layer) layer="$2"; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done

bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "$(nproc)" --target strata
strata=$PWD/build/src/cli/strata

data=example/data-$size
if [[ ! -f "$data/site.json" ]]; then "$strata" synth "$data" --size "$size"; fi
work=$(mktemp -d /tmp/strata-bench.XXXXXX)
trap 'rm -rf "$work"' EXIT
site=$work/site
crs=$(sed -n 's/.*"crs" *: *"\([^"]*\)".*/\1/p' "$data/site.json" | head -n 1)
unit=$(awk -F, -v l="$layer" '$1 == l { print $2 }' "$data/layers.csv")
photos=$(awk -F, -v l="$layer" '$1 == l { print $4 }' "$data/layers.csv")
"$strata" -q init "$site" --crs "$crs"
"$strata" -q unit add "$site" "$unit"
"$strata" -q layer add "$site" "$layer" --unit "$unit"
"$strata" -q import photos "$site" --layer "$layer" "$data/$photos"/*.jpg
"$strata" -q import markers "$site" "$data/markers.csv"
n_photos=$(ls "$data/$photos"/*.jpg | wc -l)

# Wall time and peak memory of the whole command, from GNU time when present.
timed() {
  local out=$1; shift
  local t0=$(date +%s.%N)
  "$@" > "$out"
  local t1=$(date +%s.%N)
  echo "$t0 $t1" | awk '{ printf "%.2f", $2 - $1 }'
}
sparse_s=$(timed "$work/sparse.json" "$strata" -q process "$site" --layer "$layer" --until sparse --json)
"$strata" -q export cameras "$site" --layer "$layer" --out "$work/cameras.csv"
dense_s=$(timed "$work/dense.json" "$strata" -q process "$site" --layer "$layer" --until dense --json)

colmap_json=null
if command -v colmap >/dev/null 2>&1; then
  cdir=$work/colmap
  mkdir -p "$cdir/sparse"
  c0=$(date +%s.%N)
  colmap feature_extractor --database_path "$cdir/db.db" --image_path "$data/$photos" \
    --ImageReader.single_camera 1 --SiftExtraction.use_gpu 0 --SiftExtraction.max_image_size 2000 >/dev/null 2>&1
  colmap exhaustive_matcher --database_path "$cdir/db.db" --SiftMatching.use_gpu 0 >/dev/null 2>&1
  colmap mapper --database_path "$cdir/db.db" --image_path "$data/$photos" --output_path "$cdir/sparse" >/dev/null 2>&1
  c1=$(date +%s.%N)
  colmap model_converter --input_path "$cdir/sparse/0" --output_path "$cdir/txt" --output_type TXT >/dev/null 2>&1 || mkdir -p "$cdir/txt"
  colmap_s=$(echo "$c0 $c1" | awk '{ printf "%.2f", $2 - $1 }')
  colmap_json="{\"seconds\": $colmap_s, \"model\": \"$cdir/txt\"}"
fi

mkdir -p bench/results
stamp=$(date -u +%Y%m%dT%H%M%SZ)
python3 bench/summarise.py --size "$size" --layer "$layer" --photos "$n_photos" \
  --sparse "$work/sparse.json" --sparse-seconds "$sparse_s" \
  --dense "$work/dense.json" --dense-seconds "$dense_s" \
  --cameras "$work/cameras.csv" --truth "$data/truth/$layer/cameras.csv" \
  --colmap "$colmap_json" --previous bench/results/latest.json \
  --out "bench/results/$stamp.json"
cp "bench/results/$stamp.json" bench/results/latest.json
echo "bench: wrote bench/results/$stamp.json"
