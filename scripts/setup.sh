#!/usr/bin/env bash
# Installs the Debian 12 packages strata needs, only when some are missing.
# Idempotent and quiet when everything is present (one dpkg-query, a fraction of a second).
# Usage: scripts/setup.sh [--gis] [--missing]
#   --gis      also installs GRASS, Graphviz and Chromium for the integration tests that
#              drive real GIS clients and load the viewer and the field station's pages in
#              a headless browser, with Selenium
#   --missing  installs nothing: prints the missing packages on one line (empty when none)
#              and the number of packages checked on the next (scripts/example.sh plans with it)
set -euo pipefail
gis=false
list_missing=false
for arg in "$@"; do
  case "$arg" in
    --gis) gis=true ;;
    --missing) list_missing=true ;;
  esac
done

packages=(
  build-essential cmake ninja-build pkg-config
  libsqlite3-dev sqlite3 libgdal-dev gdal-bin libgeographiclib-dev libproj-dev proj-bin
  libcgal-dev libopenvdb-dev libboost-iostreams-dev libopencv-dev libopencv-contrib-dev
  libceres-dev libeigen3-dev libtbb-dev libgtest-dev googletest libexiv2-dev
  nlohmann-json3-dev libcli11-dev libfmt-dev libspdlog-dev
  libicu-dev  # Unicode normalisation (NFC) of codes and names at the door
  libjs-three  # three.js r111, inlined by 'strata export viewer', served by 'strata serve'
  libjs-leaflet libcpp-httplib-dev  # the field station (strata serve): its map and its HTTP server
  python3  # bench scripts; the crash-injection sample of the test suite
)
if $gis; then
  packages+=(grass-core graphviz chromium chromium-driver python3-selenium)
fi

# dpkg-query fails when it knows none of a package's name; the others are still listed.
declare -A installed=()
while read -r name want ok state; do
  if [[ "$want $ok $state" == "install ok installed" ]]; then installed[$name]=1; fi
done < <(dpkg-query -W -f='${Package} ${Status}\n' "${packages[@]}" 2>/dev/null || true)
missing=()
for p in "${packages[@]}"; do
  [[ -n "${installed[$p]:-}" ]] || missing+=("$p")
done
if $list_missing; then
  echo "${missing[*]}"
  echo "${#packages[@]}"
  exit 0
fi
[[ ${#missing[@]} -eq 0 ]] && exit 0

echo "strata setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "strata setup: done"
