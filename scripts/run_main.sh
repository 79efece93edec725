#!/usr/bin/env bash
# The main job: install, build, then run the thesis' limit-cycle case (App. D1) as a live ROS graph — the node is
# the clock (20× real time), roscore comes up with roslaunch, everything is recorded to a bag in ~/.ros — and print
# a readable summary while it runs. Stops after 200 s of simulated time (~12 s of wall time).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/setup.sh >/dev/null
set +u; source build/devel/setup.bash; set -u
exec roslaunch backlash_servo thesis_limit_cycle.launch real_time_factor:=20 stop_after:=200 "$@"
