#include "backlash_servo/limit_cycle_prediction.h"

#include <cmath>

#include "backlash_servo/params.h"
#include "backlash_servo/simulator.h"

namespace backlash_servo
{
namespace
{
constexpr double PI = 3.14159265358979323846;
constexpr int CYCLE_SAMPLES = 4096;
}  // namespace

double LimitCyclePrediction::amplitudeError(const HarmonicBalance& h) const
{
  const bool cycle = simulated.verdict == Verdict::LimitCycle && std::isfinite(simulated.amplitude);
  return cycle && h.stable ? h.amplitude / simulated.amplitude - 1.0 : NAN;
}

double LimitCyclePrediction::frequencyError(const HarmonicBalance& h) const
{
  const bool cycle = simulated.verdict == Verdict::LimitCycle && std::isfinite(simulated.amplitude);
  return cycle && h.stable ? h.frequency / simulated.frequency - 1.0 : NAN;
}

std::complex<double> thesisLoop(const ServoParams& p, double w)
{
  const double wn = p.naturalFrequency(), zeta = p.dampingRatio();
  return wn * wn / std::complex<double>(-w * w, 2.0 * zeta * wn * w);
}

SimulatedCycle simulateCycle(const RunConfig& config)
{
  SimulatedCycle c;
  RunConfig run = config;
  run.track_energy = false;
  const RunSummary r = runResponse(run);
  c.verdict = r.status.verdict;
  c.simulated = r.simulated;
  if (r.status.verdict != Verdict::LimitCycle || !(r.status.period > 0.0))
  {
    return c;
  }
  // One more period from the settled state, sampled evenly: the continuous law's state is the plant's.
  const double period = r.status.period, rho = config.params.gear_ratio;
  Simulator sim(config.params, r.final_state, config.command);
  const double t0 = r.final_state.time;
  std::vector<double> x(CYCLE_SAMPLES);
  for (int k = 0; k < CYCLE_SAMPLES; ++k)
  {
    sim.advanceTo(t0 + period * k / CYCLE_SAMPLES);
    x[static_cast<std::size_t>(k)] = rho * sim.state().motor_position;
  }
  double mean = 0.0, b1 = 0.0, a1 = 0.0;
  for (int k = 0; k < CYCLE_SAMPLES; ++k)
  {
    const double theta = 2.0 * PI * k / CYCLE_SAMPLES, v = x[static_cast<std::size_t>(k)];
    mean += v;
    b1 += v * std::sin(theta);
    a1 += v * std::cos(theta);
  }
  c.centre = mean / CYCLE_SAMPLES;
  c.amplitude = 2.0 / CYCLE_SAMPLES * std::hypot(a1, b1);
  c.peak = 0.0;
  for (double v : x)
  {
    c.peak = std::max(c.peak, std::fabs(v - c.centre));
  }
  c.frequency = 2.0 * PI / period;
  return c;
}

LimitCyclePrediction predictLimitCycle(const RunConfig& config)
{
  if (!config.drive.thesisLaw() || config.profile)
  {
    throw InvalidParameterError("controller_rate",
                                "the describing-function analysis takes the continuous P law with a constant command "
                                "(no controller_rate, torque_limit, compensation or profile)");
  }
  const ServoParams& p = config.params;
  if (!(p.backlash > 0.0))
  {
    throw InvalidParameterError("backlash", "must be > 0: without backlash there is no describing function to balance");
  }
  LimitCyclePrediction out;
  out.zeta = p.dampingRatio();
  out.natural_frequency = p.naturalFrequency();
  const double wn = out.natural_frequency;
  out.predictions =
      backlashHarmonicBalance([&p](double w) { return thesisLoop(p, w); }, p.backlash, 1e-4 * wn, 1e4 * wn);
  out.simulated = simulateCycle(config);
  return out;
}

}  // namespace backlash_servo
