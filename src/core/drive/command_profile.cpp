#include "backlash_servo/drive/command_profile.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
namespace
{
/// Trapezoid (or triangle) distance covered after tau [s] of a move of length |d| [rad].
double trapezoid(double d, double vmax, double amax, double tau)
{
  const double t_acc = vmax / amax;
  double t_cruise = (d - vmax * t_acc) / vmax;
  double v_peak = vmax;
  double ta = t_acc;
  if (t_cruise < 0.0)
  {
    ta = std::sqrt(d / amax);  // triangular: never reaches vmax
    v_peak = amax * ta;
    t_cruise = 0.0;
  }
  const double total = 2.0 * ta + t_cruise;
  if (tau <= 0.0)
  {
    return 0.0;
  }
  if (tau >= total)
  {
    return d;
  }
  if (tau < ta)
  {
    return 0.5 * amax * tau * tau;
  }
  const double s1 = 0.5 * amax * ta * ta;
  if (tau < ta + t_cruise)
  {
    return s1 + v_peak * (tau - ta);
  }
  const double tr = total - tau;
  return d - 0.5 * amax * tr * tr;
}

double moveDuration(const ProfileSegment& s)
{
  const double d = std::fabs(s.distance);
  const double t_acc = s.max_velocity / s.max_acceleration;
  if (d < s.max_velocity * t_acc)
  {
    return 2.0 * std::sqrt(d / s.max_acceleration);
  }
  return 2.0 * t_acc + (d - s.max_velocity * t_acc) / s.max_velocity;
}
}  // namespace

CommandProfile::CommandProfile(double start, std::vector<ProfileSegment> segments)
    : start_(start), segments_(std::move(segments))
{
  requireFinite("profile start", start);
  double last = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < segments_.size(); ++i)
  {
    const ProfileSegment& s = segments_[i];
    const std::string where = "profile segment " + std::to_string(i + 1);
    auto need = [&](bool ok, const std::string& what) {
      if (!ok)
      {
        throw InvalidParameterError(where, what);
      }
    };
    for (double v : {s.time, s.target, s.duration, s.rate, s.amplitude, s.frequency, s.distance, s.max_velocity,
                     s.max_acceleration})
    {
      need(std::isfinite(v), "every value must be a finite number");
    }
    // Positions the profile reaches stay in the range of `command` (a set-point of 1e12 rad is a typo, not a test).
    const ParamRange& positions = param("command").range;
    for (double v : {s.target, s.amplitude, s.distance})
    {
      need(positions.contains(v),
           "a target, amplitude or distance must be " + positions.describe() + " rad (got " + formatNumber(v) + ")");
    }
    need(s.time >= 0.0 && s.time >= last, "times must be >= 0 and in order (got " + formatNumber(s.time) + " s)");
    last = s.time;
    switch (s.kind)
    {
      case ProfileSegment::Kind::Ramp:
        need(s.duration > 0.0 || s.rate > 0.0, "a ramp needs duration > 0 s or rate > 0 rad/s");
        break;
      case ProfileSegment::Kind::Sine:
        need(s.frequency > 0.0 && s.duration > 0.0, "a sine needs frequency > 0 Hz and duration > 0 s");
        need(positions.contains(s.dither_amplitude) && std::isfinite(s.dither_frequency) &&
                 (s.dither_amplitude == 0.0 || s.dither_frequency > 0.0),
             "a dither needs dither_frequency > 0 Hz and a finite dither_amplitude (got " +
                 formatNumber(s.dither_amplitude) + " rad at " + formatNumber(s.dither_frequency) + " Hz)");
        break;
      case ProfileSegment::Kind::Move:
        need(s.max_velocity > 0.0 && s.max_acceleration > 0.0,
             "a move needs max_velocity > 0 rad/s and max_acceleration > 0 rad/s²");
        break;
      case ProfileSegment::Kind::Points:
        need(!s.points.empty(), "points: at least one (time, value)");
        for (std::size_t k = 0; k < s.points.size(); ++k)
        {
          need(std::isfinite(s.points[k].first) && std::isfinite(s.points[k].second), "points must be finite numbers");
          need(positions.contains(s.points[k].second), "point " + std::to_string(k + 1) + ": the value must be " +
                                                           positions.describe() + " rad (got " +
                                                           formatNumber(s.points[k].second) + ")");
          need(k == 0 || s.points[k].first >= s.points[k - 1].first, "point times must be in order");
        }
        break;
      default:
        break;
    }
  }
}

double CommandProfile::evaluate(const ProfileSegment& s, double v0, double tau) const
{
  switch (s.kind)
  {
    case ProfileSegment::Kind::Step:
      return s.target;
    case ProfileSegment::Kind::Ramp: {
      const double d = s.duration > 0.0 ? s.duration : std::fabs(s.target - v0) / s.rate;
      return d <= 0.0 ? s.target : v0 + (s.target - v0) * std::min(1.0, tau / d);
    }
    case ProfileSegment::Kind::Sine:
      return tau < s.duration ? v0 + s.amplitude * std::sin(TWO_PI * s.frequency * tau) +
                                    s.dither_amplitude * std::sin(TWO_PI * s.dither_frequency * tau)
                              : v0;
    case ProfileSegment::Kind::Move: {
      const double sign = s.distance >= 0.0 ? 1.0 : -1.0;
      return v0 + sign * trapezoid(std::fabs(s.distance), s.max_velocity, s.max_acceleration, tau);
    }
    default: {
      // The last point at or before s.time + tau (points are in time order: a binary search, O(log N)).
      const auto after = std::upper_bound(s.points.begin(), s.points.end(), s.time + tau,
                                          [](double t, const std::pair<double, double>& p) { return t < p.first; });
      const double v = after == s.points.begin() ? v0 : std::prev(after)->second;
      return v;
    }
  }
}

double CommandProfile::at(double t) const
{
  double value = start_;
  for (std::size_t i = 0; i < segments_.size(); ++i)
  {
    const ProfileSegment& s = segments_[i];
    if (t < s.time)
    {
      break;
    }
    const double next = i + 1 < segments_.size() ? segments_[i + 1].time : std::numeric_limits<double>::infinity();
    // The segment runs until the next one starts (which then starts from the value it left).
    value = evaluate(s, value, std::min(t, next) - s.time);
  }
  return value;
}

double CommandProfile::finalValue() const
{
  return at(std::numeric_limits<double>::infinity());  // every segment run to its end
}

bool CommandProfile::piecewiseConstant() const
{
  return std::all_of(segments_.begin(), segments_.end(), [](const ProfileSegment& s) {
    return s.kind == ProfileSegment::Kind::Step || s.kind == ProfileSegment::Kind::Points;
  });
}

double CommandProfile::nextChange(double t) const
{
  double next = std::numeric_limits<double>::infinity();
  for (const ProfileSegment& s : segments_)
  {
    if (s.time > t)
    {
      next = std::min(next, s.time);
    }
    const auto after = std::upper_bound(s.points.begin(), s.points.end(), t,
                                        [](double x, const std::pair<double, double>& p) { return x < p.first; });
    if (after != s.points.end())
    {
      next = std::min(next, after->first);
    }
  }
  return next;
}

bool CommandProfile::piecewiseLinear() const
{
  return std::all_of(segments_.begin(), segments_.end(), [](const ProfileSegment& s) {
    return s.kind != ProfileSegment::Kind::Sine && s.kind != ProfileSegment::Kind::Move;
  });
}

void CommandProfile::pieceAt(double t, double* slope, double* until, Waveform* wave, double* base) const
{
  *slope = 0.0;
  *until = nextChange(t);
  if (wave != nullptr)
  {
    *wave = Waveform();
  }
  double value = start_;
  for (std::size_t i = 0; i < segments_.size() && t >= segments_[i].time; ++i)
  {
    const ProfileSegment& s = segments_[i];
    const double next = i + 1 < segments_.size() ? segments_[i + 1].time : std::numeric_limits<double>::infinity();
    const double v0 = value;
    value = evaluate(s, value, std::min(t, next) - s.time);
    if (wave != nullptr)
    {
      *wave = Waveform();
    }
    if (s.kind == ProfileSegment::Kind::Sine && t < next && t < s.time + s.duration)
    {
      // Within the sine: its centre and the sine itself, to its end (or the next segment's start).
      *slope = 0.0;
      if (wave != nullptr)
      {
        *wave = Sinusoid{s.amplitude, TWO_PI * s.frequency, 0.0, s.time};
        wave->add(Sinusoid{s.dither_amplitude, TWO_PI * s.dither_frequency, 0.0, s.time});  // (none if 0)
      }
      if (base != nullptr)
      {
        *base = v0;
      }
      *until = std::min(*until, s.time + s.duration);
      continue;
    }
    if (s.kind != ProfileSegment::Kind::Ramp || t >= next)
    {
      *slope = 0.0;
      continue;
    }
    const double d = s.duration > 0.0 ? s.duration : std::fabs(s.target - v0) / s.rate;
    if (t < s.time + d)
    {
      *slope = (s.target - v0) / d;
      *until = std::min(*until, s.time + d);
    }
    else
    {
      *slope = 0.0;
    }
  }
}

void CommandProfile::requireTakenBy(bool sampled, bool dry, bool compliant, int max_tones) const
{
  if (sampled || piecewiseConstant())
  {
    return;
  }
  bool moves = false, sines = false;
  for (const ProfileSegment& s : segments_)
  {
    moves = moves || s.kind == ProfileSegment::Kind::Move;
    sines = sines || s.kind == ProfileSegment::Kind::Sine;
    if (s.kind == ProfileSegment::Kind::Sine && s.dither_amplitude != 0.0 && max_tones < 2)
    {
      throw InvalidParameterError("profile",
                                  "a sine with a dither is two sines, and the continuous law carries one on this "
                                  "joint (a torsional shaft): set controller_rate > 0 Hz for a digital drive");
    }
  }
  if (moves || (sines && dry && !compliant))
  {
    throw InvalidParameterError("profile",
                                "the continuous law takes step, points, ramp and sine profiles (sines on rigid teeth "
                                "without dry friction); a move — or a sine on rigid teeth with dry friction — is "
                                "sampled by a digital drive: set controller_rate > 0 Hz");
  }
  bool ramps = false;
  for (const ProfileSegment& s : segments_)
  {
    ramps = ramps || s.kind == ProfileSegment::Kind::Ramp;
  }
  if (!ramps)
  {
    return;  // (steps, points and sines: no moving frame)
  }
  if (dry)
  {
    throw InvalidParameterError("profile",
                                "the continuous law takes ramps only without dry friction (it runs them in the frame "
                                "moving with the ramp, where Coulomb friction is not constant): set "
                                "controller_rate > 0 Hz or no *_coulomb/static_friction");
  }
}

CommandProfile CommandProfile::delayed(double dt) const
{
  std::vector<ProfileSegment> segments = segments_;
  for (ProfileSegment& s : segments)
  {
    s.time += dt;
    for (auto& p : s.points)
    {
      p.first += dt;
    }
  }
  return CommandProfile(start_, std::move(segments));
}

double CommandProfile::endTime() const
{
  double end = 0.0;
  for (const ProfileSegment& s : segments_)
  {
    double length = 0.0;
    if (s.kind == ProfileSegment::Kind::Sine)
    {
      length = s.duration;
    }
    else if (s.kind == ProfileSegment::Kind::Move)
    {
      length = moveDuration(s);
    }
    else if (s.kind == ProfileSegment::Kind::Ramp)
    {
      length = s.duration > 0.0 ? s.duration : 0.0;  // a rate ramp's length depends on v₀: bounded below
    }
    else if (s.kind == ProfileSegment::Kind::Points)
    {
      length = s.points.back().first - s.time;
    }
    end = std::max(end, s.time + std::max(0.0, length));
  }
  return end;
}

}  // namespace backlash_servo
