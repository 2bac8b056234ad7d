#!/usr/bin/env bash
# Builds strata and runs every test. Installs the Debian packages it needs first
# (including GRASS and Graphviz, which the GIS integration tests drive).
# Usage: scripts/test.sh            (build folder: build/)
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh --gis
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build -j "$(nproc)"
cd build
ctest --output-on-failure -j "$(nproc)" --timeout 900
