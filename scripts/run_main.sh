#!/usr/bin/env bash
# The main job: install, build, then simulate the thesis' limit-cycle case (App. D1) and print a readable summary.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/setup.sh >/dev/null
./build/devel/lib/backlash_servo/backlash_sim --config config/thesis_limit_cycle.yaml "$@"
