#!/usr/bin/env bash
# strata on real photographs with truth (docs/real_data.md): the Strecha et al. (CVPR 2008)
# scenes Herz-Jesu-P8 and entry-P10 (true cameras from a laser scan, no EXIF) and the
# Coal Oil Point kite set copr (41 photos, ODM gcp_list of 10 surveyed targets, plan
# only). For each set: a fresh project, strata's alignment (`process --until sparse`,
# copr georeferenced on its markers), and, when the Debian `colmap` package is
# installed, COLMAP's CPU sparse pipeline with the defaults a new user gets, in the
# same run. bench/eval_real.py scores both against the truth, triangulates copr's
# clicked markers in each tool's model independently of strata's georeference, and
# compares every figure with the previous run as a ratio.
#
# Usage: bench/real.sh [--no-colmap] [--set herz|entry|copr|all] [--keep DIR]
# Data: $STRATA_REAL_DATA (default ../shared/data beside the repository).
# The binary: built here into $STRATA_BUILD_DIR (default build/), or $STRATA_BIN as it is.
# Writes bench/results/real-<UTC timestamp>.json and bench/results/latest-real.json.
set -euo pipefail
cd "$(dirname "$0")/.."
sets=all
colmap=1
keep=
while [[ $# -gt 0 ]]; do
  case "$1" in
    --set) sets="$2"; shift 2 ;;
    --no-colmap) colmap=0; shift ;;
    --keep) keep="$2"; shift 2 ;;
    *) echo "bench/real.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
case "$sets" in
  all) sets="herz entry copr" ;;
  herz|entry|copr) ;;
  *) echo "bench/real.sh: --set must be herz, entry, copr or all, not '$sets'" >&2; exit 2 ;;
esac
data_root=${STRATA_REAL_DATA:-$PWD/../shared/data}
for d in strecha/Herz-Jesus-P8 strecha/entry-P10 copr; do
  [[ -d "$data_root/$d/images" ]] || { echo "bench/real.sh: $data_root/$d/images: not found (set STRATA_REAL_DATA)" >&2; exit 2; }
done

bash scripts/setup.sh
command -v /usr/bin/time >/dev/null && /usr/bin/python3 -c 'import numpy' 2>/dev/null || {
  echo "bench: installing time, python3-numpy"
  sudo_cmd=; [[ $(id -u) -ne 0 ]] && sudo_cmd=sudo
  $sudo_cmd env DEBIAN_FRONTEND=noninteractive apt-get install -y -q time python3-numpy >/dev/null
}
if [[ -n "${STRATA_BIN:-}" ]]; then
  strata=$STRATA_BIN  # a strata binary built elsewhere (e.g. another commit): used as it is
else
  build=${STRATA_BUILD_DIR:-build}  # another build directory of the same tree, e.g. a developer's
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$build" -j "$(nproc)" --target strata
  strata=$PWD/$build/src/cli/strata
fi
if [[ $colmap == 1 ]] && ! command -v colmap >/dev/null 2>&1; then
  echo "bench: colmap is not installed: strata only"
  colmap=0
fi

if [[ -n "$keep" ]]; then work=$keep; rm -rf "$work"; mkdir -p "$work"
else work=$(mktemp -d /tmp/strata-real.XXXXXX); trap 'rm -rf "$work"' EXIT; fi

# timed OUT CMD...: runs CMD with stdout to OUT, its /usr/bin/time -v report to OUT.time.
timed() {
  local out=$1; shift
  /usr/bin/time -v -o "$out.time" "$@" > "$out"
}

# run_strata SET IMAGES CRS [GCP_LIST]: a fresh project in $work/SET/strata.
run_strata() {
  local set=$1 images=$2 crs=$3 gcp=${4:-}
  local dir=$work/$set/strata site=$work/$set/strata/site
  mkdir -p "$dir"
  "$strata" -q init "$site" --crs "$crs"
  "$strata" -q unit add "$site" U1
  "$strata" -q layer add "$site" L1 --unit U1
  "$strata" -q import photos "$site" --layer L1 "$images"/*.jpg
  if [[ -n "$gcp" ]]; then "$strata" -q import markers "$site" "$gcp" --format odm --layer L1; fi
  # A failed alignment is a figure too (registered 0): keep going to the next set.
  timed "$dir/sparse.json" "$strata" -q process "$site" --layer L1 --until sparse --json \
    2> "$dir/log.txt" || echo "bench: $set: strata process failed (exit $?), see the log" >&2
  "$strata" -q export cameras "$site" --layer L1 --format csv --out "$dir/cameras.csv" \
    2>> "$dir/log.txt" || true
  rm -rf "$site"  # the project (media copies, feature cache) is not needed any more
}

# run_colmap SET IMAGES: COLMAP 3.8's CPU pipeline in $work/SET/colmap with a new
# user's defaults: one shared camera (SIMPLE_RADIAL, the default model; its focal
# from EXIF, else 1.2 x the longer side), exhaustive matching, incremental mapper.
run_colmap() {
  local set=$1 images=$2
  local dir=$work/$set/colmap
  mkdir -p "$dir/sparse" "$dir/txt"
  (cd "$images" && ls *.jpg) > "$dir/images.txt"  # Strecha's folders also hold K.txt
  timed "$dir/extract.log" colmap feature_extractor --database_path "$dir/db.db" --image_path "$images" \
    --image_list_path "$dir/images.txt" --ImageReader.single_camera 1 --ImageReader.camera_model SIMPLE_RADIAL \
    --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$(nproc)"
  timed "$dir/match.log" colmap exhaustive_matcher --database_path "$dir/db.db" --SiftMatching.use_gpu 0 \
    --SiftMatching.num_threads "$(nproc)"
  timed "$dir/mapper.log" colmap mapper --database_path "$dir/db.db" --image_path "$images" \
    --output_path "$dir/sparse" --Mapper.num_threads "$(nproc)" || echo "bench: $set: colmap mapper failed" >&2
  # The largest model when the mapper made several.
  local best= n=0 m k
  for m in "$dir"/sparse/*/; do
    [[ -f "$m/images.bin" ]] || continue
    k=$(stat -c %s "$m/images.bin")
    if (( k > n )); then n=$k; best=$m; fi
  done
  if [[ -n "$best" ]]; then
    colmap model_converter --input_path "$best" --output_path "$dir/txt" --output_type TXT > "$dir/convert.log" 2>&1
  fi
  ls -d "$dir"/sparse/*/ 2>/dev/null | wc -l > "$dir/models.txt"
  rm -f "$dir/db.db"
}

load_before=$(cut -d' ' -f1 /proc/loadavg)
for set in $sets; do
  case "$set" in
    herz) images=$data_root/strecha/Herz-Jesus-P8/images; crs=EPSG:32631; gcp= ;;
    entry) images=$data_root/strecha/entry-P10/images; crs=EPSG:32631; gcp= ;;
    copr) images=$data_root/copr/images; crs=EPSG:32611; gcp=$data_root/copr/gcp_list.txt ;;
  esac
  echo "bench: $set: strata"
  run_strata "$set" "$images" "$crs" "$gcp"
  if [[ $colmap == 1 ]]; then
    echo "bench: $set: COLMAP (CPU)"
    run_colmap "$set" "$images"
  fi
done

mkdir -p bench/results
stamp=$(date -u +%Y%m%dT%H%M%SZ)
out=bench/results/real-$stamp.json
latest=bench/results/latest-real.json  # the previous run
/usr/bin/python3 bench/eval_real.py --work "$work" --data "$data_root" --sets $sets \
  --previous "$latest" --latest "$latest" --load-before "$load_before" --out "$out"
echo "bench: wrote $out"
