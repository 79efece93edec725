#!/usr/bin/env bash
# Installs, builds and runs every test (gtest on the core and tools; rostests when present), then prints the
# totals as the last line: "N passed, N failed". Exit code 0 only when nothing failed.
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
bash scripts/setup.sh || { echo "0 passed, 1 failed"; exit 1; }
rm -rf build/test_results
make -C build -j"$(nproc)" tests || { echo "0 passed, 1 failed"; exit 1; }
make -C build run_tests -j1 2>&1 | tail -n 200
/usr/bin/python3 scripts/count_results.py build/test_results
