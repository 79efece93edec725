#!/usr/bin/env bash
# Installs, builds and runs every test (gtest on the core and tools; rostests when present), then prints the
# totals as the last line: "N passed, N failed". Exit code 0 only when nothing failed.
#
# --quick: the loop for someone changing one file — from an already built tree (bash scripts/run_tests.sh once, or
# make -C build tests), rebuilds what changed, then runs the core's unit tests, the tools' tests, the config and
# golden tests and the Python tests (the layer check among them), two at a time; no setup, no ROS tests, no
# sanitizers, no parser fuzzing. A few minutes on two cores. GTEST_FILTER narrows the gtest part.
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
if [ "${1:-}" = "--quick" ]; then
  bin=build/devel/lib/backlash_servo
  if [ ! -x "$bin/backlash_servo_core_test" ]; then
    echo "no built tree in build/: run bash scripts/run_tests.sh once (it installs and builds)"
    echo "0 passed, 1 failed"
    exit 1
  fi
  make -C build -j"$(nproc)" tests >/dev/null || { echo "build failed"; echo "0 passed, 1 failed"; exit 1; }
  results=build/quick_results
  rm -rf "$results" && mkdir -p "$results"
  set +u
  source build/devel/setup.bash
  set -u
  gtest() {  # binary name
    "$bin/backlash_servo_$1_test" --gtest_output="xml:$results/$1.xml" >"$results/$1.log" 2>&1 ||
      grep -E '^\[  FAILED  \]|Failure' "$results/$1.log" | head -n 20
    # (a binary none of whose tests GTEST_FILTER selects ran nothing: no result to count)
    if [ -n "${GTEST_FILTER:-}" ] && grep -q '<testsuites tests="0"' "$results/$1.xml" 2>/dev/null; then
      rm -f "$results/$1.xml"
    fi
  }
  gtest core &
  (gtest tools; gtest cli; gtest golden; gtest param_table; gtest robot) &
  wait
  /usr/bin/python3 -m pytest -q -p no:cacheprovider test/python --junitxml="$results/pytest.xml" 2>&1 | tail -n 5
  /usr/bin/python3 scripts/count_results.py "$results"
  exit $?
fi
bash scripts/setup.sh || { echo "0 passed, 1 failed"; exit 1; }
rm -rf build/test_results
make -C build -j"$(nproc)" tests || { echo "0 passed, 1 failed"; exit 1; }
# The sanitizer build (used below) compiles meanwhile, at the lowest priority, on the core the plain tests leave idle
# (they run one at a time).
mkdir -p build/sanitize/devel/lib/python3/dist-packages
(cmake -S . -B build/sanitize -DPYTHON_EXECUTABLE=/usr/bin/python3 -DBACKLASH_SANITIZE=ON >/dev/null &&
 nice -n 19 make -C build/sanitize -j1 backlash_servo_core_test backlash_servo_fuzz_test >/dev/null 2>&1) &
sanitize_build=$!
make -C build run_tests -j1 2>&1 | tail -n 200
# The Python API against the tools and the design-study notebook, executed (pytest, Debian's python3).
mkdir -p build/test_results/backlash_servo
(set +u; source build/devel/setup.bash; export PYDEVD_DISABLE_FILE_VALIDATION=1;
 /usr/bin/python3 -m pytest -q -p no:cacheprovider test/python \
   --junitxml=build/test_results/backlash_servo/pytest-python.xml 2>&1 | tail -n 30)
# The core's unit tests and the fuzz sample again under AddressSanitizer + UndefinedBehaviorSanitizer.
if wait "$sanitize_build" &&
   make -C build/sanitize -j"$(nproc)" backlash_servo_core_test backlash_servo_fuzz_test >/dev/null; then
  # Three processes on the machine's cores: the core tests in two shards, the fuzz sample. The compensators'
  # convergence study (8 million samples a run, the same code paths as its 100 kHz runs) is left to the plain build.
  sanitized() {  # name, binary, extra gtest flags…
    local name=$1 bin=$2
    shift 2
    local xml="build/test_results/backlash_servo/gtest-sanitize-${name}.xml"
    if ! ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 \
        "build/sanitize/devel/lib/backlash_servo/backlash_servo_${bin}_test" --gtest_output="xml:$xml" "$@" \
        >"build/sanitize/${name}.log" 2>&1; then
      tail -n 30 "build/sanitize/${name}.log"
      # A sanitizer abort writes no result file: count it as a failure.
      [ -s "$xml" ] || echo "<testsuite tests=\"1\"><testcase name=\"sanitize_${name}\"><failure/></testcase></testsuite>" >"$xml"
    fi
    tail -n 3 "build/sanitize/${name}.log"
  }
  # (Left out here, run in the normal build: long replays whose code the other sanitized tests cover.)
  slow='-Compensation.TheContinuousLawTakesFeedforwardAndSquareDitherExactly:JointFit.MeasuredAnglesFromFineEncoders'
  slow+=':Identification.RestitutionFittedByReplayingWindowsOfTheRecording'
  slow+=':Verdicts.ARandomCompliantJointConvergedOnASettlingMotorNeverMovesAgain'  # (24 joints; the rule: one)
  slow+=':IdentifyMesh.TheJointFitRecoversTheCompliantJoint'  # (the fit: JointFit.*, the mesh: IdentifyMesh.*)
  slow+=':FrequencyResponse.ALoadTorqueSineGivesTheServosDynamicCompliance'  # (the sine: LoadWave.*)
  GTEST_TOTAL_SHARDS=2 GTEST_SHARD_INDEX=0 sanitized core-0 core --gtest_filter="$slow" &
  GTEST_TOTAL_SHARDS=2 GTEST_SHARD_INDEX=1 sanitized core-1 core --gtest_filter="$slow" &
  # (the compliant joint's and the frequency tools' code runs in the core tests; their fuzz here is long under ASan)
  sanitized fuzz fuzz --gtest_filter='-Fuzz.CompliantJoints*:Fuzz.DampedCompliant*:FrequencyFuzz*' &
  wait
else
  echo "sanitizer build failed"
  echo '<testsuite tests="1" failures="1"><testcase name="sanitize_build"><failure/></testcase></testsuite>' \
    >build/test_results/backlash_servo/gtest-sanitize-build.xml
fi
# Coverage-guided fuzzing of every input parser (clang/libFuzzer + ASan/UBSan): kept findings, then 50000 inputs, seed 1.
bash scripts/fuzz_parsers.sh --ci 50000 build/test_results/backlash_servo/libfuzzer-parsers.xml
/usr/bin/python3 scripts/count_results.py build/test_results
