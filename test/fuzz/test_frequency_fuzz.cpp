// Property fuzzing of the frequency tools in CI: stepped-sine points and broadband measurements on joints drawn by
// fuzz_cases.h (rigid, and compliant with damped contacts; continuous and digital drives), at amplitudes and
// frequencies far beyond any sensible measurement (1e-8 … 1e12 rad/s). Every request is refused up front with InvalidParameterError naming a
// key, or answered within PER_CASE_SECONDS of wall time (an impact storm's event budget and a divergence are answers
// too); nothing else is thrown, and a periodic point's figures are finite. The corpus is fixed (seeds below): each
// request that once failed stays in it.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <string>

#include "backlash_servo/frequency/broadband_response.h"
#include "backlash_servo/frequency/frequency_response.h"
#include "fuzz_cases.h"

namespace
{
using namespace backlash_servo;

constexpr double PER_CASE_SECONDS = 90.0;

/// One frequency request: the joint of a fuzz case, and how it is measured.
struct FrequencyCase
{
  RunConfig config;
  std::string joint;  ///< the joint as backlash_sim flags
  FrfChannel channel = FrfChannel::CommandToLoadPosition;
  double amplitude = 0.0, frequency = 0.0;  ///< [rad or N·m], [rad/s]
  bool broadband = false;
  BroadbandKind kind = BroadbandKind::Prbs;
  std::string describe() const
  {
    std::ostringstream o;
    o.precision(17);
    o << joint << " --channel " << toString(channel) << " --amplitude " << amplitude;
    if (broadband)
    {
      o << " --excitation " << (kind == BroadbandKind::Prbs ? "prbs" : "chirp");
    }
    else
    {
      o << " --frequency " << frequency;
    }
    return o.str();
  }
};

FrequencyCase makeFrequencyCase(std::uint64_t seed, std::uint64_t index)
{
  std::mt19937_64 rng(seed * 0xD1B54A32D192ED03ull + index * 6151 + 5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto logu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u(rng)); };
  const fuzz::Case c = u(rng) < 0.3 ? fuzz::makeDampedCompliantCase(seed, index) : fuzz::makeCase(seed, index);
  FrequencyCase f;
  f.config.params = c.params;
  f.config.drive = c.drive;
  f.config.initial = c.start;
  f.config.command = c.command;
  f.joint = c.describe();
  const FrfChannel channels[] = {FrfChannel::CommandToLoadPosition,  FrfChannel::TorqueToMotorVelocity,
                                 FrfChannel::TorqueToLoadVelocity,   FrfChannel::SetpointToMotorVelocity,
                                 FrfChannel::SetpointToLoadVelocity, FrfChannel::LoadTorqueToLoadPosition};
  f.channel = channels[static_cast<int>(u(rng) * 6.0) % 6];
  f.amplitude = logu(1e-6, 1e3);
  f.frequency = logu(1e-8, 1e12);
  f.broadband = u(rng) < 0.25;
  f.kind = u(rng) < 0.5 ? BroadbandKind::Prbs : BroadbandKind::Chirp;
  return f;
}

/// "refused", "answered", "budget", "diverged", or a failure class with what happened.
std::string outcomeOf(const FrequencyCase& f, std::string* detail)
{
  try
  {
    if (f.broadband)
    {
      BroadbandSettings s;
      s.channel = f.channel;
      s.kind = f.kind;
      s.prbs_order = 8;
      s.chirp_samples = 1024;
      const double rate = excitationRate(f.config, f.channel, 0.0);
      s.chirp_low = 0.01 * 2.0 * 3.141592653589793 * rate;
      s.chirp_high = 0.25 * 2.0 * 3.141592653589793 * rate;
      s.periods = 2;
      measureBroadband(f.config, s, f.amplitude);
      return "answered";
    }
    FrfSettings s;
    s.channel = f.channel;
    frfSampling(f.config, s, f.frequency);
    const FrfPoint p = measureFrequencyResponse(f.config, s, f.amplitude, f.frequency);
    if (p.periodic && !(std::isfinite(p.gain) && std::isfinite(p.phase)))
    {
      *detail = "a periodic point with gain " + std::to_string(p.gain) + ", phase " + std::to_string(p.phase);
      return "nonfinite";
    }
    return "answered";
  }
  catch (const InvalidParameterError& e)
  {
    *detail = e.what();
    return "refused";
  }
  catch (const EventBudgetExceeded& e)
  {
    *detail = e.what();
    return "budget";
  }
  catch (const MotionDiverged& e)
  {
    *detail = e.what();
    return "diverged";
  }
  catch (const std::exception& e)
  {
    *detail = e.what();
    return "exception";
  }
}
}  // namespace

TEST(FrequencyFuzz, EveryRequestIsRefusedOrAnsweredInBoundedTime)
{
  const int n = 48;
  std::map<std::string, int> counts;
  double slowest = 0.0;
  for (int i = 0; i < n; ++i)
  {
    const FrequencyCase f = makeFrequencyCase(7, static_cast<std::uint64_t>(i));
    std::string detail;
    const auto start = std::chrono::steady_clock::now();
    const std::string outcome = outcomeOf(f, &detail);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    slowest = std::max(slowest, seconds);
    ++counts[outcome];
    EXPECT_TRUE(outcome == "refused" || outcome == "answered" || outcome == "budget" || outcome == "diverged")
        << outcome << " in case " << i << ": " << detail << "\n  backlash_frf " << f.describe();
    EXPECT_LT(seconds, PER_CASE_SECONDS) << "case " << i << ": backlash_frf " << f.describe();
    if (outcome == "refused")
    {
      // A refusal names the key it is about, first.
      EXPECT_NE(detail.find(": "), std::string::npos) << detail;
    }
  }
  for (const auto& kv : counts)
  {
    std::printf("frequency fuzz: %-10s %d\n", kv.first.c_str(), kv.second);
  }
  std::printf("frequency fuzz: slowest case %.2f s\n", slowest);
  EXPECT_GT(counts["answered"], n / 5);
}
