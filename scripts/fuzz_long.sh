#!/usr/bin/env bash
# Long property-fuzz run: N cases (default 100000) of seed S on every core, counts per outcome class, one example
# command line per failure class, and each process's slowest cases.
# usage: bash scripts/fuzz_long.sh [N] [SEED] [--compliant | --damped]
# (--compliant: the same cases with a compliant mesh and shaft drawn across the envelope, no dry friction;
# --damped: those with contact and shaft damping ratios up to the envelope's edge)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
N=${1:-100000}
SEED=${2:-1}
EXTRA=${3:-}
make -C build -j"$(nproc)" backlash_fuzz >/dev/null
jobs=$(nproc)
per=$(( (N + jobs - 1) / jobs ))
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for ((j = 0; j < jobs; ++j)); do
  first=$((j * per))
  count=$(( first + per > N ? N - first : per ))
  [ "$count" -gt 0 ] || continue
  build/devel/lib/backlash_servo/backlash_fuzz --cases "$count" --first "$first" --seed "$SEED" $EXTRA >"$tmp/$j.txt" || true &
done
wait
awk '/^  [a-z_]+ +[0-9]+$/ {n[$1] += $2} END {for (k in n) printf "  %-12s %d\n", k, n[k]}' "$tmp"/*.txt | sort
grep -h "^example" "$tmp"/*.txt | sort -u -t' ' -k2,2 | head -20 || true
grep -h "in [0-9.]* s$" "$tmp"/*.txt
grep -h "^  slowest:" "$tmp"/*.txt
