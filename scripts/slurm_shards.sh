#!/usr/bin/env bash
# Runs a sharded backlash_sweep or backlash_frf on a Slurm cluster: an array job of N parts (TOOL --shard K/N, one
# task per part) plus a merge job that starts when every part succeeded and writes exactly the CSV a single run would
# (TOOL --merge). Prints the two job ids; the merged CSV appears at OUTPUT. Called through scripts/slurm_sweep.sh and
# scripts/slurm_frf.sh.
#
# usage: bash scripts/slurm_shards.sh TOOL -n PARTS -o OUTPUT [-d WORKDIR] [-- SBATCH_OPTION...] -- TOOL_ARGUMENT...
#   TOOL         backlash_sweep or backlash_frf
#   -n PARTS     number of parts (array tasks), e.g. 100
#   -o OUTPUT    merged CSV (absolute or relative to the current directory)
#   -d WORKDIR   where parts and Slurm logs go (default: OUTPUT.parts/); must be on a filesystem all nodes share
#   sbatch options (partition, time limit, account, ...) go between the first and the second "--", e.g.
#   bash scripts/slurm_sweep.sh -n 50 -o fine.csv -- --partition=short --time=00:30:00 -- --preset thesis
# Environment: BACKLASH_SWEEP, BACKLASH_FRF = the executables (default: this checkout's build, else PATH).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
tool=${1:-}
shift || true
case $tool in
  backlash_sweep) exe=${BACKLASH_SWEEP:-} out_flag=--output check=(--max-duration 1e-9) resume=(--resume) ;;
  backlash_frf) exe=${BACKLASH_FRF:-} out_flag=--csv check=(--dry-run) resume=() ;;
  *) sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2 ;;
esac
name=${tool#backlash_}
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
tool_args=("$@")
if ! [[ "$parts" =~ ^[1-9][0-9]*$ ]] || [ -z "$output" ]; then
  echo "slurm_$name.sh: -n PARTS (a positive whole number) and -o OUTPUT are required (got -n '$parts' -o '$output')" >&2
  exit 2
fi
command -v sbatch >/dev/null || { echo "slurm_$name.sh: sbatch not found (is this a Slurm submit host?)" >&2; exit 2; }
exe=${exe:-$here/build/devel/lib/backlash_servo/$tool}
[ -x "$exe" ] || exe=$(command -v "$tool" || true)
[ -x "$exe" ] || { echo "slurm_$name.sh: $tool not built (bash scripts/setup.sh) and not on PATH" >&2; exit 2; }
output=$(realpath -m "$output")
workdir=$(realpath -m "${workdir:-$output.parts}")
mkdir -p "$workdir"
# Refuse bad arguments now, not in N failed tasks (every point is validated before any is computed; the check
# computes nothing, or part 1 under a negligible time cap, and is thrown away).
status=0
"$exe" "${tool_args[@]}" --shard "1/$parts" "$out_flag" "$workdir/check.csv" --jobs 1 "${check[@]}" \
  >/dev/null 2>"$workdir/check.err" || status=$?
rm -f "$workdir/check.csv"
if [ $status -eq 2 ]; then
  cat "$workdir/check.err" >&2
  exit 2
fi
quoted=$(printf ' %q' "${tool_args[@]}")
array_id=$(sbatch --parsable "${sbatch_opts[@]}" --job-name="$tool" --array="1-$parts" \
  --output="$workdir/part_%a.log" --cpus-per-task=1 \
  --wrap="exec $(printf %q "$exe")$quoted --jobs 1 --shard \$SLURM_ARRAY_TASK_ID/$parts ${resume[*]} $out_flag $(printf %q "$workdir")/part_\$SLURM_ARRAY_TASK_ID.csv")
array_id=${array_id%%;*}
merge_id=$(sbatch --parsable "${sbatch_opts[@]}" --job-name=backlash_merge --dependency="afterok:$array_id" \
  --output="$workdir/merge.log" \
  --wrap="exec $(printf %q "$exe") --merge $(printf %q "$workdir")/part_*.csv $out_flag $(printf %q "$output")")
merge_id=${merge_id%%;*}
echo "slurm_$name.sh: array job $array_id ($parts parts) -> merge job $merge_id -> $output"
echo "$array_id $merge_id"
