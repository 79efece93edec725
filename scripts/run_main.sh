#!/usr/bin/env bash
# The main job: install, build, then run the thesis' limit-cycle case (App. D1) as a live ROS graph — the node is
# the clock (20× real time), roscore comes up with roslaunch, everything is recorded to a bag in $ROS_HOME (else
# ~/.ros) — and print a readable summary while it runs. Stops after 200 s of simulated time (~12 s of wall time).
# Exits 1 when the node fails (roslaunch itself exits 0 either way) or the run does not reach its end.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/setup.sh >/dev/null
set +u; source build/devel/setup.bash; set -u
log=$(mktemp)
trap 'rm -f "$log"' EXIT
# At stop_after the node ends the launch itself (a clean roslaunch shutdown); roslaunch exits 0 either way, so the
# outcome is read from its output.
set +e
roslaunch backlash_servo thesis_limit_cycle.launch real_time_factor:=20 stop_after:=200 "$@" 2>&1 | tee "$log"
set -e
if grep -E "\[backlash_servo[^]]*\] process has died \[pid [0-9]+, exit code" "$log" >/dev/null; then
  echo "run_main: the simulator node failed (see above)" >&2
  exit 1
fi
if ! grep -q "stop_after .* reached" "$log"; then
  echo "run_main: the run ended before stop_after (see above)" >&2
  exit 1
fi
bag="${ROS_HOME:-$HOME/.ros}/thesis_limit_cycle.bag"
echo "run_main: finished cleanly; bag: $bag"
[ -f "$bag" ] && /usr/bin/python3 bin/backlash_bag_report "$bag" || true
