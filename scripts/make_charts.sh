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
py=scripts/backlash_charts.py
/usr/bin/python3 $py existence "$data/existence.csv" "$out" "$data/thesis.csv"
/usr/bin/python3 $py surface "$data/existence.csv" "$out"
/usr/bin/python3 $py error "$data/thesis.csv" "$out"
/usr/bin/python3 $py delta "$data/delta.csv" "$out"
/usr/bin/python3 $py phase "$data/fig31.csv" "$out" phase_portrait_fig31
/usr/bin/python3 $py digital "$data/rate.csv" "$data/encoder.csv" "$out"
cp "$data/rate.csv" "$out/digital_rate_sweep.csv"
cp "$data/encoder.csv" "$out/digital_encoder_sweep.csv"
cp "$data/thesis.csv" "$out/thesis_sweep.csv"
