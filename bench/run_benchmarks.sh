#!/usr/bin/env bash
# One command: builds in Release (build/release/: inside build/, which rosrun does not search, so the relays in
# bin/ stay the only backlash_sim it finds) and prints the speed/accuracy table of the core against the
# methods users would write instead, the scipy rows, the thesis-grid sweep wall time and peak memory, and the thesis
# study against one scipy solution (bench/thesis_vs_scipy.sh).
# usage: bash bench/run_benchmarks.sh [--quick]
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/setup.sh >/dev/null   # dependencies (and the normal build)
# SUNDIALS CVODE for the compliant joint's comparison (only the benchmarks need it).
if ! dpkg-query -W -f='${Status}' libsundials-dev 2>/dev/null | grep -q "install ok installed"; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO=sudo
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends libsundials-dev >/dev/null
fi
mkdir -p build/release/devel/lib/python3/dist-packages
cmake -S . -B build/release -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release >/dev/null
make -C build/release -j"$(nproc)" bench_core bench_compliant backlash_sweep backlash_sim backlash_identify backlash_frf >/dev/null
bin=build/release/devel/lib/backlash_servo
ref=$(mktemp)
trap 'rm -f "$ref"' EXIT
echo "== core vs baselines (ratios: wall time per simulated second, baseline / ours)"
"$bin/bench_core" "$@" --reference-out "$ref"
echo "== the compliant joint against SUNDIALS CVODE (and the 1 kHz PID robot joint with a compliant mesh)"
"$bin/bench_compliant" "$@"
echo "== scipy solve_ivp with events (python; first 200 s of each case, or 20 s with --quick)"
/usr/bin/python3 bench/scipy_baseline.py "$ref" --max-sim "$([ "${1:-}" = --quick ] && echo 20 || echo 200)"
echo "== thesis grid (1344 points, until each verdict is settled)"
/usr/bin/time -f "peak memory %M kB" "$bin/backlash_sweep" --preset thesis --output "$ref.sweep.csv"
rm -f "$ref.sweep.csv"
echo "== tolerance study: 10 000 robot joints (config/robot_batch.yaml; four keys drawn; each until its verdict settles)"
/usr/bin/time -f "wall %e s, peak memory %M kB" "$bin/backlash_sweep" --config config/robot_batch.yaml \
  --monte-carlo 10000 --seed 1 --backlash 'uniform(0.0015,0.0045)' --restitution 'uniform(0.1,0.6)' \
  --load-coulomb-friction 'lognormal(-1.6,0.3)' --load-torque 'normal(-3.5,0.5)' --output "$ref.batch.csv" | head -5
rm -f "$ref.batch.csv"
echo "== the example arm: 3 joints under 1 kHz PIDs for 100 s, the arm's gravity and inertia at every sample vs held constant"
"$bin/backlash_sim" --config config/three_joint_arm.yaml --duration 100 | head -1
sed -e "s#^urdf: \.\./#urdf: $PWD/#" -e '/^  \(shoulder\|elbow\|wrist\):/a\    load_torque: 1.0\n    load_inertia: 0.5' \
  config/three_joint_arm.yaml >"$ref.arm.yaml"
"$bin/backlash_sim" --config "$ref.arm.yaml" --duration 100 | head -1
rm -f "$ref.arm.yaml"
echo "== identification of a 60 s recording at 1 kHz (the experiment through a 1 kHz P drive; target: seconds)"
work=$(mktemp -d)
printf 'controller_rate: 1000.0\ngain: 5.0\ngear_ratio: 1.0\nrestitution: 0.5\nbacklash: 0.3\n' >"$work/prior.yaml"
cp "$work/prior.yaml" "$work/truth.yaml"
printf 'motor_coulomb_friction: 0.05\nload_coulomb_friction: 0.1\nload_torque: 0.2\nprofile: %s\n' \
  "$work/experiment.yaml" >>"$work/truth.yaml"
"$bin/backlash_identify" --experiment --config "$work/prior.yaml" --output "$work/experiment.yaml" 2>/dev/null
"$bin/backlash_sim" --config "$work/truth.yaml" --duration 60 --sample-rate 1000 --csv "$work/rec.csv" >/dev/null
/usr/bin/time -o "$work/time" -f "backlash_identify: wall %e s, peak memory %M kB" \
  "$bin/backlash_identify" --data "$work/rec.csv" --config "$work/prior.yaml" 2>/dev/null | sed -n 2p
cat "$work/time"
echo "== the same joint with a compliant mesh (c = 1000 N*m/rad, d = 2 N*m*s/rad; the prior says compliant)"
printf 'mesh_stiffness: 1000.0\nmesh_damping: 2.0\n' >>"$work/truth.yaml"
printf 'mesh_stiffness: 5000.0\n' >>"$work/prior.yaml"
sed -i '/^restitution/d' "$work/truth.yaml" "$work/prior.yaml"
"$bin/backlash_sim" --config "$work/truth.yaml" --duration 60 --sample-rate 1000 --csv "$work/rec.csv" >/dev/null
/usr/bin/time -o "$work/time" -f "backlash_identify: wall %e s, peak memory %M kB" \
  "$bin/backlash_identify" --data "$work/rec.csv" --config "$work/prior.yaml" 2>/dev/null | sed -n 2p
cat "$work/time"
rm -rf "$work"
echo "== broadband FRF of the thesis joint under a 1 kHz P drive: chirp periods of 2^14, 2^16, 2^20 samples, a PRBS of 2^20 - 1"
echo "   (2 settling + 2 recorded periods each; the estimate's DFTs are fast transforms, the simulation dominates)"
for excitation in "chirp --chirp-samples 16384" "chirp --chirp-samples 65536" "chirp --chirp-samples 1048576" \
  "prbs --prbs-order 20"; do
  # shellcheck disable=SC2086
  /usr/bin/time -f "--excitation $excitation: wall %e s, peak memory %M kB" "$bin/backlash_frf" --amplitude 0.1 \
    --controller-rate 1000 --excitation $excitation --settle-periods 2 --periods 2 >/dev/null
done
echo "== the thesis study against one scipy solution of App. D1 (whole processes, alternately)"
bash bench/thesis_vs_scipy.sh "$([ "${1:-}" = --quick ] && echo 1 || echo 5)" "$bin"
