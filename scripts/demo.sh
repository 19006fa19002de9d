#!/usr/bin/env bash
# Quick start, first command: install what is missing, build (Release) and run the main job on
# the built-in demo mission, writing everything under ./demo (or the folder given as $1).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-demo}"
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"

bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release --target areomap
areomap=./build/release/apps/areomap

echo "== areomap simulate: the demo mission (terrain, craters, rocks, HiRISE-like products, traverse)"
"$areomap" simulate --preset demo --seed 1 --out "$out/mission"
echo
echo "== areomap info: where the orbital image is on Mars"
"$areomap" info "$out/mission/orbital/hirise_ortho.tif"
echo
echo "== areomap coords: the true sites (north, east, down in site 0's frame) -> lat, lon (0-360), h"
origin=$(sed -n 2p "$out/mission/truth/sites.csv" | cut -d, -f6-8)  # Site 0: lat,lon,h.
tail -n +2 "$out/mission/truth/sites.csv" | cut -d, -f2-4 |
  "$areomap" coords --from site --origin "$origin" --to planetocentric,360
echo
echo "== areomap coords: the same sites as orbital image pixels (col row)"
tail -n +2 "$out/mission/truth/sites.csv" | cut -d, -f6-8 | awk -F, '{print $1, $2, $3}' |
  "$areomap" coords --from planetocentric --to "pixel:$out/mission/orbital/hirise_ortho.tif"
echo
echo "outputs in $out/mission (mission.json is the manifest; open orbital/*.tif in QGIS)"
