#include "backlash_servo/response_monitor.h"

#include <algorithm>
#include <cmath>

#include "backlash_servo/drive.h"

namespace backlash_servo
{
namespace
{
constexpr double PI = 3.14159265358979323846;

double scaleOf(const ServoParams& params, double command, double equilibrium, const State& start)
{
  return std::max({params.backlash, std::fabs(command - start.load_position), std::fabs(equilibrium - command), 1e-12});
}
}  // namespace

double loopEquilibrium(const ServoParams& params, const DriveParams& drive, double command)
{
  const double held = params.gear_ratio * params.load_torque;  // −T_m at rest [N·m]
  const bool sampled = drive.sampled();
  if (sampled && drive.control_law == "pid" && drive.integral_gain > 0.0)
  {
    return command;
  }
  if (sampled && drive.control_law == "cascade")
  {
    const double k = drive.velocity_loop_gain * drive.position_loop_gain;
    return drive.velocity_loop_integral_gain > 0.0 || !(k > 0.0) ? command : command + held / k;
  }
  return command + held / params.gain;
}

ResponseMonitor::ResponseMonitor(const ServoParams& params, double command, double equilibrium, const State& start,
                                 bool sampled_drive)
    : command_(command),
      equilibrium_(equilibrium),
      omega_n_(params.naturalFrequency()),
      rho_(params.gear_ratio),
      scale_(scaleOf(params, command, equilibrium, start)),
      start_time_(start.time),
      bands_(sampled_drive || params.hasDryFriction()),
      dry_friction_(params.hasDryFriction()),
      detector_(command, scale_, equilibrium)
{
  restartAt(start);
}

void ResponseMonitor::restartAt(const State& state)
{
  start_time_ = state.time;
  detector_ = LimitCycleDetector(command_, scale_, equilibrium_);
  detector_.allowBands(bands_);
  detector_.extrapolateDecay(!dry_friction_);
  // A thousandth of the natural period: far below any cycle of the loop, far above micro-bounces.
  detector_.setMinimumSpacing(1e-3 * 2.0 * PI / omega_n_);
  longest_ = 0.0;
  intervals_seen_ = 0;
}

void ResponseMonitor::onEvent(const Event& e)
{
  if (e.type == EventType::Maximum)
  {
    detector_.addMaximum({e.state.time, e.state.load_position, e.state.load_velocity});
  }
}

void ResponseMonitor::check(const State& s, bool drive_winding, bool at_rest_forever)
{
  const std::vector<Maximum>& m = detector_.judged();
  for (; intervals_seen_ + 1 < m.size(); ++intervals_seen_)
  {
    longest_ = std::max(longest_, m[intervals_seen_ + 1].time - m[intervals_seen_].time);
  }
  if (at_rest_forever)
  {
    detector_.markStuck();
    return;
  }
  if (drive_winding)
  {
    return;
  }
  const double rest = LimitCycleDetector::ZERO_FRACTION * scale_;
  if (std::fabs(s.load_position - equilibrium_) <= rest && std::fabs(s.load_velocity) <= rest * omega_n_ &&
      std::fabs(rho_ * s.motor_velocity) <= rest * omega_n_)
  {
    detector_.markAtRest();
  }
  const double last = m.empty() ? start_time_ : m.back().time;
  const double quiet_floor = QUIET_PERIODS * 2.0 * PI / omega_n_;
  if (s.time - last > std::max(quiet_floor, 5.0 * longest_) &&
      std::fabs(s.load_position - equilibrium_) <= QUIET_ERROR_FRACTION * scale_)
  {
    detector_.markAtRest();
  }
}

}  // namespace backlash_servo
