// Property fuzzing in CI (issue 14): 2000 deterministic cases over the validated envelope and its edges
// (test/fuzz/fuzz_cases.h). Every case: no crash or "no progress", the gap in [0, Δ] to rounding at every event,
// the energy balance closing to 1e-9 of the energy scale, the same final state when the run is cut into 17 pieces,
// a finite state. An impact storm may end at the event budget (counted, allowed). Long runs:
// bash scripts/fuzz_long.sh.
#include <gtest/gtest.h>

#include <map>

#include "fuzz_cases.h"

namespace
{
TEST(Fuzz, TwoThousandCasesKeepEveryProperty)
{
  std::map<std::string, int> counts;
  for (std::uint64_t i = 0; i < 2000; ++i)
  {
    const fuzz::Case c = fuzz::makeCase(2, i);
    const fuzz::Outcome o = fuzz::check(c);
    ++counts[o.klass];
    EXPECT_TRUE(o.klass == "ok" || o.klass == "budget")
        << o.klass << " in case " << i << ": " << o.detail << "\n  backlash_sim " << c.describe();
  }
  for (const auto& kv : counts)
  {
    std::printf("fuzz: %-10s %d\n", kv.first.c_str(), kv.second);
  }
  EXPECT_GT(counts["ok"], 1800);  // the budget ends only a few storms
}
}  // namespace
