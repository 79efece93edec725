#!/usr/bin/env bash
# Coverage-guided fuzzing of every input parser (test/fuzz/parser_fuzzer.cpp: run and compare YAML, profiles as YAML
# and CSV, flags, sweep parts; clang + libFuzzer + ASan/UBSan). Builds build/libfuzzer.
#
#   bash scripts/fuzz_parsers.sh [SECONDS] [JUNIT.xml]   open-ended: fuzzes for SECONDS (default 600) on a corpus
#                                                         kept in build/libfuzzer/corpus between runs
#   bash scripts/fuzz_parsers.sh --ci RUNS [JUNIT.xml]   reproducible (the test command): replays every kept finding
#                                                         in test/fuzz/regressions, then RUNS inputs with seed 1 from
#                                                         a fresh corpus of the shipped configs
# A finding is written as build/libfuzzer/crash-* (or timeout-*, oom-*) and the whole log is printed; keep it as a
# regression input: cp build/libfuzzer/crash-XXX test/fuzz/regressions/<what-it-was>.
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
ci=0
if [ "${1:-}" = "--ci" ]; then
  ci=1
  shift
fi
amount=${1:-600}
junit=${2:-}
result() {
  [ -n "$junit" ] || return 0
  if [ "$2" -eq 0 ]; then
    echo "<testsuite tests=\"1\" failures=\"0\"><testcase name=\"$1\"/></testsuite>" >"$junit"
  else
    echo "<testsuite tests=\"1\" failures=\"1\"><testcase name=\"$1\"><failure/></testcase></testsuite>" >"$junit"
  fi
}
mkdir -p build/libfuzzer/devel/lib/python3/dist-packages
cmake -S . -B build/libfuzzer -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DBACKLASH_LIBFUZZER=ON >/dev/null && make -C build/libfuzzer -j"$(nproc)" backlash_parser_fuzzer >/dev/null || {
  echo "fuzz_parsers: the libFuzzer build failed"
  result libfuzzer_build 1
  exit 1
}
fuzzer=$PWD/build/libfuzzer/devel/lib/backlash_servo/backlash_parser_fuzzer
corpus=build/libfuzzer/corpus
[ $ci -eq 1 ] && corpus=build/libfuzzer/ci_corpus && rm -rf "$corpus"
mkdir -p "$corpus"
# Seeds: every shipped YAML under each YAML parser's selector byte (0 run, 1 compare, 2 profile), flags (3), a
# profile CSV (4) and a sweep part (5).
i=0
for f in config/*.yaml test/ros/*.yaml; do
  for sel in 0 1 2; do printf "\\x0$sel" | cat - "$f" >"$corpus/seed_${i}_$sel"; done
  i=$((i + 1))
done
printf '\x03--zeta 0.4 --inertia-ratio 9 --friction-ratio 0.4 --controller-rate 1000 --control-law pid' >"$corpus/seed_flags"
printf '\x02- ramp: {time: 0, target: 1, duration: 2}\n- sine: {time: 3, amplitude: 0.1, frequency: 2, duration: 1}' \
  >"$corpus/seed_profile"
printf '\x04time,value\n0,0\n0.5,1\n1,-0.25\n2.5,0.1\n' >"$corpus/seed_profile_csv"
printf '\x05# backlash_sweep part 1/1: points [0, 2) of 2, grid 0123456789abcdef\nzeta,inertia_ratio,friction_ratio,restitution,backlash,verdict,limit_cycle,limit_cycle_error,period,impacts,simulated_time,settled,steady_error,maxima_per_period\n0.3,9,0.4,1,0.3,limit_cycle,1,0.05,12.2,23,160.5,1,,1\n0.5,9,0.4,1,0.3,converged,0,0,0,4,80,1,1e-17,0\n' \
  >"$corpus/seed_sweep_part"
log=$PWD/build/libfuzzer/fuzz.log
rm -f "$log" "$log.regressions"
rc=0
if [ $ci -eq 1 ]; then
  # Repeatable: a fixed seed, a fresh corpus, a fixed scratch directory and no address randomisation (yaml-cpp keeps
  # its nodes in a set ordered by address, so coverage would otherwise vary from run to run).
  norand=()
  setarch "$(uname -m)" -R true 2>/dev/null && norand=(setarch "$(uname -m)" -R)
  export BACKLASH_FUZZ_DIR=$PWD/build/libfuzzer/ci_scratch
  rm -rf "$BACKLASH_FUZZ_DIR" && mkdir -p "$BACKLASH_FUZZ_DIR"
  regressions=(test/fuzz/regressions/*)
  ( cd build/libfuzzer && ASAN_OPTIONS=detect_leaks=0 "${norand[@]}" "$fuzzer" "${regressions[@]/#/$OLDPWD/}" ) \
    >"$log.regressions" 2>&1 || {
    rc=$?
    cat "$log.regressions"
    echo "fuzz_parsers: a kept finding fails again (test/fuzz/regressions)"
  }
  echo "fuzz_parsers: ${#regressions[@]} kept findings replayed"
  if [ $rc -eq 0 ]; then
    ( cd build/libfuzzer && ASAN_OPTIONS=detect_leaks=0 "${norand[@]}" "$fuzzer" ci_corpus -seed=1 -runs="$amount" \
        -reload=0 -max_len=4096 -timeout=120 -rss_limit_mb=4096 -print_final_stats=1 ) >"$log" 2>&1 || rc=$?
  fi
else
  export BACKLASH_FUZZ_DIR=$PWD/build/libfuzzer/scratch
  mkdir -p "$BACKLASH_FUZZ_DIR"
  ( cd build/libfuzzer && ASAN_OPTIONS=detect_leaks=0 "$fuzzer" corpus -max_total_time="$amount" -max_len=4096 \
      -timeout=120 -rss_limit_mb=4096 -print_final_stats=1 ) >"$log" 2>&1 || rc=$?
fi
[ -f "$log" ] && grep -E "stat::number_of_executed_units|stat::new_units_added|cov:" "$log" | tail -n 3
if [ $rc -ne 0 ]; then
  [ -f "$log" ] && cat "$log"
  echo "fuzz_parsers: finding (the log above; the input is build/libfuzzer/crash-*, timeout-* or oom-*)"
fi
result libfuzzer_parsers $rc
exit $rc
