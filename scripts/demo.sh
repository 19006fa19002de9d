#!/usr/bin/env bash
# Quick start, first command: install what is missing, build (Release) and run the main job on
# the built-in sample, writing everything under ./demo (or the folder given as $1).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-demo}"
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"

bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release --target areomap
areomap=./build/release/apps/areomap

echo "== areomap sample: a small georeferenced Mars DTM (Gusev, HiRISE-style projection)"
"$areomap" sample --out "$out"
echo
echo "== areomap info: where it is on Mars"
"$areomap" info "$out/sample_dtm.tif"
echo
echo "== areomap coords: tile centre and a point 100 m north, planetocentric -> MER site frame"
printf -- '-14.5692 175.4729 -1900\n-14.5675 175.4729 -1900\n' |
  "$areomap" coords --from planetocentric --to site --origin -14.5692,175.4729,-1900
echo
echo "== areomap coords: DTM pixel (col row) -> planetocentric lat, east lon (0-360), height"
printf '0.5 0.5\n128 128\n' |
  "$areomap" coords --from "pixel:$out/sample_dtm.tif" --to planetocentric,360
echo
echo "outputs in $out/ (open sample_dtm.tif in QGIS; summary.json has the key figures)"
