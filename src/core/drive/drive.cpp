#include "backlash_servo/drive/drive.h"
#include "backlash_servo/model/constants.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace backlash_servo
{
namespace
{
/// Where the load θ_c = x [rad] lies relative to [lo, hi] [rad]: +1 above, −1 below, 0 inside; on an edge the side
/// the load is moving to (v [rad/s]) decides, so a switch never repeats at the same instant.
int sideOf(double x, double v, double lo, double hi)
{
  return x > hi || (x >= hi && v > 0.0) ? 1 : (x < lo || (x <= lo && v < 0.0) ? -1 : 0);
}

/// The θ_c interval [*a, *b] [rad] of side `side` of [lo, hi] (sideOf's convention): a piece's watch interval.
void sideInterval(int side, double lo, double hi, double* a, double* b)
{
  *a = side < 0 ? -INF : (side > 0 ? hi : lo);
  *b = side < 0 ? lo : (side > 0 ? INF : hi);
}
}  // namespace

std::unique_ptr<Drive> makePositionDrive(const DriveParams& drive, double gain, double gear_ratio, double command,
                                         double t0)
{
  if (drive.sampled())
  {
    return std::make_unique<SampledDrive>(drive, gain, gear_ratio, command, t0);
  }
  return std::make_unique<ProportionalDrive>(drive, gain, command);
}

ProportionalDrive::ProportionalDrive(double gain, double command, double torque_limit)
    : gain_(gain), command_(0.0), limit_(torque_limit)
{
  requireFinite("gain", gain);
  requireFinite("torque_limit", torque_limit);
  setCommand(command);
}

ProportionalDrive::ProportionalDrive(const DriveParams& drive, double gain, double command)
    : ProportionalDrive(gain, command, drive.torque_limit)
{
  drive.validate();
  if (drive.compensation == "friction_feedforward")
  {
    friction_ = drive.compensation_friction;
    width_ = drive.compensation_width;
  }
  else if (drive.compensation == "dither" && drive.dither_amplitude > 0.0 && drive.dither_frequency > 0.0)
  {
    amplitude_ = drive.dither_amplitude;
    frequency_ = drive.dither_frequency;
  }
}

MotorInput ProportionalDrive::law() const
{
  switch (region_)
  {
    case Region::High:
      return {limit_, 0.0};
    case Region::Low:
      return {-limit_, 0.0};
    default:
      return {feedforward_ == 0 && dither_sign_ == 0 ? gain_ * command_ : gain_ * command_ + added(), gain_,
              wave_.scaled(gain_)};
  }
}

double ProportionalDrive::nextEventTime(double /*t*/) const
{
  // Switches at t_n = n/(2f), computed from the integer n (no drift): the end of the present half period (a switch
  // due at the current time is taken there, as a digital drive's sample is).
  return amplitude_ == 0.0 ? std::numeric_limits<double>::infinity() : (half_ + 1.0) / (2.0 * frequency_);
}

void ProportionalDrive::sample(const State& s)
{
  if (amplitude_ == 0.0)
  {
    return;
  }
  // The half period [n/(2f), (n+1)/(2f)) that holds state.time, with the switch instants as nextEventTime() computes
  // them: sin(2πft) has the sign (−1)^n there.
  double n = std::floor(2.0 * frequency_ * s.time);
  if ((n + 1.0) / (2.0 * frequency_) <= s.time)
  {
    n += 1.0;
  }
  half_ = n;
  dither_sign_ = std::fmod(n, 2.0) == 0.0 ? 1 : -1;
  reevaluate(s);
}

void ProportionalDrive::reevaluate(const State& s)
{
  const double x = s.load_position;
  const double v = s.load_velocity;
  if (friction_ > 0.0)
  {
    // The feed-forward's zone: θ_c above θ_R + w pushes down (−F), below θ_R − w up (+F), none in between.
    feedforward_ = -sideOf(x, v, command_ - width_, command_ + width_);
  }
  if (!(limit_ > 0.0))
  {
    region_ = Region::Linear;
    return;
  }
  double lo, hi;
  band(&lo, &hi);
  const int side = sideOf(x, v, lo, hi);
  region_ = side > 0 ? Region::Low : (side < 0 ? Region::High : Region::Linear);
}

void ProportionalDrive::watchInterval(double* lo, double* hi) const
{
  *lo = -INF;
  *hi = INF;
  if (limit_ > 0.0)
  {
    double band_lo, band_hi;
    band(&band_lo, &band_hi);
    const int side = region_ == Region::Low ? 1 : (region_ == Region::High ? -1 : 0);
    sideInterval(side, band_lo, band_hi, lo, hi);
  }
  if (friction_ > 0.0)
  {
    double zone_lo, zone_hi;  // ∩ the feed-forward's zone
    sideInterval(-feedforward_, command_ - width_, command_ + width_, &zone_lo, &zone_hi);
    *lo = std::max(*lo, zone_lo);
    *hi = std::min(*hi, zone_hi);
  }
}

void ProportionalDrive::band(double* lo, double* hi) const
{
  if (feedforward_ == 0 && dither_sign_ == 0)
  {
    *lo = command_ - limit_ / gain_;
    *hi = command_ + limit_ / gain_;
    return;
  }
  const double c = added();
  *lo = command_ - (limit_ - c) / gain_;
  *hi = command_ + (limit_ + c) / gain_;
}

void ProportionalDrive::configure(const ServoParams& params)
{
  gain_ = params.gain;  // validated with the rest of the parameters by the caller
}

void ProportionalDrive::setCommand(double command)
{
  requireFinite("command", command);
  command_ = command;
  wave_ = Waveform();
}

namespace
{
/// A wave's numbers finite, each sine's frequency > 0.
void requireWave(const std::string& key, const Waveform& wave)
{
  for (int i = 0; i < wave.count; ++i)
  {
    const Sinusoid& w = wave.tones[static_cast<std::size_t>(i)];
    if (!std::isfinite(w.amplitude) || !std::isfinite(w.frequency) || !std::isfinite(w.phase) ||
        !std::isfinite(w.origin) || !(w.frequency > 0.0))
    {
      throw InvalidParameterError(key, "a sine needs a finite amplitude, phase and origin and a frequency > 0 rad/s");
    }
  }
}
}  // namespace

void ProportionalDrive::setCommandWave(double command, const Waveform& wave)
{
  requireWave("command", wave);
  if (wave.active() && (limit_ > 0.0 || friction_ != 0.0 || amplitude_ != 0.0))
  {
    throw InvalidParameterError("command",
                                "a sine under the continuous law needs its linear law (no torque_limit or "
                                "compensation): use a digital drive (controller_rate > 0), which samples it");
  }
  setCommand(command);
  wave_ = wave;
}

EffortDrive::EffortDrive(double torque, const Waveform& wave) : torque_(0.0)
{
  setTorque(torque);
  requireWave("motor_torque", wave);
  wave_ = wave;
}

void EffortDrive::setTorque(double torque)
{
  requireFinite("motor_torque", torque);
  torque_ = torque;
  wave_ = Waveform();
}

SampledDrive::SampledDrive(const DriveParams& drive, double gain, double gear_ratio, double command, double t0)
    : p_(drive), gain_(gain), rho_(gear_ratio), command_(command), t0_(t0), period_(1.0 / drive.controller_rate)
{
  drive.validate();
  requireFinite("command", command);
  law_ = drive.control_law == "pid" ? Law::Pid : drive.control_law == "cascade" ? Law::Cascade : Law::Proportional;
  motor_feedback_ = drive.feedback == "motor";
  compensator_ = Compensator(drive);
}

void SampledDrive::configure(const ServoParams& params)
{
  gain_ = params.gain;
  rho_ = params.gear_ratio;
}

bool SampledDrive::retune(const DriveParams& drive)
{
  drive.validate();
  if (!drive.sampled() || drive.control_law != p_.control_law || drive.feedback != p_.feedback)
  {
    return false;
  }
  Compensator compensator = compensator_;
  if (!compensator.retune(drive))
  {
    return false;
  }
  compensator_ = compensator;
  if (drive.controller_rate != p_.controller_rate)
  {
    t0_ = nextEventTime(0.0);  // the sample due stays due; the later ones follow the new period
    next_ = 0;
    period_ = 1.0 / drive.controller_rate;
  }
  if (drive.controller_delay > 0.0 && !(p_.controller_delay > 0.0))
  {
    pending_ = held_;  // delay 0 → 1: the present output is held one more sample
  }
  p_ = drive;
  return true;
}

void SampledDrive::setCommand(double command)
{
  requireFinite("command", command);
  command_ = command;
}

double SampledDrive::nextEventTime(double /*t*/) const
{
  return t0_ + static_cast<double>(next_) / p_.controller_rate;  // t_k from the integer k: no drift
}

double quantiseAngle(double angle, double resolution)
{
  return TWO_PI / resolution * std::floor(resolution * angle / TWO_PI);
}

void SampledDrive::sample(const State& s)
{
  const double period = period_;
  const double qm = encoderReading(s.motor_position, p_.motor_encoder_resolution);
  motor_reading_ = rho_ * qm;
  load_reading_ = encoderReading(s.load_position, p_.load_encoder_resolution);
  const double y = motor_feedback_ ? motor_reading_ : load_reading_;
  const bool compensated = compensator_.active();
  const double t_k = profile_ || compensated ? t0_ + static_cast<double>(next_) * period : 0.0;  // (only they read it)
  reference_ = profile_ ? profile_->at(t_k) : command_;
  const double e = (compensated ? compensator_.reference(reference_, load_reading_, period) : reference_) - y;
  const bool first = !started_;
  const double limit = p_.torque_limit;
  auto beyond = [&](double u, double sign) { return limit > 0.0 && std::fabs(u) > limit && u * sign > 0.0; };
  double u = 0.0;
  bool steady = false;  // the output is the same at every later sample while the plant stands still
  if (law_ == Law::Pid)
  {
    const double y_prev = first ? y : y_prev_;
    const double derivative = p_.derivative_gain * (y - y_prev) / period;
    double integral = integral_ + p_.integral_gain * period * e;
    u = gain_ * e + integral - derivative;
    if (beyond(u, e))
    {
      integral = integral_;  // conditional integration: no wind-up against the limit
      u = gain_ * e + integral - derivative;
    }
    // Frozen when the increment is lost in rounding, or when its input is: an error within a few ulps of the
    // positions it is the difference of (the load on the command to 3e-16 rad) is rounding, not a drift.
    winding_ = std::fabs(integral - integral_) > 4.0 * EPS * std::fabs(integral) &&
               std::fabs(e) > 4.0 * EPS * std::max(std::fabs(reference_), std::fabs(y));
    integral_ = integral;
    steady = !winding_ && y == y_prev;
  }
  else if (law_ == Law::Cascade)
  {
    const double w_ref = p_.position_loop_gain * e;
    const double w_hat = first ? 0.0 : rho_ * (qm - qm_prev_) / period;
    const double err = w_ref - w_hat;
    double integral = integral_ + p_.velocity_loop_integral_gain * period * err;
    u = p_.velocity_loop_gain * err + integral;
    if (beyond(u, err))
    {
      integral = integral_;
      u = p_.velocity_loop_gain * err + integral;
    }
    winding_ = std::fabs(integral - integral_) > 4.0 * EPS * std::fabs(integral) &&
               !(w_hat == 0.0 && std::fabs(e) <= 4.0 * EPS * std::max(std::fabs(reference_), std::fabs(y)));
    integral_ = integral;
    steady = !winding_ && w_hat == 0.0;
  }
  else
  {
    u = gain_ * e;
    steady = true;
  }
  if (compensated)
  {
    u = compensator_.torque(u, e, t_k);
    steady = false;
  }
  injected_ = 0.0;
  if (injection_amplitude_ != 0.0)
  {
    // The phase from the index modulo N: exact however long the run.
    const long k = ((next_ - injection_start_) % injection_period_ + injection_period_) % injection_period_;
    injected_ = injection_amplitude_ * (injection_shape_ ? (*injection_shape_)[static_cast<std::size_t>(k)]
                                                         : std::sin(6.283185307179586476925 * static_cast<double>(k) /
                                                                    static_cast<double>(injection_period_)));
    u += injected_;
    steady = false;
  }
  if (limit > 0.0)
  {
    u = std::min(std::max(u, -limit), limit);
  }
  y_prev_ = y;
  qm_prev_ = qm;
  if (p_.controller_delay > 0.0)
  {
    held_ = pending_;
    pending_ = u;
  }
  else
  {
    held_ = u;
  }
  steady_ = steady && held_ == u;
  ++next_;
  started_ = true;
}

void SampledDrive::setInjection(double amplitude, long period_samples)
{
  if (!std::isfinite(amplitude) || (amplitude != 0.0 && period_samples < 2))
  {
    throw InvalidParameterError("amplitude",
                                "an injected torque needs a finite amplitude [N·m] and a period of at "
                                "least 2 samples");
  }
  injection_amplitude_ = amplitude;
  injection_period_ = period_samples;
  injection_start_ = next_;
  injection_shape_.reset();
}

void SampledDrive::setInjection(double amplitude, std::shared_ptr<const std::vector<double>> shape)
{
  for (std::size_t k = 0; shape && k < shape->size(); ++k)
  {
    if (!std::isfinite((*shape)[k]))
    {
      throw InvalidParameterError("amplitude", "an injected shape must be finite at every sample");
    }
  }
  setInjection(amplitude, shape ? static_cast<long>(shape->size()) : 0L);
  injection_shape_ = std::move(shape);
}

long SampledDrive::holdSamples(const State& state, double until, double lo, double hi, long max_count, double* last)
{
  long taken = 0;
  while (taken < max_count)
  {
    const double t = nextEventTime(0.0);
    if (!(t < until))
    {
      break;
    }
    sample(state);
    ++taken;
    *last = t;
    if (!(held_ >= lo && held_ <= hi))
    {
      break;  // this torque may move the joint: the caller applies it through the rest rule
    }
  }
  return taken;
}

}  // namespace backlash_servo
