#!/usr/bin/env bash
# Node throughput and CPU (issue figures; a benchmark, not a test). Prints the node's own measurement lines:
#  1. node is the clock, real_time_factor 0 (as fast as possible), 100 Hz and 1 kHz publishing, rosbag recording;
#  2. real-time mode (wall clock, factor 1) at 1 kHz for 20 s with a rosbag subscriber: CPU share of one core.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
set +u; source build/devel/setup.bash; set -u
tmp=$(mktemp -d)
run() {
  roslaunch backlash_servo backlash_servo.launch config:="$PWD/config/thesis_limit_cycle.yaml" record:=true \
    bag_dir:="$tmp" "$@" 2>&1 | grep -E "achieved real-time factor" | sed 's/.*backlash_servo_node: //; s/\x1b\[[0-9;]*m//g'
}
echo "== node is the clock, as fast as possible (2000 s of sim time), recording all topics"
for rate in 100 1000; do
  echo -n "publish_rate $rate Hz: "
  run publish_clock:=true real_time_factor:=0 publish_rate:=$rate stop_after:=2000
done
echo "== real time (wall clock), 1 kHz, 20 s, recording all topics"
echo -n "publish_rate 1000 Hz: "
run publish_clock:=false real_time_factor:=1 publish_rate:=1000 stop_after:=20
rm -rf "$tmp"
