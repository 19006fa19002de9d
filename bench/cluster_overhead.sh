#!/usr/bin/env bash
# Per-unit scheduling overhead of the plan executors (docs/cluster.md), against running the same
# units in one process: every unit of a finished run's plan is already done, so what is timed is
# only what it costs to hand a unit to a process and have it find its result (process start,
# reading the plan, the mission's manifest and the fingerprint, the claim).
#   bash bench/cluster_overhead.sh AREOMAP MISSION WORK [--slurm]
# WORK/done is the finished run (made by a local run if missing). Prints one line per executor:
# units, wall seconds, seconds per unit and the ratio to the in-process figure.
set -euo pipefail
areomap=$(realpath "$1")
mission=$(realpath "$2")
work=$(realpath -m "$3")
slurm=${4:-}
mkdir -p "$work"
done_dir="$work/done"
if [ ! -f "$done_dir/summary.json" ]; then
  "$areomap" --quiet run "$mission" --out "$done_dir"
fi
"$areomap" --quiet run "$mission" --out "$done_dir" --plan
units=$(python3 -c 'import json,sys
plan = json.load(open(sys.argv[1]))
print(" ".join(u["id"] for s in plan["stages"] for u in s["units"] if u["id"] != "finish"))' \
  "$done_dir/plan.json")
count=$(wc -w <<< "$units")
now() { date +%s.%N; }
report() {  # name seconds
  python3 -c 'import sys
name, seconds, count, base = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
per = seconds / count
print(f"{name:<34} {count:>5} {seconds:>9.2f} {per * 1000:>10.1f} {per / base if base else 1:>8.1f}x")' \
    "$1" "$2" "$count" "${base:-0}"
}
printf "%-34s %5s %9s %10s %9s\n" "executor" "units" "wall [s]" "ms/unit" "vs one"
# shellcheck disable=SC2086
t0=$(now); "$areomap" --quiet run-unit "$done_dir" $units; t1=$(now)
one=$(python3 -c "print($t1 - $t0)")
base=""
report "one process, every unit" "$one"
base=$(python3 -c "print($one / $count)")
t0=$(now)
for unit in $units; do "$areomap" --quiet run-unit "$done_dir" "$unit"; done
t1=$(now)
report "one process per unit, in turn" "$(python3 -c "print($t1 - $t0)")"
t0=$(now)
parallel --will-cite --jobs 2 "$areomap" --quiet run-unit "$done_dir" {} ::: $units
t1=$(now)
report "GNU parallel, 2 slots" "$(python3 -c "print($t1 - $t0)")"
if [ "$slurm" = "--slurm" ]; then
  mkdir -p "$work/slurm"
  t0=$(now)
  for unit in $units; do
    sbatch --parsable --quiet --output="$work/slurm/%j.out" \
      --wrap="exec '$areomap' --quiet run-unit '$done_dir' $unit" > /dev/null
  done
  while [ -n "$(squeue --noheader --format=%i --name=wrap 2>/dev/null)" ]; do sleep 0.1; done
  t1=$(now)
  report "Slurm, one job per unit" "$(python3 -c "print($t1 - $t0)")"
fi
