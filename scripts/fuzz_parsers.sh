#!/usr/bin/env bash
# Coverage-guided fuzzing of the YAML/flag parsers and a short run of what they accept (test/fuzz/parser_fuzzer.cpp,
# clang + libFuzzer + ASan/UBSan). Builds build/libfuzzer, seeds a corpus from the shipped configs, fuzzes for
# SECONDS (default 600) and exits non-zero on a finding (the crashing input is written as crash-*).
# usage: bash scripts/fuzz_parsers.sh [SECONDS] [JUNIT.xml]
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH=/usr/bin:$PATH
seconds=${1:-600}
junit=${2:-}
mkdir -p build/libfuzzer/devel/lib/python3/dist-packages
cmake -S . -B build/libfuzzer -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DBACKLASH_LIBFUZZER=ON >/dev/null && make -C build/libfuzzer -j"$(nproc)" backlash_parser_fuzzer >/dev/null || {
  echo "fuzz_parsers: the libFuzzer build failed"
  [ -n "$junit" ] && echo '<testsuite tests="1" failures="1"><testcase name="libfuzzer_build"><failure/></testcase></testsuite>' >"$junit"
  exit 1
}
corpus=build/libfuzzer/corpus
mkdir -p "$corpus"
# Seeds: every shipped YAML under each parser's selector byte (0 run, 1 compare, 2 profile, 3 flags).
i=0
for f in config/*.yaml test/ros/*.yaml; do
  for sel in 0 1 2; do printf "\\x0$sel" | cat - "$f" >"$corpus/seed_${i}_$sel"; done
  i=$((i + 1))
done
printf '\x03--zeta 0.4 --inertia-ratio 9 --friction-ratio 0.4 --controller-rate 1000 --control-law pid' >"$corpus/seed_flags"
printf '\x02- ramp: {time: 0, target: 1, duration: 2}\n- sine: {time: 3, amplitude: 0.1, frequency: 2, duration: 1}' \
  >"$corpus/seed_profile"
log=build/libfuzzer/fuzz.log
( cd build/libfuzzer && ASAN_OPTIONS=detect_leaks=0 ./devel/lib/backlash_servo/backlash_parser_fuzzer corpus \
    -max_total_time="$seconds" -max_len=4096 -timeout=20 -rss_limit_mb=4096 -print_final_stats=1 ) >"$log" 2>&1
rc=$?
grep -E "stat::number_of_executed_units|stat::new_units_added|cov:" "$log" | tail -n 3
if [ $rc -ne 0 ]; then
  tail -n 40 "$log"
  echo "fuzz_parsers: finding (see $log and build/libfuzzer/crash-*)"
fi
if [ -n "$junit" ]; then
  if [ $rc -eq 0 ]; then
    echo '<testsuite tests="1" failures="0"><testcase name="libfuzzer_parsers"/></testsuite>' >"$junit"
  else
    echo '<testsuite tests="1" failures="1"><testcase name="libfuzzer_parsers"><failure/></testcase></testsuite>' >"$junit"
  fi
fi
exit $rc
