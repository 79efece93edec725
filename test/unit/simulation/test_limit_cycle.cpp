// The verdict on synthetic maxima sequences with known answers.
#include <gtest/gtest.h>

#include <cmath>

#include "backlash_servo/simulation/limit_cycle.h"
#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

using namespace backlash_servo;

namespace
{
LimitCycleDetector feed(double (*x)(int), int n, double period = 10.0)
{
  LimitCycleDetector d(1.0, 0.3);
  for (int i = 0; i < n && !d.settled(); ++i)
  {
    d.addMaximum({period * i, 1.0 + x(i), -0.01});
  }
  return d;
}
}  // namespace

TEST(LimitCycle, GeometricApproachToAFixedPointIsALimitCycle)
{
  const auto d = feed([](int i) { return 0.05 + 0.3 * std::pow(0.6, i); }, 200);
  ASSERT_EQ(d.status().verdict, Verdict::LimitCycle);
  EXPECT_NEAR(d.status().error, 0.05, 1e-6);
  EXPECT_NEAR(d.status().period, 10.0, 1e-12);
  EXPECT_EQ(d.status().multiplicity, 1);
}

TEST(LimitCycle, SlowApproachIsNotDeclaredEarly)
{
  // Ratio 0.97: the maxima differ by ~1e-3 for a long time; the verdict must wait until the fixed point is pinned.
  const auto d = feed([](int i) { return 0.05 + 0.2 * std::pow(0.97, i); }, 2000);
  ASSERT_EQ(d.status().verdict, Verdict::LimitCycle);
  EXPECT_NEAR(d.status().error, 0.05, 1e-6);
}

TEST(LimitCycle, GeometricDecayToTheCommandConverges)
{
  const auto d = feed([](int i) { return 0.3 * std::pow(0.8, i); }, 200);
  EXPECT_EQ(d.status().verdict, Verdict::Converged);
  EXPECT_LT(d.maxima().size(), 20u);  // decided from the trend, not by waiting for zero
}

TEST(LimitCycle, SlowNonGeometricDecayIsNotMistakenForACycle)
{
  // x_n = 0.3/(1 + n/5): decays like 1/n; successive differences shrink, which "average the last few" would call
  // a cycle. No fixed point exists, so no LimitCycle verdict may be given.
  const auto d = feed([](int i) { return 0.3 / (1.0 + i / 5.0); }, 300);
  EXPECT_NE(d.status().verdict, Verdict::LimitCycle);
  EXPECT_NE(d.status().verdict, Verdict::Irregular);
}

TEST(LimitCycle, PeriodTwoCycleIsFoundWithItsMultiplicity)
{
  const auto d = feed([](int i) { return (i % 2 ? 0.04 : 0.07) + 0.1 * std::pow(0.5, i); }, 200, 3.0);
  ASSERT_EQ(d.status().verdict, Verdict::LimitCycle);
  EXPECT_EQ(d.status().multiplicity, 2);
  EXPECT_NEAR(d.status().error, 0.07, 1e-6);
  EXPECT_NEAR(d.status().period, 6.0, 1e-12);
}

TEST(LimitCycle, IrregularSustainedOscillation)
{
  // Bounded, non-decaying, never settling (a quasi-periodic sequence).
  const auto d =
      feed([](int i) { return 0.4 + 0.02 * std::sin(2.0 * i) + 0.01 * std::sin(0.7 * std::sqrt(2.0) * i); }, 400);
  EXPECT_EQ(d.status().verdict, Verdict::Irregular);
  EXPECT_GT(d.status().error, 0.4);
}

TEST(LimitCycle, RestSettlesConvergence)
{
  LimitCycleDetector d(1.0, 0.3);
  d.addMaximum({1.0, 1.2, 0.0});
  EXPECT_FALSE(d.settled());
  d.markAtRest();
  EXPECT_EQ(d.status().verdict, Verdict::Converged);
  d.addMaximum({2.0, 0.9, 0.0});  // below the command: ignored
  EXPECT_EQ(d.maxima().size(), 1u);
}

// A load settling against a flank (or by stiction) under micro-bounces makes maxima of one height piling up at an
// instant, intervals shrinking geometrically: not a limit cycle of period ~0. With a minimum spacing they are one
// hump (its top kept); without it, the period test (a cycle's extrapolated period is near its latest interval)
// still refuses them. (Seen: PID + friction feed-forward on a 1 kHz robot joint, maxima 1e-7 s apart.)
TEST(LimitCycle, MaximaPilingUpAtAnInstantAreNotACycle)
{
  for (const double spacing : {0.0, 1e-3})
  {
    LimitCycleDetector d(1.0, 0.3);
    d.setMinimumSpacing(spacing);
    d.addMaximum({2.0, 1.01, 0.0});
    for (int k = 0; k < 20; ++k)  // (intervals down to 2e-12 s: well above the time resolution at 18.5 s)
    {
      d.addMaximum({18.5 - 7.6e-6 * std::pow(0.45, k), 1.000343 - 5e-11 * std::pow(0.2, k), 0.0});
    }
    EXPECT_NE(d.status().verdict, Verdict::LimitCycle) << spacing << " period " << d.status().period;
    if (spacing > 0.0)
    {
      ASSERT_EQ(d.maxima().size(), 2u);
      EXPECT_EQ(d.maxima().back().position, 1.000343 - 5e-11 * std::pow(0.2, 19));  // the top of the hump
    }
  }
  // A true cycle is unaffected by the spacing.
  LimitCycleDetector cycle(1.0, 0.3);
  cycle.setMinimumSpacing(1e-3);
  for (int i = 0; i < 200 && !cycle.settled(); ++i)
  {
    cycle.addMaximum({10.0 * i, 1.05 + 0.3 * std::pow(0.6, i), -0.01});
  }
  EXPECT_EQ(cycle.status().verdict, Verdict::LimitCycle);
}

namespace
{
RunConfig chartPoint(double zeta, double inertia_ratio, double friction_ratio, double restitution)
{
  RunConfig c;
  c.params = test_helpers::chart(zeta, inertia_ratio, friction_ratio, restitution);
  return c;
}
}  // namespace

// Running until settled, an oscillation stops within 1/16 of a natural period of the maximum that settles it (before:
// at the end of that natural period, up to 2.9 × 10⁵ more impacts of elastic chatter); the motion does not depend on
// where the run stops, so a run of fixed duration past that point passes through the same maxima bit for bit.
TEST(RunUntilSettled, AnOscillationStopsWithinASixteenthPeriodOfItsSettlingMaximum)
{
  const double period = 2.0 * M_PI;                                          // ω_n = 1 rad/s in both cases
  for (const RunConfig& c : {RunConfig(), chartPoint(0.3, 0.04, 1.0, 1.0)})  // App. D1; elastic chatter
  {
    const RunSummary r = runResponse(c);
    ASSERT_EQ(r.status.verdict, Verdict::LimitCycle);
    ASSERT_EQ(r.stopped_by, "settled");
    const double after = r.final_state.time - r.maxima.back().time;  // [s]
    EXPECT_GE(after, 0.0);
    EXPECT_LE(after, period / 16.0 * (1.0 + 1e-12));
    RunConfig fixed = c;
    fixed.duration = r.simulated + period;  // advanced a natural period at a time, no early stop
    const RunSummary f = runResponse(fixed);
    ASSERT_GE(f.maxima.size(), r.maxima.size());
    EXPECT_GE(f.impacts, r.impacts);
    for (std::size_t i = 0; i < r.maxima.size(); ++i)
    {
      EXPECT_EQ(f.maxima[i].time, r.maxima[i].time) << i;
      EXPECT_EQ(f.maxima[i].position, r.maxima[i].position) << i;
      EXPECT_EQ(f.maxima[i].velocity, r.maxima[i].velocity) << i;
    }
  }
}

// A convergence is judged by rest tests made at the end of each natural period, and its steady error is read there:
// such a run still stops at a whole number of periods.
TEST(RunUntilSettled, AConvergenceStopsAtTheEndOfANaturalPeriod)
{
  const RunSummary r = runResponse(chartPoint(0.4, 0.04, 0.2, 0.0));
  ASSERT_EQ(r.status.verdict, Verdict::Converged);
  const double periods = r.simulated / (2.0 * M_PI);
  EXPECT_NEAR(periods, std::round(periods), 1e-9);
}
