#!/usr/bin/env bash
# Node throughput and CPU (issue figures; a benchmark, not a test). Prints the node's own measurement lines:
#  1. node is the clock, real_time_factor 0 (as fast as possible), 100 Hz and 1 kHz, recording its own bag;
#  2. real time (wall clock, factor 1) at 1 kHz for 20 s: the node's CPU share of one core, recording its own bag
#     (record:=true), recorded by a separate process (backlash_record: its CPU too), and not recorded.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
set +u; source build/devel/setup.bash; set -u
tmp=$(mktemp -d)
clean() { sed 's/.*backlash_servo_node: //; s/\x1b\[[0-9;]*m//g'; }
run() {
  roslaunch backlash_servo backlash_servo.launch config:="$PWD/config/thesis_limit_cycle.yaml" bag_dir:="$tmp" "$@" \
    2>&1 | grep -E "achieved real-time factor" | clean
}
external() {
  roslaunch "$PWD/bench/node_external_recorder.launch" bag:="$tmp/external.bag" "$@" 2>&1 |
    grep -E "achieved real-time factor|backlash_record: wrote" | clean | sed 's/^/  /'
}
echo "== node is the clock, as fast as possible (2000 s of sim time)"
for rate in 100 1000; do
  echo -n "publish_rate $rate Hz, recording its own bag: "
  run record:=true publish_clock:=true real_time_factor:=0 publish_rate:=$rate stop_after:=2000
  echo "publish_rate $rate Hz, recorded by a separate process (backlash_record):"
  external publish_clock:=true real_time_factor:=0 publish_rate:=$rate stop_after:=2000
done
echo "== real time (wall clock), 1 kHz, 20 s"
echo -n "recording its own bag (record:=true): "
run record:=true publish_clock:=false real_time_factor:=1 publish_rate:=1000 stop_after:=20
echo "recorded by a separate process (backlash_record):"
external
echo -n "not recorded: "
run record:=false publish_clock:=false real_time_factor:=1 publish_rate:=1000 stop_after:=20
rm -rf "$tmp"
