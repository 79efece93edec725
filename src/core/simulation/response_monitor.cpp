#include "backlash_servo/simulation/response_monitor.h"

#include <algorithm>
#include <cmath>

#include "backlash_servo/drive/drive.h"
#include "backlash_servo/model/constants.h"

namespace backlash_servo
{
namespace
{
/// Aitken's Δ² limit of three successive values approaching it geometrically (contraction ratio in (−1, 1)); the
/// latest value otherwise.
double aitken(const double x[3])
{
  const double d1 = x[1] - x[0], d2 = x[2] - x[1];
  const double den = d2 - d1;
  if (den == 0.0 || d1 == 0.0 || !(std::fabs(d2 / d1) < 1.0))
  {
    return x[2];
  }
  return x[2] - d2 * d2 / den;
}

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
  rested_ = false;
  turns_.clear();
}

void ResponseMonitor::onEvent(const Event& e)
{
  if (e.type != EventType::Maximum && e.type != EventType::Minimum)
  {
    return;
  }
  if (e.type == EventType::Maximum)
  {
    detector_.addMaximum({e.state.time, e.state.load_position, e.state.load_velocity});
  }
  if (turns_.size() == TURNS_KEPT)
  {
    turns_.pop_front();
  }
  turns_.push_back({e.state.time, e.state.load_position});
}

CycleShape ResponseMonitor::cycleShape() const
{
  CycleShape shape;
  const LimitCycleReport& r = detector_.status();
  if (!detector_.oscillating() || turns_.empty())
  {
    return shape;
  }
  double window = r.period;
  const std::vector<Maximum>& m = detector_.judged();
  if ((r.quasi_periodic || r.verdict == Verdict::Irregular) && !m.empty())
  {
    const std::size_t span =
        std::min<std::size_t>(m.size() - 1, r.verdict == Verdict::Irregular ? LimitCycleDetector::IRREGULAR_WINDOW
                                                                            : LimitCycleDetector::BAND_WINDOW);
    window = std::max(window, m.back().time - m[m.size() - 1 - span].time);
  }
  // The windows' edges fall half the shortest spacing of the last period's turning points after a turning point, so
  // that a window of one period holds each turning point of the pattern exactly once.
  const double last = turns_.back().time;
  double shortest = window;
  for (std::size_t i = turns_.size() - 1; i > 0 && turns_[i].time > last - window; --i)
  {
    shortest = std::min(shortest, turns_[i].time - turns_[i - 1].time);
  }
  const double edge = last + 0.5 * shortest;
  // Highest and lowest turning point over the window of one `window` ending `back` windows before `edge`; false when
  // the window reaches beyond the turning points kept.
  auto extremes = [&](int back, double* top, double* bottom) {
    const double to = edge - back * window;
    const double from = to - window;
    *top = -INFINITY;
    *bottom = INFINITY;
    bool complete = false;
    for (auto it = turns_.rbegin(); it != turns_.rend(); ++it)
    {
      if (it->time <= from)
      {
        complete = true;
        break;
      }
      if (it->time <= to)
      {
        *top = std::max(*top, it->position);
        *bottom = std::min(*bottom, it->position);
      }
    }
    return complete && *top >= *bottom;
  };
  double top, bottom;
  extremes(0, &top, &bottom);
  double tops[3], bottoms[3];
  if (!r.quasi_periodic && r.verdict == Verdict::LimitCycle && extremes(1, &tops[1], &bottoms[1]) &&
      extremes(2, &tops[0], &bottoms[0]))
  {
    // A limit cycle's figures are its fixed point (as limit_cycle_error is): the last three periods' extremes
    // extrapolated by Aitken's Δ² where they still approach it geometrically.
    tops[2] = top;
    bottoms[2] = bottom;
    top = aitken(tops);
    bottom = aitken(bottoms);
  }
  shape.top = top;
  shape.bottom = bottom;
  shape.peak_to_peak = top - bottom;
  shape.centre = 0.5 * (top + bottom);
  return shape;
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
    rested_ = true;
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
    rested_ = true;
  }
  const double last = m.empty() ? start_time_ : m.back().time;
  const double quiet_floor = QUIET_PERIODS * 2.0 * PI / omega_n_;
  // Quiet means still, too: a load swinging through its equilibrium (a slow saturated oscillation whose period ω_n
  // does not describe) is not quiet, wherever the check catches it.
  const double quiet = QUIET_ERROR_FRACTION * scale_;
  if (s.time - last > std::max(quiet_floor, 5.0 * longest_) && std::fabs(s.load_position - equilibrium_) <= quiet &&
      std::fabs(s.load_velocity) <= quiet * omega_n_ && std::fabs(rho_ * s.motor_velocity) <= quiet * omega_n_)
  {
    detector_.markAtRest();
    rested_ = true;
  }
}

bool ResponseMonitor::convergedNear(const State& s) const
{
  if (detector_.status().verdict != Verdict::Converged)
  {
    return false;
  }
  if (rested_)
  {
    return true;
  }
  const double near = QUIET_ERROR_FRACTION * scale_;
  const std::vector<Maximum>& m = detector_.judged();
  return std::fabs(s.load_position - equilibrium_) <= near && (m.empty() || m.back().position - equilibrium_ <= near);
}

}  // namespace backlash_servo
