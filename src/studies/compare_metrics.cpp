#include "backlash_servo/studies/compare_metrics.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <thread>

#include "backlash_servo/plant/plant.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/steady_state.h"
#include "backlash_servo/simulation/tracking_metrics.h"

namespace backlash_servo
{
namespace
{
/// Counts impacts and the energy they take, and a compliant mesh's contact phases begun.
struct ImpactTally : EventSink
{
  long impacts = 0;
  long engagements = 0;
  double energy = 0.0;
  void onEvent(const Event& e) override
  {
    if (e.type == EventType::Impact)
    {
      ++impacts;
      energy += e.impact.energy_loss;
    }
    else if (e.type == EventType::Engagement)
    {
      ++engagements;
    }
  }
};

/// Thrown out of a run-on that used up its wall-time budget.
struct OutOfTime
{
  double simulated;  ///< where the run-on stood [s]
};

/// m's run-on figures: config run from its start until its verdict settles, without samples; capped by max_duration
/// when set, else by the shorter of a run until settled's own cap and RUN_ON_FACTOR × the duration; stopped after
/// `budget` of wall time.
void runOn(const RunConfig& config, std::chrono::duration<double> budget, CompareMetrics* m)
{
  RunConfig on = config;
  on.duration = 0.0;
  if (!(config.max_duration > 0.0))
  {
    on.max_duration = std::min(steadyBudget(config.params, config.drive), RUN_ON_FACTOR * config.duration);
  }
  on.tracking = false;
  const auto start = std::chrono::steady_clock::now();
  try
  {
    const RunSummary r = runResponse(on, nullptr, 0.0, nullptr, [&](double done) {
      if (std::chrono::steady_clock::now() - start > budget)
      {
        throw OutOfTime{done * on.max_duration};
      }
    });
    m->run_on_verdict = toString(r.status.verdict);
    m->run_on_time = r.simulated;
    m->run_on_stopped_by = r.stopped_by;
  }
  catch (const OutOfTime& stop)
  {
    m->run_on_verdict = "undecided";
    m->run_on_time = stop.simulated;
    m->run_on_stopped_by = "wall_time";
  }
}
}  // namespace

const std::vector<std::string>& metricNames()
{
  static const std::vector<std::string> names = {
      "limit_cycle_error",        "period",       "peak_to_peak",  "cycle_centre",
      "peak_to_peak_counts",      "steady_error", "settling_time", "rms_error",
      "steady_rms_error",         "max_error",    "overshoot",     "impacts_per_second",
      "impact_energy_per_second", "peak_torque",  "rms_torque"};
  return names;
}

std::vector<double> metricValues(const CompareMetrics& m)
{
  return {m.limit_cycle_error,        m.period,       m.peak_to_peak,  m.cycle_centre,
          m.peak_to_peak_counts,      m.steady_error, m.settling_time, m.rms_error,
          m.steady_rms_error,         m.max_error,    m.overshoot,     m.impacts_per_second,
          m.impact_energy_per_second, m.peak_torque,  m.rms_torque};
}

CompareMetrics runStrategy(const std::string& name, const RunConfig& config, double sample_rate,
                           std::vector<CompareSample>* trajectory)
{
  const CommandProfile& profile = *config.profile;
  const double final_ref = profile.finalValue();
  const double dt = 1.0 / sample_rate;
  const long n = static_cast<long>(std::floor(config.duration * sample_rate + 1e-9));
  TrackingMetrics tracking = trackingOf(config, dt, config.initial.time + config.duration);
  const double band = tracking.band();
  // The chart keeps every stride-th sample: at most kMaxChartSamples per strategy whatever the sample rate.
  const long chart_stride = std::max(1L, (n + kMaxChartSamples) / kMaxChartSamples);
  long count = 0;
  ImpactTally tally;
  const auto start = std::chrono::steady_clock::now();
  const RunSummary r = runResponse(config, &tally, dt, [&](const Simulator& sim) {
    const State& s = sim.state();
    const double ref = profile.at(s.time);
    const double tm = sim.motorTorque();
    tracking.add(s.time, ref, s.load_position, tm);
    if (trajectory != nullptr && count % chart_stride == 0)
    {
      trajectory->push_back({s.time, ref, s.load_position, s.motor_position, tm});
    }
    ++count;
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
    m.peak_to_peak_counts = r.resolution.counts;
  }
  m.steady_error = r.steady.error;
  const double simulated = std::max(r.simulated, 1e-300);
  const TrackingFigures f =
      tracking.figures(config.initial.time + r.simulated, dt, cycleLeavesBand(r.status, r.cycle, final_ref, band));
  m.settling_time = f.settling_time;
  m.rms_error = f.rms_error;
  m.steady_rms_error = f.steady_rms_error;
  m.max_error = f.max_error;
  m.overshoot = f.overshoot;
  m.peak_torque = f.peak_torque;
  m.rms_torque = f.rms_torque;
  // A compliant mesh has contact phases instead of impacts, and its losses (damping, the jumps of stored energy at
  // releases) instead of the impacts' kinetic energy.
  const bool compliant = config.params.compliant();
  m.impacts_per_second = (compliant ? tally.engagements : tally.impacts) / simulated;
  m.impact_energy_per_second = (compliant ? r.energy.mesh_loss : tally.energy) / simulated;
  m.settling_band = band;
  if (r.status.verdict == Verdict::Undecided && r.stopped_by == "duration")
  {
    const std::chrono::duration<double> own = std::chrono::steady_clock::now() - start;
    runOn(config, std::max(RUN_ON_WALL_FACTOR * own, std::chrono::duration<double>(RUN_ON_LEAST_WALL)), &m);
  }
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
