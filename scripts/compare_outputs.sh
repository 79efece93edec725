#!/usr/bin/env bash
# Outputs of the tools on the D1 servo, a robot joint and the compliant joint, for a change that must not change
# results (a refactor): record them before, record them after, compare.
#
#   bash scripts/compare_outputs.sh record DIR     # the built tree's outputs into DIR (about 30 s)
#   bash scripts/compare_outputs.sh compare A B    # every difference between two records; exit 1 if any
#
# Recorded: backlash_sim (JSON) on every config/*.yaml, the robot joint rigid and compliant under a 1 kHz PID, the D1
# and compliant D1 under a 1 kHz P drive with a 200 s trajectory CSV; backlash_df, backlash_frf (stepped sines, rigid
# and compliant), backlash_design, a small backlash_sweep and backlash_identify on three recordings of the seeded
# identification corpus. Wall times are left out; everything else must match to the last digit.
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bin=build/devel/lib/backlash_servo

strip_times() {  # a JSON document on stdin, without its wall-time fields, keys sorted
  /usr/bin/python3 -c '
import json, sys
text = sys.stdin.read()
def strip(o):
    if isinstance(o, dict):
        return {k: strip(v) for k, v in o.items() if "wall" not in k and "elapsed" not in k and "seconds" not in k}
    if isinstance(o, list):
        return [strip(v) for v in o]
    return o
try:
    print(json.dumps(strip(json.loads(text)), indent=0, sort_keys=True))
except ValueError:
    print(text)
'
}

record() {
  local out=$1
  mkdir -p "$out"
  local robot="--motor-inertia 3e-5 --load-inertia 0.12 --motor-friction 5e-5 --load-friction 0.05 --gear-ratio 0.01
    --backlash 0.002618 --restitution 0.3 --load-torque -3.5 --motor-coulomb-friction 0.005 --load-coulomb-friction 0.2
    --control-law pid --controller-rate 1000 --gain 15 --integral-gain 100 --derivative-gain 0.3
    --load-encoder-resolution 131072 --torque-limit 0.5 --command 0.5"
  for c in config/*.yaml; do
    "$bin/backlash_sim" --config "$c" --json 2>&1 | strip_times >"$out/sim_$(basename "$c" .yaml).json"
  done
  # shellcheck disable=SC2086
  "$bin/backlash_sim" $robot --json 2>&1 | strip_times >"$out/sim_robot.json"
  # shellcheck disable=SC2086
  "$bin/backlash_sim" $robot --mesh-stiffness 2e4 --mesh-damping 5 --json 2>&1 | strip_times >"$out/sim_robot_compliant.json"
  "$bin/backlash_sim" --config config/compliant_d1.yaml --controller-rate 1000 --duration 200 --json 2>&1 |
    strip_times >"$out/sim_compliant_d1_sampled.json"
  "$bin/backlash_sim" --controller-rate 1000 --duration 200 --csv "$out/trajectory_d1.csv" --json 2>&1 |
    strip_times >"$out/sim_d1_sampled.json"
  "$bin/backlash_df" --json 2>&1 | strip_times >"$out/df.json"
  "$bin/backlash_frf" --frequency 0.1,0.5,2 --amplitude 0.5 --json 2>&1 | strip_times >"$out/frf.json"
  "$bin/backlash_frf" --config config/compliant_d1.yaml --frequency 0.3,1 --amplitude 0.5 --json 2>&1 |
    strip_times >"$out/frf_compliant.json"
  "$bin/backlash_design" --find max-gain --config config/default.yaml --controller-rate 1000 --json 2>&1 |
    strip_times >"$out/design.json"
  "$bin/backlash_sweep" --gain 0.5:4:8 --restitution 0.5 --output "$out/sweep.csv" 2>/dev/null
  (
    set +u
    source build/devel/setup.bash
    corpus="$out/corpus"
    /usr/bin/python3 scripts/identification_corpus.py generate --seed 5 --count 3 --out "$corpus" >/dev/null &&
      /usr/bin/python3 scripts/identification_corpus.py evaluate "$corpus" --json "$out/identify.raw.json" >/dev/null
  )
  strip_times <"$out/identify.raw.json" >"$out/identify.json" && rm -f "$out/identify.raw.json"
  echo "recorded $(ls "$out" | wc -l) outputs in $out"
}

case "${1:-}" in
  record)
    [ $# -eq 2 ] || { echo "usage: $0 record DIR"; exit 2; }
    [ -x "$bin/backlash_sim" ] || { echo "no built tree: make -C build all"; exit 2; }
    record "$2"
    ;;
  compare)
    [ $# -eq 3 ] || { echo "usage: $0 compare A B"; exit 2; }
    if diff -r "$2" "$3"; then
      echo "identical: $(ls "$2" | wc -l) outputs"
    else
      echo "the outputs differ (above)"
      exit 1
    fi
    ;;
  *)
    sed -n '2,11p' "$0"
    exit 2
    ;;
esac
