#!/usr/bin/env bash
# Regenerates every chart from scratch: runs the sweeps, then draws PNG + SVG into OUTDIR (default docs/).
# usage: bash scripts/make_charts.sh [--quick] [OUTDIR]     (--quick: tiny grids, for CI; seconds)
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
quick=0
if [ "${1:-}" = "--quick" ]; then quick=1; shift; fi
out=${1:-docs}
bin=build/devel/lib/backlash_servo
[ -x "$bin/backlash_sweep" ] || bash scripts/setup.sh >/dev/null
data=$(mktemp -d)
trap 'rm -rf "$data"' EXIT
if [ $quick = 1 ]; then
  n=4; zetas=0.2,0.6; es=0,1; thesis=(--zeta 0.2,0.6 --inertia-ratio 1,9 --friction-ratio 0,0.4 --restitution 1)
else
  n=100; zetas=0.1,0.2,0.3,0.4,0.5,0.6,0.8,1.0; es=0,0.6,0.8,1; thesis=(--preset thesis)
fi
echo "== existence grid (${n}x${n} x zeta {$zetas} x e {$es})"
"$bin/backlash_sweep" --zeta $zetas --inertia-ratio log:0.04:9:$n --friction-ratio 0:1:$n --restitution $es \
  --output "$data/existence.csv"
echo "== thesis grid"
"$bin/backlash_sweep" "${thesis[@]}" --output "$data/thesis.csv"
echo "== error vs backlash"
"$bin/backlash_sweep" --zeta 0.4 --inertia-ratio 9 --friction-ratio 0.4 --restitution 0.6,1 \
  --backlash log:0.01:1:$((quick ? 3 : 9)) --output "$data/delta.csv"
echo "== digital drive: error vs controller rate and vs encoder resolution"
"$bin/backlash_sweep" --controller-rate log:5:10000:$((quick ? 3 : 12)) --output "$data/rate.csv"
"$bin/backlash_sweep" --backlash 0.05 --restitution 0.5 --controller-rate 1000 \
  --load-encoder-resolution 0,256,4096$([ $quick = 1 ] || echo ,1024,16384,65536,262144,1048576) --output "$data/encoder.csv"
echo "== phase portrait (thesis Fig. 31 case)"
"$bin/backlash_sim" --config config/thesis_fig31.yaml --duration 120 --csv "$data/fig31.csv" --sample-rate 50 >/dev/null
echo "== compliant joint: D1 against the mesh stiffness, a robot joint's resonance"
stiffnesses=$([ $quick = 1 ] && echo "1e3 1e4" || echo "1e3 3e3 1e4 3e4 1e5 3e5 1e6")
for c in $stiffnesses; do
  # ζ_c = d / (2√(c μ)) = 0.0744 held (μ = 0.09 kg·m²): the rigid limit is e = 0.8.
  d=$(awk -v c="$c" 'BEGIN { printf "%.17g", 2 * 0.0744 * sqrt(0.09 * c) }')
  "$bin/backlash_sim" --config config/compliant_d1.yaml --mesh-stiffness "$c" --mesh-damping "$d" --json \
    >"$data/d1_c$c.json"
done
"$bin/backlash_sim" --config config/compliant_d1.yaml --mesh-stiffness 0 --mesh-damping 0 --restitution 0.8 --json \
  >"$data/d1_rigid.json"
"$bin/backlash_sim" --config config/compliant_d1.yaml --csv "$data/d1_c1e4.csv" --sample-rate 200 >/dev/null
# The robot joint of config/compare_compliant.yaml under its "PID on load + D" strategy: the same move there and back.
printf '%s\n' '- move: {time: 0.0, distance: 0.5, max_velocity: 0.5, max_acceleration: 2.0}' \
  '- move: {time: 5.0, distance: -0.2, max_velocity: 0.5, max_acceleration: 2.0}' >"$data/robot_move.yaml"
robot=(--motor-inertia 1e-4 --load-inertia 0.5 --motor-friction 1e-4 --load-friction 0.5 --gear-ratio 0.01
  --backlash 0.005 --restitution 0.5 --gain 6 --controller-rate 1000 --control-law pid --integral-gain 30
  --derivative-gain 0.8 --profile "$data/robot_move.yaml" --duration 10)
"$bin/backlash_sim" "${robot[@]}" --csv "$data/robot_rigid.csv" --sample-rate 2000 >/dev/null
"$bin/backlash_sim" "${robot[@]}" --mesh-stiffness 8.6e4 --mesh-damping 20 --csv "$data/robot_compliant.csv" \
  --sample-rate 2000 >/dev/null
py=scripts/backlash_charts.py
/usr/bin/python3 $py existence "$data/existence.csv" "$out" "$data/thesis.csv"
/usr/bin/python3 $py surface "$data/existence.csv" "$out"
/usr/bin/python3 $py error "$data/thesis.csv" "$out"
/usr/bin/python3 $py delta "$data/delta.csv" "$out"
/usr/bin/python3 $py phase "$data/fig31.csv" "$out" phase_portrait_fig31
/usr/bin/python3 $py digital "$data/rate.csv" "$data/encoder.csv" "$out"
/usr/bin/python3 $py compliant "$data" "$out"
cp "$data/rate.csv" "$out/digital_rate_sweep.csv"
cp "$data/encoder.csv" "$out/digital_encoder_sweep.csv"
cp "$data/thesis.csv" "$out/thesis_sweep.csv"
