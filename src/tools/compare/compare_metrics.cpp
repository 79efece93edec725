#include "compare_metrics.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <thread>

#include "backlash_servo/plant.h"
#include "backlash_servo/simulator.h"

namespace backlash_servo
{
namespace
{
/// Counts impacts and the energy they take.
struct ImpactTally : EventSink
{
  long impacts = 0;
  double energy = 0.0;
  void onEvent(const Event& e) override
  {
    if (e.type == EventType::Impact)
    {
      ++impacts;
      energy += e.impact.energy_loss;
    }
  }
};
}  // namespace

const std::vector<std::string>& metricNames()
{
  static const std::vector<std::string> names = {
      "limit_cycle_error", "period",        "peak_to_peak",       "cycle_centre",
      "steady_error",      "settling_time", "rms_error",          "steady_rms_error",
      "max_error",         "overshoot",     "impacts_per_second", "impact_energy_per_second",
      "peak_torque",       "rms_torque"};
  return names;
}

std::vector<double> metricValues(const CompareMetrics& m)
{
  return {m.limit_cycle_error, m.period,        m.peak_to_peak,       m.cycle_centre,
          m.steady_error,      m.settling_time, m.rms_error,          m.steady_rms_error,
          m.max_error,         m.overshoot,     m.impacts_per_second, m.impact_energy_per_second,
          m.peak_torque,       m.rms_torque};
}

CompareMetrics runStrategy(const std::string& name, const RunConfig& config, double sample_rate,
                           std::vector<CompareSample>* trajectory)
{
  const CommandProfile& profile = *config.profile;
  const double final_ref = profile.finalValue();
  const double profile_end = profile.endTime();
  // Excursion of the reference (for the 2 % band) and the direction of its last move (for the overshoot).
  double lo = profile.at(0.0), hi = lo;
  const double dt = 1.0 / sample_rate;
  const long n = static_cast<long>(std::floor(config.duration * sample_rate + 1e-9));
  for (long k = 0; k <= n; ++k)
  {
    const double r = profile.at(config.initial.time + k * dt);
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  const double band = settlingBand(config, hi - lo);
  const double before_end = profile.at(std::max(0.0, profile_end - 1e-9));
  double direction = final_ref >= before_end ? 1.0 : -1.0;
  if (final_ref == before_end)
  {
    direction = final_ref >= profile.at(0.0) ? 1.0 : -1.0;
  }
  // The chart keeps every stride-th sample: at most kMaxChartSamples per strategy whatever the sample rate.
  const long chart_stride = std::max(1L, (n + kMaxChartSamples) / kMaxChartSamples);
  double sum_e2 = 0.0, sum_t2 = 0.0, peak = 0.0, max_after = 0.0, overshoot = 0.0, last_outside = NAN;
  long count = 0;
  std::vector<std::pair<double, double>> after;  // (t, e) from the profile's end on: the steady-state window
  ImpactTally tally;
  const RunSummary r = runResponse(config, &tally, dt, [&](const Simulator& sim) {
    const State& s = sim.state();
    const double ref = profile.at(s.time);
    const double e = ref - s.load_position;
    const double tm = sim.motorTorque();
    sum_e2 += e * e;
    sum_t2 += tm * tm;
    peak = std::max(peak, std::fabs(tm));
    ++count;
    if (s.time >= profile_end)
    {
      after.emplace_back(s.time, e);
      max_after = std::max(max_after, std::fabs(e));
      overshoot = std::max(overshoot, direction * (s.load_position - final_ref));
      if (std::fabs(e) > band)
      {
        last_outside = s.time;
      }
    }
    if (trajectory != nullptr && (count - 1) % chart_stride == 0)
    {
      trajectory->push_back({s.time, ref, s.load_position, s.motor_position, tm});
    }
  });
  CompareMetrics m;
  m.name = name;
  m.verdict = toString(r.status.verdict);
  const bool sustained = r.status.verdict == Verdict::LimitCycle || r.status.verdict == Verdict::Irregular;
  if (sustained)
  {
    m.limit_cycle_error = r.status.error;
    m.period = r.status.period;
    m.peak_to_peak = r.cycle.peak_to_peak;
    m.cycle_centre = r.cycle.centre;
  }
  if (r.status.verdict == Verdict::Converged)
  {
    m.steady_error = r.final_state.load_position - final_ref;
  }
  const double simulated = std::max(r.simulated, 1e-300);
  if (count > 0)
  {
    m.rms_error = std::sqrt(sum_e2 / count);
    m.rms_torque = std::sqrt(sum_t2 / count);
    m.peak_torque = peak;
    m.max_error = max_after;
    m.overshoot = overshoot;
  }
  // Settled: inside the band from some time on (never left it at the end of the run).
  m.settling_time = std::isnan(last_outside) ? profile_end : last_outside;
  if (!std::isnan(last_outside) && last_outside >= config.initial.time + r.simulated - 1.5 * dt)
  {
    m.settling_time = NAN;  // still outside at the end
  }
  m.impacts_per_second = tally.impacts / simulated;
  m.impact_energy_per_second = tally.energy / simulated;
  // The steady state after the transient: from the settling time on; a run that never settles, over the second half
  // of what follows the profile (a limit cycle's own error, not the step's).
  if (!after.empty())
  {
    const double from = !std::isnan(m.settling_time)
                            ? m.settling_time
                            : after.front().first + 0.5 * (after.back().first - after.front().first);
    double sum = 0.0;
    long k = 0;
    for (const auto& [t, e] : after)
    {
      if (t >= from)
      {
        sum += e * e;
        ++k;
      }
    }
    m.steady_rms_error = k > 0 ? std::sqrt(sum / k) : NAN;
  }
  m.settling_band = band;
  return m;
}

StrategyRuns runStrategies(const std::vector<CompareStrategy>& strategies, double sample_rate, int jobs,
                           bool trajectories, const std::function<void(std::size_t, std::size_t)>& on_done)
{
  const std::size_t n = strategies.size();
  StrategyRuns out;
  out.metrics.resize(n);
  out.trajectories.resize(n);
  out.errors.resize(n);
  std::atomic<std::size_t> next{0};
  std::size_t done = 0;
  std::mutex done_mutex;
  auto worker = [&]() {
    for (std::size_t i = next++; i < n; i = next++)
    {
      const CompareStrategy& s = strategies[i];
      try
      {
        out.metrics[i] = runStrategy(s.name, s.config, sample_rate, trajectories ? &out.trajectories[i] : nullptr);
      }
      catch (const std::exception& e)
      {
        out.errors[i] = e.what();
      }
      std::lock_guard<std::mutex> lock(done_mutex);
      if (on_done)
      {
        on_done(++done, n);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int j = 0; j < std::min<int>(jobs, static_cast<int>(n)); ++j)
  {
    pool.emplace_back(worker);
  }
  for (std::thread& t : pool)
  {
    t.join();
  }
  return out;
}

}  // namespace backlash_servo
