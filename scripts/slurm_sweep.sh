#!/usr/bin/env bash
# Runs a backlash_sweep on a Slurm cluster: an array job of N parts (backlash_sweep --shard K/N, one task per part,
# resumable if requeued) plus a merge job that starts when every part succeeded and writes exactly the CSV a single
# run would (backlash_sweep --merge). Prints the two job ids; the merged CSV appears at OUTPUT.
#
# usage: bash scripts/slurm_sweep.sh -n PARTS -o OUTPUT [-d WORKDIR] [-- SBATCH_OPTION...] -- SWEEP_ARGUMENT...
#   -n PARTS     number of parts (array tasks), e.g. 100
#   -o OUTPUT    merged CSV (absolute or relative to the current directory)
#   -d WORKDIR   where parts and Slurm logs go (default: OUTPUT.parts/); must be on a filesystem all nodes share
#   sbatch options (partition, time limit, account, ...) go between the first and the second "--", e.g.
#   bash scripts/slurm_sweep.sh -n 50 -o fine.csv -- --partition=short --time=00:30:00 -- --preset thesis
# Environment: BACKLASH_SWEEP = the backlash_sweep executable (default: this checkout's build, else PATH).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
parts="" output="" workdir=""
while getopts "n:o:d:h" opt; do
  case $opt in
    n) parts=$OPTARG ;;
    o) output=$OPTARG ;;
    d) workdir=$OPTARG ;;
    *) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'; exit 2 ;;
  esac
done
shift $((OPTIND - 1))
sbatch_opts=()
if [ "${1:-}" = "--" ]; then
  shift
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do sbatch_opts+=("$1"); shift; done
  [ "${1:-}" = "--" ] && shift
fi
sweep_args=("$@")
if ! [[ "$parts" =~ ^[1-9][0-9]*$ ]] || [ -z "$output" ]; then
  echo "slurm_sweep.sh: -n PARTS (a positive whole number) and -o OUTPUT are required (got -n '$parts' -o '$output')" >&2
  exit 2
fi
command -v sbatch >/dev/null || { echo "slurm_sweep.sh: sbatch not found (is this a Slurm submit host?)" >&2; exit 2; }
sweep=${BACKLASH_SWEEP:-$here/build/devel/lib/backlash_servo/backlash_sweep}
[ -x "$sweep" ] || sweep=$(command -v backlash_sweep || true)
[ -x "$sweep" ] || { echo "slurm_sweep.sh: backlash_sweep not built (bash scripts/setup.sh) and not on PATH" >&2; exit 2; }
output=$(realpath -m "$output")
workdir=$(realpath -m "${workdir:-$output.parts}")
mkdir -p "$workdir"
# Refuse bad sweep arguments now, not in N failed tasks (every point is validated before any is computed; the
# check computes part 1 with a negligible time cap and is thrown away).
status=0
"$sweep" "${sweep_args[@]}" --shard "1/$parts" --output "$workdir/check.csv" --jobs 1 --max-duration 1e-9 \
  >/dev/null 2>"$workdir/check.err" || status=$?
rm -f "$workdir/check.csv"
if [ $status -eq 2 ]; then
  cat "$workdir/check.err" >&2
  exit 2
fi
quoted=$(printf ' %q' "${sweep_args[@]}")
array_id=$(sbatch --parsable "${sbatch_opts[@]}" --job-name=backlash_sweep --array="1-$parts" \
  --output="$workdir/part_%a.log" --cpus-per-task=1 \
  --wrap="exec $(printf %q "$sweep")$quoted --jobs 1 --shard \$SLURM_ARRAY_TASK_ID/$parts --resume --output $(printf %q "$workdir")/part_\$SLURM_ARRAY_TASK_ID.csv")
array_id=${array_id%%;*}
merge_id=$(sbatch --parsable "${sbatch_opts[@]}" --job-name=backlash_merge --dependency="afterok:$array_id" \
  --output="$workdir/merge.log" \
  --wrap="exec $(printf %q "$sweep") --merge $(printf %q "$workdir")/part_*.csv --output $(printf %q "$output")")
merge_id=${merge_id%%;*}
echo "slurm_sweep.sh: array job $array_id ($parts parts) -> merge job $merge_id -> $output"
echo "$array_id $merge_id"
