#include "backlash_servo/step_response.h"

#include <algorithm>
#include <cmath>

namespace backlash_servo
{
namespace
{
constexpr double PI = 3.14159265358979323846;
/// A quiet servo must be within this fraction of the scale (max(Δ, step)) of its command to count as converged.
constexpr double QUIET_ERROR_FRACTION = 1e-2;

/// Feeds maxima to the detector and forwards every event.
class Watcher : public EventSink
{
 public:
  Watcher(LimitCycleDetector* detector, EventSink* next) : detector_(detector), next_(next) {}
  void onEvent(const Event& e) override
  {
    if (e.type == EventType::Maximum)
    {
      detector_->addMaximum({e.state.time, e.state.load_position, e.state.load_velocity});
    }
    if (next_ != nullptr)
    {
      next_->onEvent(e);
    }
  }

 private:
  LimitCycleDetector* detector_;
  EventSink* next_;
};
}  // namespace

RunSummary runResponse(const RunConfig& config, EventSink* sink, double sample_period, const SampleCallback& on_sample)
{
  Simulator sim(config.params, config.initial, config.command);
  sim.setEnergyTracking(config.track_energy);
  const double omega_n = config.params.naturalFrequency();
  const double scale =
      std::max({config.params.backlash, std::fabs(config.command - config.initial.load_position), 1e-12});
  LimitCycleDetector detector(config.command, scale);
  Watcher watcher(&detector, sink);
  const double t0 = config.initial.time;
  const bool until_settled = config.duration <= 0.0;
  const double t_stop =
      t0 + (until_settled ? (config.max_duration > 0.0 ? config.max_duration : 2000.0 / omega_n) : config.duration);
  const double chunk = sample_period > 0.0 ? sample_period : 2.0 * PI / omega_n;
  const double rest = LimitCycleDetector::ZERO_FRACTION * scale;
  // Quiet: no new positive maximum for a long time while close to the command means no oscillation is left, only
  // the slow creep of the motor across the backlash under a vanishing torque.
  const double quiet_floor = 10.0 * 2.0 * PI / omega_n;
  double longest = 0.0;  // longest interval between successive maxima so far [s]
  std::size_t intervals_seen = 0;
  if (on_sample)
  {
    on_sample(sim);
  }
  for (long i = 1;; ++i)
  {
    const double t = std::min(t0 + static_cast<double>(i) * chunk, t_stop);
    sim.advanceTo(t, &watcher);
    if (on_sample && sample_period > 0.0)
    {
      on_sample(sim);
    }
    const State& s = sim.state();
    if (std::fabs(s.load_position - config.command) <= rest && std::fabs(s.load_velocity) <= rest * omega_n &&
        std::fabs(config.params.gear_ratio * s.motor_velocity) <= rest * omega_n)
    {
      detector.markAtRest();
    }
    const std::vector<Maximum>& m = detector.maxima();
    for (; intervals_seen + 1 < m.size(); ++intervals_seen)
    {
      longest = std::max(longest, m[intervals_seen + 1].time - m[intervals_seen].time);
    }
    const double last = m.empty() ? t0 : m.back().time;
    if (s.time - last > std::max(quiet_floor, 5.0 * longest) &&
        std::fabs(s.load_position - config.command) <= QUIET_ERROR_FRACTION * scale)
    {
      detector.markAtRest();
    }
    if (t >= t_stop || (until_settled && detector.settled()))
    {
      break;
    }
  }
  RunSummary out;
  out.status = detector.status();
  out.maxima = detector.maxima();
  out.impacts = sim.impactCount();
  out.energy = sim.energy();
  out.kinetic = sim.kineticEnergy();
  out.balance_error = sim.energyBalanceError();
  out.final_state = sim.state();
  out.simulated = sim.state().time - t0;
  out.settled = detector.settled();
  return out;
}

}  // namespace backlash_servo
