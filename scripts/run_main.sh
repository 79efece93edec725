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
# The node is not `required` here: when it has finished (or died) this script stops roslaunch itself, so that a good
# run ends with roslaunch's ordinary shutdown instead of its red "REQUIRED process has died" banner.
set +e
roslaunch backlash_servo thesis_limit_cycle.launch real_time_factor:=20 stop_after:=200 required:=false "$@" \
  > >(tee "$log") 2>&1 &
launch_pid=$!
node_done='\[backlash_servo-[0-9]+\] process has (finished cleanly|died)'
while kill -0 "$launch_pid" 2>/dev/null; do
  if grep -Eq "$node_done" "$log"; then
    kill -INT "$launch_pid" 2>/dev/null
    break
  fi
  sleep 0.5
done
wait "$launch_pid"
sleep 0.2  # let tee flush the shutdown lines
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
