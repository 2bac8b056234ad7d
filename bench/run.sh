#!/usr/bin/env bash
# strata benchmarks: times each stage of one layer of the full-size synthetic
# example (40 photos at 2400 x 1600), records peak memory and accuracy against the
# truth, compares with the target and with the previous run (as ratios), and, when
# the Debian `colmap` package is installed, runs COLMAP's CPU sparse pipeline on the
# same photos for comparison (time ratio and camera accuracy after a similarity fit).
#
# Usage: [STRATA_BIN=path] [STRATA_ALIGN_ARGS="..."] bench/run.sh [--size full|small] [--layer L1] [--keep DIR] [--no-colmap] [--data DIR]
#   --data DIR: another synthetic excavation (strata synth DIR ...), e.g. 200 photos a layer:
#               strata synth /tmp/p200 --size full --stages 1 --photos 200
# Writes bench/results/<UTC timestamp>-<size>-<layer>.json and bench/results/latest-<size>-<layer>.json
# (<size> is the --data folder's name with --data).
set -euo pipefail
cd "$(dirname "$0")/.."
size=full
layer=L1
keep=
colmap=1
data=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --size) size="$2"; shift 2 ;;
    --layer) layer="$2"; shift 2 ;;
    --keep) keep="$2"; shift 2 ;;
    --no-colmap) colmap=0; shift ;;
    --data) data="$2"; shift 2 ;;
    *) echo "unknown option $1" >&2; exit 2 ;;
  esac
done

bash scripts/setup.sh
command -v /usr/bin/time >/dev/null && /usr/bin/python3 -c 'import numpy, osgeo, scipy' 2>/dev/null || {
  echo "bench: installing time, python3-numpy, python3-gdal, python3-scipy"
  sudo_cmd=; [[ $(id -u) -ne 0 ]] && sudo_cmd=sudo
  $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get install -y -q time python3-numpy python3-gdal python3-scipy >/dev/null
}
if [[ -n "${STRATA_BIN:-}" ]]; then
  strata=$(realpath "$STRATA_BIN")  # a strata binary built elsewhere (e.g. copied aside while the tree changes)
else
  build=${STRATA_BUILD_DIR:-build}  # another build directory of the same tree, e.g. a developer's
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$build" -j "$(nproc)" --target strata
  strata=$PWD/$build/src/cli/strata
fi

if [[ -z "$data" ]]; then
  data=example/data-$size
  if [[ ! -f "$data/site.json" ]]; then "$strata" synth "$data" --size "$size"; fi
elif [[ ! -f "$data/site.json" ]]; then
  echo "bench: $data: no site.json (make it with strata synth $data ...)" >&2; exit 2
fi
if [[ -n "$keep" ]]; then work=$keep; rm -rf "$work"; mkdir -p "$work"
else work=$(mktemp -d /tmp/strata-bench.XXXXXX); trap 'rm -rf "$work"' EXIT; fi
site=$work/site
crs=$(sed -n 's/.*"crs" *: *"\([^"]*\)".*/\1/p' "$data/site.json" | head -n 1)
unit=$(awk -F, -v l="$layer" '$1 == l { print $2 }' "$data/layers.csv")
photos=$(awk -F, -v l="$layer" '$1 == l { print $4 }' "$data/layers.csv")
"$strata" -q init "$site" --crs "$crs"
"$strata" -q unit add "$site" "$unit"
"$strata" -q layer add "$site" "$layer" --unit "$unit"
"$strata" -q import photos "$site" --layer "$layer" "$data/$photos"/*.jpg
"$strata" -q import markers "$site" "$data/markers.csv"
# The hand-placed observations of this layer's photos (as scripts/example.sh imports them).
ls "$data/$photos" > "$work/names.txt"
awk 'NR == FNR { keep[$1] = 1; next } FNR == 1 || ($6 in keep)' "$work/names.txt" "$data/gcp_list.txt" > "$work/gcp_list.txt"
"$strata" -q import markers "$site" "$work/gcp_list.txt"
n_photos=$(ls "$data/$photos"/*.jpg | wc -l)

# timed NAME CMD...: wall seconds of CMD (stdout to $work/NAME.json); peak RSS (kB), user and
# system CPU seconds in $work/NAME.mem (CPU seconds change less than wall time with other load).
timed() {
  local name=$1; shift
  local t0 t1
  t0=$(date +%s.%N)
  /usr/bin/time -f "%M %U %S" -o "$work/$name.mem" "$@" > "$work/$name.json"
  t1=$(date +%s.%N)
  echo "$t0 $t1" | awk '{ printf "%.2f", $2 - $1 }'
}
echo "bench: $size $layer, $n_photos photos: alignment"
# Other work on the machine makes the timings meaningless: the 1-minute load average
# just before the timed stages is kept with the results (quiet: below about 0.5).
load_before=$(cut -d' ' -f1 /proc/loadavg)
# STRATA_ALIGN_ARGS: extra options of the alignment (e.g. "--max-image-size 1200"), to compare; given to
# every stage, since a stage whose alignment options differ would align the layer again.
# shellcheck disable=SC2086
sparse_s=$(timed sparse "$strata" -q process "$site" --layer "$layer" --until sparse --json ${STRATA_ALIGN_ARGS:-})
"$strata" -q export cameras "$site" --layer "$layer" --out "$work/cameras.csv"
echo "bench: dense surface"
# shellcheck disable=SC2086
dense_s=$(timed dense "$strata" -q process "$site" --layer "$layer" --until dense --json ${STRATA_ALIGN_ARGS:-})
echo "bench: products"
# shellcheck disable=SC2086
products_s=$(timed products "$strata" -q process "$site" --layer "$layer" --json ${STRATA_ALIGN_ARGS:-})
points=
if [[ -f "$site/products/$layer/dense/points.ply" ]]; then
  /usr/bin/python3 bench/eval_points.py "$site/products/$layer/dense/points.ply" "$data/truth/$layer/surface.tif" \
    "$data/site.json" > "$work/points.json" && points=$work/points.json
fi
surface=
dtm=$(ls "$site/products/$layer"/dtm*.tif 2>/dev/null | head -n 1 || true)
if [[ -n "$dtm" && -f bench/eval_surface.py ]]; then
  /usr/bin/python3 bench/eval_surface.py "$dtm" "$data/truth/$layer/surface.tif" "$data/site.json" \
    > "$work/surface.json" && surface=$work/surface.json
fi

colmap_json=null
if [[ $colmap == 1 ]] && command -v colmap >/dev/null 2>&1; then
  echo "bench: COLMAP (CPU) sparse pipeline on the same photos"
  cdir=$work/colmap
  mkdir -p "$cdir/sparse"
  c0=$(date +%s.%N)
  /usr/bin/time -f "%U %S" -a -o "$cdir/cpu.txt" colmap feature_extractor --database_path "$cdir/db.db" --image_path "$data/$photos" \
    --ImageReader.single_camera 1 --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$(nproc)" \
    --SiftExtraction.max_image_size 2000 > "$cdir/log.txt" 2>&1
  /usr/bin/time -f "%U %S" -a -o "$cdir/cpu.txt" colmap exhaustive_matcher --database_path "$cdir/db.db" --SiftMatching.use_gpu 0 \
    --SiftMatching.num_threads "$(nproc)" >> "$cdir/log.txt" 2>&1
  /usr/bin/time -f "%U %S" -a -o "$cdir/cpu.txt" colmap mapper --database_path "$cdir/db.db" --image_path "$data/$photos" \
    --output_path "$cdir/sparse" --Mapper.num_threads "$(nproc)" >> "$cdir/log.txt" 2>&1
  c1=$(date +%s.%N)
  mkdir -p "$cdir/txt"
  colmap model_converter --input_path "$cdir/sparse/0" --output_path "$cdir/txt" --output_type TXT \
    >> "$cdir/log.txt" 2>&1 || true
  colmap_s=$(echo "$c0 $c1" | awk '{ printf "%.2f", $2 - $1 }')
  colmap_cpu=$(awk '{ s += $1 + $2 } END { printf "%.2f", s }' "$cdir/cpu.txt")
  colmap_json="{\"seconds\": $colmap_s, \"cpu_seconds\": $colmap_cpu, \"model\": \"$cdir/txt\"}"
fi

mkdir -p bench/results
stamp=$(date -u +%Y%m%dT%H%M%SZ)
label=$size  # another --data set is named by its folder
[[ "$data" != example/data-$size ]] && label=$(basename "$data")
out=bench/results/$stamp-$label-$layer.json
latest=bench/results/latest-$label-$layer.json  # the previous run of the same layer
# A run with other alignment options is compared with the default run but does not replace it.
[[ -n "${STRATA_ALIGN_ARGS:-}" ]] && latest_out=/dev/null || latest_out=$latest
/usr/bin/python3 bench/summarise.py --size "$size" --layer "$layer" --photos "$n_photos" \
  --sparse "$work/sparse.json" --sparse-seconds "$sparse_s" \
  --dense "$work/dense.json" --dense-seconds "$dense_s" --products-seconds "$products_s" --memdir "$work" \
  --cameras "$work/cameras.csv" --truth "$data/truth/$layer/cameras.csv" \
  --surface "$surface" --points "$points" --colmap "$colmap_json" --previous "$latest" --load-before "$load_before" \
  --align-args "${STRATA_ALIGN_ARGS:-}" --out "$out"
cp "$out" "$latest_out"
echo "bench: wrote $out"
