#!/usr/bin/env bash
# Submits a planned terrain cook to Slurm: the units as one job array, the merge as a job that runs
# after every unit has ended (afterany), whatever their outcome.
#   submit.sh WORK_DIR ARCHIVE [--max-parallel K] [--partition P] [other sbatch arguments...]
# WORK_DIR holds plan.json from `terrain-cook plan INPUTS... --work-dir WORK_DIR`; it and ARCHIVE's folder
# must be on a filesystem every compute node sees. The terrain-cook used is $TERRAIN_COOK, else the one
# on PATH, resolved to an absolute path here and passed to the jobs. Prints the two job ids:
#   units_job=<id>
#   merge_job=<id>
# Running it again after a failure re-submits the array: complete units are skipped, so only the
# missing or failed ones are cooked, then the merge runs again.
set -euo pipefail
usage() { echo "usage: submit.sh WORK_DIR ARCHIVE [--max-parallel K] [--partition P] [sbatch args...]" >&2; exit 2; }
[ $# -ge 2 ] || usage
work_dir=$1 archive=$2
shift 2
max_parallel="" sbatch_args=()
while [ $# -gt 0 ]; do
  case $1 in
    --max-parallel) [ $# -ge 2 ] || usage; max_parallel=$2; shift 2 ;;
    --max-parallel=*) max_parallel=${1#*=}; shift ;;
    --partition) [ $# -ge 2 ] || usage; sbatch_args+=(--partition "$2"); shift 2 ;;
    --partition=*) sbatch_args+=("$1"); shift ;;
    *) sbatch_args+=("$1"); shift ;;
  esac
done
if [ -n "$max_parallel" ] && ! [[ $max_parallel =~ ^[1-9][0-9]*$ ]]; then
  echo "submit.sh: --max-parallel must be a positive integer, not '$max_parallel'" >&2; exit 2
fi

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
work_dir=$(cd "$work_dir" && pwd) || { echo "submit.sh: no work directory $1" >&2; exit 1; }
plan=$work_dir/plan.json
[ -f "$plan" ] || { echo "submit.sh: $plan is missing: run terrain-cook plan INPUTS... --work-dir $work_dir first" >&2; exit 1; }
archive_dir=$(cd "$(dirname "$archive")" && pwd) || { echo "submit.sh: no folder for $archive" >&2; exit 1; }
archive=$archive_dir/$(basename "$archive")

cook=${TERRAIN_COOK:-terrain-cook}
cook_path=$(command -v "$cook") || { echo "submit.sh: $cook not found (set TERRAIN_COOK or PATH)" >&2; exit 1; }
cook_path=$(cd "$(dirname "$cook_path")" && pwd)/$(basename "$cook_path")

# The unit count: "unit_count", else the length of the "units" array (or "units" itself when a number).
units=$(python3 - "$plan" <<'PY'
import json, sys
plan = json.load(open(sys.argv[1]))
n = plan.get("unit_count")
if n is None:
    u = plan.get("units")
    n = len(u) if isinstance(u, list) else u
if not isinstance(n, int) or isinstance(n, bool) or n < 1:
    sys.exit(f"no unit count in {sys.argv[1]} (expected \"unit_count\" or a \"units\" array)")
print(n)
PY
)

logs=$work_dir/slurm-logs
mkdir -p "$logs"
array="0-$((units - 1))${max_parallel:+%$max_parallel}"
# --export=ALL keeps the submitting shell's environment (GDAL/PROJ settings, test hooks) in the jobs.
units_job=$(sbatch --parsable --export=ALL,TERRAIN_COOK="$cook_path" --array="$array" \
  --output="$logs/unit-%A_%a.out" "${sbatch_args[@]}" "$here/terrain-cook-units.sbatch" "$work_dir")
units_job=${units_job%%;*}
merge_job=$(sbatch --parsable --export=ALL,TERRAIN_COOK="$cook_path" --dependency="afterany:$units_job" \
  --output="$logs/merge-%j.out" "${sbatch_args[@]}" "$here/terrain-cook-merge.sbatch" "$work_dir" "$archive")
merge_job=${merge_job%%;*}
echo "submitted $units units (array $array) of $work_dir; merge into $archive; logs in $logs" >&2
echo "units_job=$units_job"
echo "merge_job=$merge_job"
