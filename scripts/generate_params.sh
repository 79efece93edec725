#!/usr/bin/env bash
# After a change of the parameter table (src/core/model/param_table.cpp): rebuilds backlash_params and rewrites the files
# that derive from the table (cfg/BacklashServo.cfg, docs/parameters.md).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
make -C build -j"$(nproc)" backlash_params >/dev/null
/usr/bin/python3 scripts/generate_params.py build/devel/lib/backlash_servo/backlash_params
