#!/usr/bin/env bash
# What `areomap run ... --executor slurm` does, with plain sbatch, for users who write their own
# submission (other dependencies, per-stage resources, a site's module loads): one job array per
# stage of DIR/plan.json, task i running the stage's unit i, each stage after the stages it waits
# for (afterok; a failed unit cancels what depends on it). docs/cluster.md.
#   bash scripts/slurm_plan.sh DIR [sbatch options...]
# DIR holds plan.json (`areomap run MISSION --out DIR --plan`); AREOMAP names the areomap
# executable (default: areomap on PATH), which every node must reach at the same path.
set -euo pipefail
if [ $# -lt 1 ] || [ ! -f "$1/plan.json" ]; then
  echo "usage: slurm_plan.sh DIR [sbatch options...] (DIR/plan.json from areomap run --plan)" >&2
  exit 2
fi
dir=$(realpath "$1")
shift
areomap=$(command -v "${AREOMAP:-areomap}") || { echo "areomap not found (set AREOMAP)" >&2; exit 2; }
mkdir -p "$dir/slurm"
declare -A job_of_stage
# Each stage: its name, its unit count and the stages it waits for, one line per stage.
while read -r stage units after; do
  [ "$units" -gt 0 ] || continue
  dependency=()
  ids=""
  for name in ${after//,/ }; do
    [ -n "${job_of_stage[$name]:-}" ] && ids="$ids:${job_of_stage[$name]}"
  done
  [ -n "$ids" ] && dependency=("--dependency=afterok$ids")
  id=$(sbatch --parsable --job-name="areomap-$stage" --array="0-$((units - 1))" \
    --kill-on-invalid-dep=yes --output="$dir/slurm/$stage-%A_%a.out" "${dependency[@]}" "$@" \
    --wrap="exec '$areomap' run-unit '$dir' --stage '$stage' --task-index \$SLURM_ARRAY_TASK_ID")
  id=${id%%;*}
  job_of_stage[$stage]=$id
  echo "slurm job $id: stage $stage ($units tasks)"
done < <(python3 - "$dir/plan.json" <<'PY'
import json, sys
for stage in json.load(open(sys.argv[1]))["stages"]:
    print(stage["name"], len(stage["units"]), ",".join(stage["after"]) or "-")
PY
)
echo "follow with: $areomap run-status $dir"
