#!/usr/bin/env bash
# The headline ratio: the whole thesis study (`backlash_sweep --preset thesis`,
# one process, all cores) against ONE ordinary event-driven ODE solution of App. D1 (scipy solve_ivp with events,
# bench/scipy_baseline.py --d1, one process, simulated as long as our run of D1 takes to settle), the two whole
# processes timed alternately, RUNS times. Prints each pair, then the ratios' minimum, median and maximum.
# usage: bash bench/thesis_vs_scipy.sh [RUNS] [BIN_DIR]     (defaults: 5, build/devel/lib/backlash_servo)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
runs=${1:-5}
bin=${2:-build/devel/lib/backlash_servo}
out=$(mktemp)
trap 'rm -f "$out"' EXIT
now() { date +%s.%N; }
d1=$("$bin/backlash_sim" --json | /usr/bin/python3 -c 'import json, sys; print(json.load(sys.stdin)["simulated_time"])')
echo "thesis preset (whole process) vs one scipy solution of App. D1 over ${d1} s (our D1 run until settled)"
# One untimed run of each first: a cold start (scipy's imports, the page cache) would flatter whichever runs second.
"$bin/backlash_sweep" --preset thesis --output "$out" 2>/dev/null
/usr/bin/python3 bench/scipy_baseline.py --d1 "$d1" >/dev/null
ratios=()
for i in $(seq "$runs"); do
  t0=$(now)
  "$bin/backlash_sweep" --preset thesis --output "$out" 2>/dev/null
  t1=$(now)
  /usr/bin/python3 bench/scipy_baseline.py --d1 "$d1" >/dev/null
  t2=$(now)
  line=$(/usr/bin/python3 -c "a = $t1 - $t0; b = $t2 - $t1; print('%.3f %.3f %.2f' % (a, b, a / b))")
  read -r thesis scipy ratio <<<"$line"
  echo "run $i: thesis ${thesis} s, scipy ${scipy} s, ratio ${ratio}"
  ratios+=("$ratio")
done
/usr/bin/python3 -c "
import statistics, sys
r = sorted(float(x) for x in sys.argv[1:])
print('ratio (thesis study / one scipy solution): min %.2f, median %.2f, max %.2f over %d runs (target: < 1)'
      % (r[0], statistics.median(r), r[-1], len(r)))" "${ratios[@]}"
