#!/usr/bin/env bash
# Compares two `areomap run` output folders for a refactoring that must not change results:
# summary.json with its run-specific fields removed (times, versions, paths), every GeoTIFF by
# georeference and pixel checksums (gdalinfo), every CSV byte for byte. Prints each difference;
# exits 1 if any, 0 if the two runs carry the same figures and rasters.
#   bash scripts/compare_runs.sh RUN_A RUN_B
set -euo pipefail
if [ $# -ne 2 ] || [ ! -f "$1/summary.json" ] || [ ! -f "$2/summary.json" ]; then
  echo "usage: compare_runs.sh RUN_A RUN_B (two areomap run output folders with summary.json)" >&2
  exit 2
fi
a="$1"
b="$2"
differ=0

# Fields that name the run rather than its result.
strip() {
  sed -E '/"(seconds|wall_s|elapsed_s|started|finished|version|out|mission|created|duration_s)"[[:space:]]*:/d' "$1"
}
if ! diff <(strip "$a/summary.json") <(strip "$b/summary.json") >/dev/null; then
  echo "differ: summary.json"
  diff <(strip "$a/summary.json") <(strip "$b/summary.json") | head -20
  differ=1
fi

raster_digest() {
  gdalinfo -checksum -nomd -norat -noct "$1" | grep -vE "^(Files:|  [^ ]*\.(tif|aux\.xml))"
}
count=0
while IFS= read -r -d '' f; do
  rel="${f#"$a"/}"
  count=$((count + 1))
  if [ ! -f "$b/$rel" ]; then
    echo "missing in $b: $rel"
    differ=1
  elif [[ "$rel" == *.tif ]]; then
    if ! diff <(raster_digest "$f") <(raster_digest "$b/$rel") >/dev/null; then
      echo "differ: $rel"
      differ=1
    fi
  elif ! cmp -s "$f" "$b/$rel"; then
    echo "differ: $rel"
    differ=1
  fi
done < <(find "$a" -type f \( -name '*.tif' -o -name '*.csv' \) -print0 | sort -z)
echo "compare_runs: $count GeoTIFF and CSV files and summary.json compared: $([ $differ = 0 ] && echo identical || echo DIFFERENT)"
exit $differ
