#!/usr/bin/env bash
# The main job on the bundled example excavation, end to end:
#   install what is missing -> build strata -> generate the synthetic example
#   excavation (if absent) -> create a project -> record units, relations, layers
#   -> import photos and surveyed markers -> process every layer -> summary.
# Usage: scripts/example.sh [--size small|full]
#   small (default): 4 layers x 20 photos, about 3.5 minutes on 2 cores
#   full:            the full-size excavation, about 30 minutes on 2 cores
# Everything goes under example/ (ignored by git); rerunning reuses what exists.
set -euo pipefail
cd "$(dirname "$0")/.."
size=small
if [[ "${1:-}" == "--size" ]]; then size="${2:?--size needs small or full}"; fi

bash scripts/setup.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "$(nproc)" --target strata
strata=build/src/cli/strata

data=example/data-$size
site=example/site-$size
if [[ ! -f "$data/site.json" ]]; then
  echo "== generating the synthetic example excavation ($size) in $data"
  rm -rf "$data"
  "$strata" synth "$data" --size "$size"
fi

if [[ ! -f "$site/project.gpkg" ]]; then
  echo "== creating the project $site"
  crs=$(sed -n 's/.*"crs" *: *"\([^"]*\)".*/\1/p' "$data/site.json" | head -n 1)
  "$strata" init "$site" --crs "$crs" --name "strata example excavation ($size)"
  "$strata" -q import units "$site" "$data/units.csv"
  "$strata" -q import relations "$site" "$data/relations.csv"
  tail -n +2 "$data/layers.csv" | while IFS=, read -r layer unit captured photos; do
    "$strata" -q layer add "$site" "$layer" --unit "$unit" --captured-at "$captured"
    "$strata" -q import photos "$site" --layer "$layer" "$data/$photos"/*.jpg
  done
  "$strata" -q import markers "$site" "$data/markers.csv"
  # Hand-placed marker observations, as a surveyor clicks them where coded-target
  # detection misses distant targets (OpenDroneMap gcp_list format).
  "$strata" -q import markers "$site" "$data/gcp_list.txt"
fi

echo "== processing every layer (alignment -> dense surface -> DTM, orthophoto, site plan)"
"$strata" process "$site" --all

echo "== unit volumes (between consecutive layer surfaces)"
# The limit of excavation recorded in the field (nothing outside it was dug); the
# project keeps it for later volume runs, reports and exports.
outline=()
[[ -f "$data/trench_outline.geojson" ]] && outline=(--outline "$data/trench_outline.geojson")
"$strata" volume "$site" "${outline[@]}"
"$strata" check "$site" || echo "(the geometry contradicts a recorded relation: see above)"

echo "== exports"
mkdir -p "$site/exports"
"$strata" export qgis "$site" --out "$site/exports/site.qgz"
"$strata" export grass "$site" --out "$site/exports/grass"
"$strata" export voxels "$site" --out "$site/exports/units.vdb"
"$strata" report "$site" --out "$site/exports/report.html"

echo "== the project"
"$strata" info "$site"
echo
echo "Everything is in $site:"
echo "  project database (open in QGIS):  $site/project.gpkg"
echo "  QGIS project:                      $site/exports/site.qgz"
echo "  per-layer products:                $site/products/<layer>/ (dtm.tif, ortho.tif, dense/mesh.ply, ...)"
echo "  GRASS import script:               $site/exports/grass/import.sh"
echo "  field report:                      $site/exports/report.html"
echo "  Harris matrix:                     $strata matrix $site --format svg --out matrix.svg"
