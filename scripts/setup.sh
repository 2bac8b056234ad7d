#!/usr/bin/env bash
# Installs the Debian 12 packages strata needs, only when some are missing.
# Idempotent and quiet when everything is present.
# Usage: scripts/setup.sh [--gis]   (--gis also installs GRASS, Graphviz and Chromium for
#                                   the integration tests that drive real GIS clients and
#                                   load the viewer and the field station's pages in a
#                                   headless browser, with Selenium)
set -euo pipefail

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
if [[ "${1:-}" == "--gis" ]]; then
  packages+=(grass-core graphviz chromium chromium-driver python3-selenium)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

echo "strata setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "strata setup: done"
