#!/usr/bin/env bash
# The planned mission run (docs/cluster.md) against the local run on the same mission: through
# GNU parallel on two "hosts" (tests/cluster/local_ssh.sh stands in for ssh), after a unit killed
# with SIGKILL halfway, with two executors started on one plan at once (each unit computed
# exactly once), and, with --slurm, through a Slurm cluster (`--executor slurm --wait`). Each
# run's summary figures and files must equal the local run's (scripts/compare_runs.sh).
# With --data (../shared/data), also a crater catalogue over three real CTX images given a made-up
# overlapping georeference, planned and run through GNU parallel, against the local catalogue,
# and with an unreadable image (a failed unit, the others merged).
#   executors_test.sh AREOMAP WORK [--slurm] [--mission DIR] [--data DIR] [--only STEP[,STEP...]]
# STEP: parallel, kill, twice, slurm, catalogue (all by default; slurm only with --slurm,
# catalogue only with --data).
# Without --mission, a three-site mission is generated into WORK. Exits non-zero on the first
# difference or failure.
set -euo pipefail
areomap=$(realpath "$1")
work=$(realpath -m "$2")
shift 2
root=$(cd "$(dirname "$0")/../.." && pwd)
slurm=0
mission=""
data=""
only=""
while [ $# -gt 0 ]; do
  case "$1" in
    --slurm) slurm=1 ;;
    --mission) mission=$(realpath "$2"); shift ;;
    --data) data="$2"; shift ;;
    --only) only="$2"; shift ;;
    *) echo "usage: executors_test.sh AREOMAP WORK [--slurm] [--mission DIR] [--data DIR] [--only STEP]" >&2; exit 2 ;;
  esac
  shift
done
wanted() { [ -z "$only" ] || [[ ",$only," == *",$1,"* ]]; }
rm -rf "$work"
mkdir -p "$work"
if [ -z "$mission" ] && [ "$only" != catalogue ]; then
  mission="$work/mission"
  "$areomap" --quiet simulate --out "$mission" --sites 3 --navcam-pairs 1 --min-leg 3 --max-leg 4
fi
step() { echo "== $(date +%T) $*"; }

if [ -n "$only" ] && [ "$only" = catalogue ]; then
  :  # The catalogue needs no mission run.
else
  step "local run"
  "$areomap" --quiet run "$mission" --out "$work/local"
fi

if wanted parallel; then
  step "GNU parallel on two hosts"
  printf 'nodeA\nnodeB\n' > "$work/hosts"
  "$areomap" run "$mission" --out "$work/parallel" --executor parallel --hosts "$work/hosts" \
    --jobs 1 --parallel-args "--ssh $root/tests/cluster/local_ssh.sh" > "$work/parallel.log"
  grep -q "^stage finish: 1 units done" "$work/parallel.log"
  bash "$root/scripts/compare_runs.sh" "$work/local" "$work/parallel"
  "$areomap" run-status "$work/parallel" | tee "$work/parallel.status"
  grep -qE "^finish +1 +0 +0 +0" "$work/parallel.status"
fi

if wanted kill; then
  step "a unit killed with SIGKILL halfway, then the plan run again"
  "$areomap" --quiet run "$mission" --out "$work/kill" --plan
  "$areomap" --quiet run-unit "$work/kill" site_000 &
  victim=$!
  claim="$work/kill/.areomap-units/site_000.claim"
  for _ in $(seq 1 100); do [ -f "$claim" ] && break; sleep 0.1; done
  # Halfway: once the stereo has written its points (the unit's other products still to come).
  for _ in $(seq 1 600); do [ -f "$work/kill/sites/site_000/points.ply" ] && break; sleep 0.1; done
  kill -KILL "$victim"
  wait "$victim" 2>/dev/null || true
  [ -f "$claim" ] || { echo "the killed unit left no claim" >&2; exit 1; }
  [ ! -f "$work/kill/sites/site_000/unit.json" ] || { echo "killed too late" >&2; exit 1; }
  "$areomap" run-status "$work/kill" | grep -q "site_000: stale claim"
  "$areomap" run "$mission" --out "$work/kill" --executor parallel --jobs 2 > "$work/kill.log"
  grep -q "site_000: computed" "$work/kill.log"
  bash "$root/scripts/compare_runs.sh" "$work/local" "$work/kill"
fi

if wanted twice; then
  step "two executors started at once on one folder (one writes the plan, both use it)"
  "$areomap" run "$mission" --out "$work/twice" --executor parallel --jobs 2 \
    > "$work/twice_a.log" 2>&1 &
  first=$!
  "$areomap" run "$mission" --out "$work/twice" --executor parallel --jobs 2 \
    > "$work/twice_b.log" 2>&1 &
  second=$!
  wait "$first"
  wait "$second"
  units=$(python3 -c 'import json,sys
plan = json.load(open(sys.argv[1]))
print(" ".join(u["id"] for s in plan["stages"] for u in s["units"]))' "$work/twice/plan.json")
  for unit in $units; do
    computed=$(cat "$work/twice_a.log" "$work/twice_b.log" | grep -c "^$unit: computed" || true)
    # A second pass that has nothing to do is reused by both.
    if [ "$computed" -gt 1 ] || { [ "$computed" = 0 ] && [[ "$unit" != *_pass2 ]]; }; then
      echo "unit $unit computed $computed times by the two executors" >&2
      cat "$work/twice_a.log" "$work/twice_b.log" >&2
      exit 1
    fi
  done
  bash "$root/scripts/compare_runs.sh" "$work/local" "$work/twice"
fi

if [ "$slurm" = 1 ] && wanted slurm; then
  step "Slurm"
  sinfo >/dev/null || { echo "no Slurm cluster answers (scripts/slurm-single-node.sh)" >&2; exit 1; }
  "$areomap" run "$mission" --out "$work/slurm" --executor slurm --wait | tee "$work/slurm.log"
  grep -qE "^slurm job [0-9]+: stage finish" "$work/slurm.log"
  bash "$root/scripts/compare_runs.sh" "$work/local" "$work/slurm"
fi
ctx="$data/craters-train/ctx-mc11e"
if [ -n "$data" ] && [ -d "$ctx" ] && wanted catalogue; then
  step "crater catalogue of three CTX images, planned, through GNU parallel"
  mkdir -p "$work/ctx"
  x0=0
  for name in A B C; do  # 2000 px of 6 m side by side, overlapping by 200 px.
    gdal_translate -q -a_srs IAU_2015:49910 -a_ullr "$x0" 0 $((x0 + 12000)) -12000 \
      "$ctx/MC11E-$name.png" "$work/ctx/$name.tif"
    x0=$((x0 + 10800))
  done
  images=("$work/ctx/A.tif" "$work/ctx/B.tif" "$work/ctx/C.tif")
  "$areomap" --quiet craters "${images[@]}" --out "$work/catalogue_local"
  "$areomap" craters "${images[@]}" --out "$work/catalogue" --executor parallel --jobs 2 \
    > "$work/catalogue.log"
  grep -q "^catalogue of 3 images (0 failed)" "$work/catalogue.log"
  for dir in "$work/catalogue_local/images/"*; do
    cmp "$dir/craters.csv" "$work/catalogue/images/$(basename "$dir")/craters.csv"
  done
  # The merged rows, but for the source image's path (as given locally, absolute in a plan).
  cmp <(cut -d, -f1,3- "$work/catalogue_local/craters.csv") \
    <(cut -d, -f1,3- "$work/catalogue/craters.csv")
  step "a catalogue with an unreadable image: a failed unit, the others merged"
  echo "not a raster" > "$work/ctx/broken.tif"
  if "$areomap" --quiet craters "$work/ctx/A.tif" "$work/ctx/broken.tif" \
    --out "$work/catalogue_broken" --executor parallel --jobs 2 2> "$work/catalogue_broken.err"; then
    echo "a catalogue with an unreadable image succeeded" >&2
    exit 1
  fi
  grep -q "image_002: failed, [^ ]*broken.tif: not a readable raster" "$work/catalogue_broken.err"
  grep -q "^002_broken,.*,failed," "$work/catalogue_broken/images.csv"
  grep -q "^001_A,.*,ok," "$work/catalogue_broken/images.csv"
  grep -q "not a readable raster" "$work/catalogue_broken/images/002_broken/error.txt"
fi
step "executors_test: every run equals the local run"
