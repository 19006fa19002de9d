#!/usr/bin/env bash
# Compares two `areomap run` output folders for a change that must not alter results (a
# refactoring) or a run made another way (a plan's units on Slurm or GNU parallel): summary.json
# without its run-specific fields (times, the mission folder, "units": which units this
# invocation computed or reused), every GeoTIFF by georeference and pixel checksums (gdalinfo),
# every CSV byte for byte. Prints each difference; exits 1 if any, 0 if the two runs carry the
# same figures and rasters.
#   bash scripts/compare_runs.sh RUN_A RUN_B [--skip UNIT]...
# --skip UNIT leaves out a unit that is meant to differ: its folder and its summary.json entry
# (e.g. --skip craters after a change of crater detector).
set -euo pipefail
usage="usage: compare_runs.sh RUN_A RUN_B [--skip UNIT]... (two areomap run output folders)"
if [ $# -lt 2 ] || [ ! -f "$1/summary.json" ] || [ ! -f "$2/summary.json" ]; then
  echo "$usage" >&2
  exit 2
fi
a="$1"
b="$2"
shift 2
skip=()
while [ $# -gt 0 ]; do
  if [ "$1" != "--skip" ] || [ $# -lt 2 ]; then
    echo "$usage" >&2
    exit 2
  fi
  skip+=("$2")
  shift 2
done
differ=0

# summary.json less every "*seconds" field and the skipped units, keys sorted.
figures() {
  python3 - "$1" "${skip[@]}" <<'PY'
import json, sys
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in v.items() if not k.endswith("seconds")}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
summary = json.load(open(sys.argv[1] + "/summary.json"))
for unit in sys.argv[2:]:
    summary.pop(unit, None)
    summary.get("units", {}).pop(unit, None)
summary.pop("mission", None)
summary.pop("units", None)
print(json.dumps(strip(summary), indent=1, sort_keys=True))
PY
}
if ! diff <(figures "$a") <(figures "$b") >/tmp/compare_runs.$$; then
  echo "differ: summary.json"
  head -20 /tmp/compare_runs.$$
  differ=1
fi
rm -f /tmp/compare_runs.$$

raster_digest() {
  gdalinfo -checksum -nomd -norat -noct "$1" | grep -vE "^(Files:|  [^ ]*\.(tif|aux\.xml))"
}
prune=()
for unit in "${skip[@]}"; do prune+=(-path "$a/$unit" -prune -o); done
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
done < <(find "$a" "${prune[@]}" -type f \( -name '*.tif' -o -name '*.csv' \) -print0 | sort -z)
echo "compare_runs: summary.json and $count GeoTIFF and CSV files compared: $([ $differ = 0 ] && echo identical || echo DIFFERENT)"
exit $differ
