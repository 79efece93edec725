// Tolerance studies: the draws against their distributions' moments, the batch summary against brute-force figures.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/studies/monte_carlo.h"

using namespace backlash_servo;

namespace
{
std::vector<double> draws(const std::string& key, const std::string& text, std::uint64_t seed, std::size_t n)
{
  const Distribution d = parseDistribution(key, text);
  std::vector<double> v;
  for (std::size_t i = 0; i < n; ++i)
  {
    v.push_back(drawValue(d, seed, i));
  }
  return v;
}

double mean(const std::vector<double>& v)
{
  double s = 0.0;
  for (double x : v)
  {
    s += x;
  }
  return s / static_cast<double>(v.size());
}

double sd(const std::vector<double>& v)
{
  const double m = mean(v);
  double s = 0.0;
  for (double x : v)
  {
    s += (x - m) * (x - m);
  }
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}
}  // namespace

// Each distribution's draws have its moments (within 5 standard errors of 20 000 draws), are the same for the same
// (seed, point, key) and independent across keys and seeds; a distribution reaching below a key's range is truncated
// there: normal(0, 1) on the backlash (≥ 0) is the half-normal, mean √(2/π).
TEST(MonteCarlo, DrawsFollowTheirDistributions)
{
  const std::size_t n = 20000;
  const double se = 1.0 / std::sqrt(static_cast<double>(n));
  const auto u = draws("backlash", "uniform(0.002,0.006)", 7, n);
  EXPECT_TRUE(std::all_of(u.begin(), u.end(), [](double x) { return x >= 0.002 && x <= 0.006; }));
  EXPECT_NEAR(mean(u), 0.004, 5.0 * 0.004 / std::sqrt(12.0) * se);
  EXPECT_NEAR(sd(u), 0.004 / std::sqrt(12.0), 0.02 * 0.004 / std::sqrt(12.0));
  const auto g = draws("load_torque", "normal(-3.5,0.2)", 7, n);
  EXPECT_NEAR(mean(g), -3.5, 5.0 * 0.2 * se);
  EXPECT_NEAR(sd(g), 0.2, 0.02 * 0.2);
  const auto l = draws("load_inertia", "lognormal(-2,0.3)", 7, n);
  std::vector<double> logs;
  for (double x : l)
  {
    logs.push_back(std::log(x));
  }
  EXPECT_NEAR(mean(logs), -2.0, 5.0 * 0.3 * se);
  EXPECT_NEAR(sd(logs), 0.3, 0.02 * 0.3);
  const auto h = draws("backlash", "normal(0,1)", 7, n);
  EXPECT_TRUE(std::all_of(h.begin(), h.end(), [](double x) { return x >= 0.0; }));
  EXPECT_NEAR(mean(h), std::sqrt(2.0 / M_PI), 5.0 * std::sqrt(1.0 - 2.0 / M_PI) * se);
  // Reproducible, and independent across keys and seeds (the correlation of the uniforms within 5/√n of 0).
  EXPECT_EQ(u, draws("backlash", "uniform(0.002,0.006)", 7, n));
  const auto other_key = draws("restitution", "uniform(0.002,0.006)", 7, n);
  const auto other_seed = draws("backlash", "uniform(0.002,0.006)", 8, n);
  for (const auto* w : {&other_key, &other_seed})
  {
    double sxy = 0.0;
    for (std::size_t i = 0; i < n; ++i)
    {
      sxy += (u[i] - 0.004) * ((*w)[i] - 0.004);
    }
    EXPECT_LT(std::fabs(sxy / static_cast<double>(n) / (0.004 * 0.004 / 12.0)), 5.0 * se);
  }
}

// A malformed or impossible distribution is one error naming the key and the text.
TEST(MonteCarlo, RefusesBadDistributions)
{
  for (const char* bad : {"uniform(1,2", "uniform(1)", "uniform(2,1)", "uniform(-1,1)", "normal(0,0)", "normal(0,-1)",
                          "lognormal(nan,1)", "gamma(1,2)", "uniform(a,b)"})
  {
    try
    {
      parseDistribution("backlash", bad);
      ADD_FAILURE() << bad;
    }
    catch (const ConfigError& e)
    {
      EXPECT_NE(std::string(e.what()).find("--backlash '" + std::string(bad) + "'"), std::string::npos) << e.what();
    }
  }
  // Mostly outside the range: 1000 redraws fail, said with the key.
  EXPECT_THROW(drawValue(parseDistribution("backlash", "normal(-100,1)"), 1, 0), ConfigError);
  EXPECT_FALSE(isDistributionText("0.1,0.2"));
  EXPECT_TRUE(isDistributionText("lognormal(0,1)"));
}

// The summary of a batch written here: verdict shares with the Wilson interval found by bisection on its defining
// inequality |p̂ − p| ≤ z √(p(1 − p)/n), quantiles of the hunting joints, Spearman's correlation from its
// definition (1 − 6Σd²/(n(n² − 1)) without ties) and the best split by trying every threshold.
TEST(MonteCarlo, SummaryAgreesWithBruteForce)
{
  std::ostringstream csv;
  csv << "backlash,zeta,verdict,limit_cycle,limit_cycle_error,period,peak_to_peak\n";
  const int n = 40;
  std::vector<double> key, hunts;
  for (int i = 0; i < n; ++i)
  {
    const double b = 0.001 * ((i * 17) % n + 1);  // distinct, shuffled
    const double z = 0.1 + 0.01 * ((i * 7) % n);
    const bool hunting = b > 0.012 && i % 9 != 0;  // mostly by the backlash, with exceptions
    csv << b << "," << z << "," << (hunting ? "limit_cycle" : "converged") << "," << hunting << ",,"
        << (hunting ? std::to_string(1.0 + i) : "") << "," << (hunting ? std::to_string(0.01 * i) : "") << "\n";
    key.push_back(b);
    hunts.push_back(hunting ? 1.0 : 0.0);
  }
  const MonteCarloSummary s = summarizeBatch(csv.str(), {"zeta", "backlash"});
  ASSERT_EQ(s.joints, 40u);
  ASSERT_EQ(s.verdicts.size(), 2u);
  for (const auto& v : s.verdicts)
  {
    const double p_hat = static_cast<double>(v.count) / n, z = 1.959963984540054;
    const auto outside = [&](double p) { return std::fabs(p_hat - p) > z * std::sqrt(p * (1.0 - p) / n); };
    const auto edge = [&](double inside, double out) {
      for (int k = 0; k < 200; ++k)
      {
        const double mid = 0.5 * (inside + out);
        (outside(mid) ? out : inside) = mid;
      }
      return inside;
    };
    EXPECT_NEAR(v.low, edge(p_hat, 0.0), 1e-12) << v.verdict;
    EXPECT_NEAR(v.high, edge(p_hat, 1.0), 1e-12) << v.verdict;
  }
  // Spearman from its definition: the backlash has distinct values; the hunts' ties take mid-ranks, so compare with
  // Pearson's correlation of the ranks computed here.
  std::vector<double> rk(n), rh(n);
  for (int i = 0; i < n; ++i)
  {
    int below = 0, equal = 0;
    for (int j = 0; j < n; ++j)
    {
      below += key[j] < key[i];
      equal += hunts[j] == hunts[i] && j != i;
    }
    rk[i] = below + 1;
    int hb = 0;
    for (int j = 0; j < n; ++j)
    {
      hb += hunts[j] < hunts[i];
    }
    rh[i] = hb + 1 + 0.5 * equal;
  }
  const double mk = mean(rk), mh = mean(rh);
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (int i = 0; i < n; ++i)
  {
    sxy += (rk[i] - mk) * (rh[i] - mh);
    sxx += (rk[i] - mk) * (rk[i] - mk);
    syy += (rh[i] - mh) * (rh[i] - mh);
  }
  ASSERT_EQ(s.influences.front().key, "backlash");  // the stronger one first
  EXPECT_NEAR(s.influences.front().rank_correlation, sxy / std::sqrt(sxx * syy), 1e-12);
  // Every threshold tried: the best rule's accuracy.
  double best = 0.0;
  for (double t : key)
  {
    int right = 0;
    for (int i = 0; i < n; ++i)
    {
      right += (key[i] > t) == (hunts[i] > 0.5);
    }
    best = std::max(best, static_cast<double>(right) / n);
  }
  EXPECT_DOUBLE_EQ(s.influences.front().accuracy, best);
  EXPECT_TRUE(s.influences.front().above);
  // The hunting joints' median period: sorted by hand.
  std::vector<double> periods;
  for (int i = 0; i < n; ++i)
  {
    if (hunts[i] > 0.5)
    {
      periods.push_back(1.0 + i);
    }
  }
  std::sort(periods.begin(), periods.end());
  const double median = periods.size() % 2 == 1 ? periods[periods.size() / 2]
                                                : 0.5 * (periods[periods.size() / 2 - 1] + periods[periods.size() / 2]);
  EXPECT_NEAR(s.period_quantiles[2], median, 1e-9);
  EXPECT_EQ(s.hunting, periods.size());
}
