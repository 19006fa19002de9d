#!/usr/bin/env bash
# Quick start, first command: install what is missing, build (Release) and run the main job on
# the built-in demo mission, writing everything under ./demo (or the folder given as $1).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-demo}"
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"

bash scripts/install-deps.sh
cmake --preset release >/dev/null
# The CLI, and the Python module where it is configured (docs/python.md).
targets=(areomap)
grep -q '^AREOMAP_PYTHON:BOOL=ON' build/release/CMakeCache.txt && targets+=(_areomap)
cmake --build --preset release --target "${targets[@]}"
areomap=./build/release/apps/areomap

echo "== areomap simulate: the demo mission (terrain, craters, rocks, HiRISE-like products, traverse)"
"$areomap" simulate --preset demo --seed 1 --out "$out/mission"
echo
echo "== areomap run: stereo, DTM/orthophoto, registration onto HiRISE, rock tie points, craters, bundle adjustment, traverse DTM/orthomosaic"
"$areomap" run "$out/mission" --out "$out/run"
echo
echo "outputs in $out (mission/ is the generated input, run/ the products; open run/report.html,"
echo "run/adjustment/traverse.gpkg, run/products/traverse_ortho.tif, run/products/traverse_dtm.tif and"
echo "run/craters/craters.gpkg in a browser or QGIS)"
