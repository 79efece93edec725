#include "backlash_servo/frequency/frequency_response.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <deque>
#include <memory>
#include <vector>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/model/constants.h"
#include "compliant/compliant_joint.h"
#include "numerics/gauss_legendre.h"

namespace backlash_servo
{
namespace
{
/// An exact sine's period is observed at this many instants (the steady-state test, the Fourier pieces' cuts).
constexpr int CONTINUOUS_POINTS = 64;
/// Subharmonics looked for: a response repeating after up to this many periods.
constexpr int MAX_PERIOD_MULTIPLE = 4;

/// Records the instants where the output or its slope may jump (impacts, contacts, separations, rests) and the
/// flank changes (the teeth crossing the backlash).
class BreakSink : public EventSink
{
 public:
  void onEvent(const Event& e) override
  {
    int flank = 0;
    switch (e.type)
    {
      case EventType::Impact:
        flank = e.impact.wall == Contact::Forward ? 1 : -1;
        breaks.push_back(e.state.time);
        break;
      case EventType::Engagement:
        flank = e.state.contact == Contact::Forward ? 1 : (e.state.contact == Contact::Backward ? -1 : 0);
        breaks.push_back(e.state.time);
        break;
      case EventType::Separation:
        ++separations;
        breaks.push_back(e.state.time);
        break;
      case EventType::Rest:
        breaks.push_back(e.state.time);
        break;
      default:
        break;
    }
    if (flank != 0)
    {
      flanks.push_back(flank);
    }
  }
  /// Changes of flank around the periodic window (its last flank is followed by its first).
  long flankChanges() const
  {
    long n = 0;
    for (std::size_t i = 0; i < flanks.size(); ++i)
    {
      n += flanks[i] != flanks[(i + 1) % flanks.size()] ? 1 : 0;
    }
    return n;
  }
  std::vector<double> breaks;
  long separations = 0;
  std::vector<int> flanks;  // the flank (+1 forward, −1 backward) of each impact or engagement, in order
};

/// The quantities compared from one period start to the next.
struct Snapshot
{
  std::array<double, 2> position{};  // θ_c, ρθ_m: may advance by the same amount each period
  std::array<double, 5> level{};     // gap, twist [rad]; ω_c, ρω_m, twist rate [rad/s]: must repeat
};

Snapshot snapshotOf(const State& s, double rho)
{
  Snapshot n;
  n.position = {s.load_position, rho * s.motor_position};
  n.level = {s.load_position - rho * s.motor_position, s.shaft_twist, s.load_velocity, rho * s.motor_velocity,
             s.shaft_twist_rate};
  return n;
}

/// Ranges over a period of the snapshot's quantities (from the samples): the scales of the repeat test.
struct Ranges
{
  std::array<double, 7> lo, hi;
  Ranges() { reset(); }
  void reset()
  {
    lo.fill(INFINITY);
    hi.fill(-INFINITY);
  }
  void add(const Snapshot& s)
  {
    const std::array<double, 7> v = {s.position[0], s.position[1], s.level[0], s.level[1],
                                     s.level[2],    s.level[3],    s.level[4]};
    for (std::size_t i = 0; i < v.size(); ++i)
    {
      lo[i] = std::min(lo[i], v[i]);
      hi[i] = std::max(hi[i], v[i]);
    }
  }
  double range(std::size_t i) const { return hi[i] >= lo[i] ? hi[i] - lo[i] : 0.0; }
  /// The angle scale [rad] (positions, gap, twist) and the speed scale [rad/s].
  double angleScale() const { return std::max({range(0), range(1), range(2), range(3)}); }
  double speedScale() const { return std::max({range(4), range(5), range(6)}); }
};

/// The latest `keep` entries of a sequence, indexed from its start: the settling test reads only the last few
/// periods, so its memory stays bounded however many periods a point runs.
template <class T>
class RecentHistory
{
 public:
  explicit RecentHistory(std::size_t keep) : keep_(keep) {}
  void push_back(const T& v)
  {
    items_.push_back(v);
    if (items_.size() > keep_)
    {
      items_.pop_front();
      ++first_;
    }
  }
  const T& operator[](std::size_t i) const { return items_.at(i - first_); }

 private:
  std::size_t keep_;
  std::size_t first_ = 0;  ///< the index of the oldest entry kept
  std::deque<T> items_;
};

/// Whether the period starts n − 2m, n − m, n repeat: levels equal, positions advancing by the same step, each
/// within tol of its scale (plus the rounding of the values themselves).
bool repeats(const RecentHistory<Snapshot>& s, std::size_t n, std::size_t m, double angle_scale, double speed_scale,
             double tol)
{
  const Snapshot &a = s[n - 2 * m], &b = s[n - m], &c = s[n];
  const auto close = [&](double x, double y, double scale, double magnitude) {
    return std::fabs(x - y) <= tol * scale + 64.0 * 2.2e-16 * magnitude;
  };
  for (std::size_t i = 0; i < 2; ++i)
  {
    const double mag = std::max({std::fabs(a.position[i]), std::fabs(b.position[i]), std::fabs(c.position[i])});
    if (!close(c.position[i] - b.position[i], b.position[i] - a.position[i], angle_scale, mag))
    {
      return false;
    }
  }
  for (std::size_t i = 0; i < 5; ++i)
  {
    const double scale = i < 2 ? angle_scale : speed_scale;
    if (!close(c.level[i], b.level[i], scale, std::max(std::fabs(b.level[i]), std::fabs(c.level[i]))))
    {
      return false;
    }
  }
  return true;
}

}  // namespace

const char* toString(FrfChannel c)
{
  switch (c)
  {
    case FrfChannel::CommandToLoadPosition:
      return "command:load_position";
    case FrfChannel::TorqueToMotorVelocity:
      return "motor_torque:motor_velocity";
    case FrfChannel::TorqueToLoadVelocity:
      return "motor_torque:load_velocity";
    case FrfChannel::SetpointToMotorVelocity:
      return "torque_setpoint:motor_velocity";
    case FrfChannel::SetpointToLoadVelocity:
      return "torque_setpoint:load_velocity";
    case FrfChannel::LoadTorqueToLoadPosition:
      return "load_torque:load_position";
  }
  return "?";
}

FrfChannel frfChannelFrom(const std::string& name, const std::string& key)
{
  for (FrfChannel c :
       {FrfChannel::CommandToLoadPosition, FrfChannel::TorqueToMotorVelocity, FrfChannel::TorqueToLoadVelocity,
        FrfChannel::SetpointToMotorVelocity, FrfChannel::SetpointToLoadVelocity, FrfChannel::LoadTorqueToLoadPosition})
  {
    if (name == toString(c))
    {
      return c;
    }
  }
  throw InvalidParameterError(key, "'" + name +
                                       "' is not a channel: command:load_position, motor_torque:motor_velocity, "
                                       "motor_torque:load_velocity, torque_setpoint:motor_velocity, "
                                       "torque_setpoint:load_velocity or load_torque:load_position");
}

double excitationRate(const RunConfig& config, FrfChannel channel, double injection_rate)
{
  if (loadTorqueInput(channel))
  {
    if (injection_rate != 0.0)
    {
      throw InvalidParameterError("injection_rate",
                                  "the load torque's sine is applied itself, not sampled: leave injection_rate out");
    }
    if (!config.drive.sampled())
    {
      throw InvalidParameterError("controller_rate", "the load torque's sine has no rate without a digital drive");
    }
    return config.drive.controller_rate;  // (its period spans whole samples of the drive)
  }
  if (setpointInput(channel))
  {
    if (!config.drive.sampled())
    {
      throw InvalidParameterError("controller_rate",
                                  "the torque set-point is the digital drive's: give a "
                                  "controller_rate > 0 Hz");
    }
    if (injection_rate != 0.0 && injection_rate != config.drive.controller_rate)
    {
      throw InvalidParameterError("injection_rate",
                                  "the set-point is injected at the drive's own samples "
                                  "(controller_rate): leave injection_rate out");
    }
    return config.drive.controller_rate;
  }
  if (!torqueInput(channel))
  {
    if (!config.drive.sampled())
    {
      throw InvalidParameterError("controller_rate",
                                  "the command channel needs a digital drive (controller_rate > 0 Hz), which samples "
                                  "the excitation exactly; the continuous law takes no sine");
    }
    return config.drive.controller_rate;
  }
  const double rate = injection_rate > 0.0
                          ? injection_rate
                          : (config.drive.sampled() ? config.drive.controller_rate : DEFAULT_INJECTION_RATE);
  if (!std::isfinite(rate))
  {
    throw InvalidParameterError("injection_rate", "must be finite");
  }
  return rate;
}

double slowestTimeScale(const RunConfig& config, FrfChannel channel)
{
  return std::max({plantTimeScale(config.params), driveTimeScale(config),
                   torqueInput(channel) ? 0.0 : 1.0 / config.params.naturalFrequency()});
}

std::shared_ptr<const CommandProfile> speedOffsetProfile(const RunConfig& config, double speed, double duration)
{
  if (speed == 0.0)
  {
    return nullptr;
  }
  ProfileSegment ramp;
  ramp.kind = ProfileSegment::Kind::Ramp;
  ramp.time = config.initial.time;
  ramp.duration = duration;
  ramp.target = config.command + speed * ramp.duration;
  return std::make_shared<const CommandProfile>(config.command, std::vector<ProfileSegment>{ramp});
}

double frfOutput(FrfChannel c, const State& s)
{
  switch (c)
  {
    case FrfChannel::CommandToLoadPosition:
    case FrfChannel::LoadTorqueToLoadPosition:
      return s.load_position;
    case FrfChannel::TorqueToMotorVelocity:
    case FrfChannel::SetpointToMotorVelocity:
      return s.motor_velocity;
    case FrfChannel::TorqueToLoadVelocity:
    case FrfChannel::SetpointToLoadVelocity:
      return s.load_velocity;
  }
  return NAN;
}

double fastestRate(const ServoParams& p)
{
  const double rho2 = p.gear_ratio * p.gear_ratio;
  double rate = std::max({p.naturalFrequency(), p.motor_friction / p.motor_inertia,
                          p.load_friction / (p.load_inertia + (p.torsionalShaft() ? 0.0 : p.gear_inertia))});
  if (p.compliant())
  {
    // The mesh couples the motor (J_m/ρ² at the load shaft) with the output gear (and the load behind a rigid shaft).
    const double out = p.torsionalShaft() ? p.gear_inertia : p.load_inertia + p.gear_inertia;
    const double inv_mu = rho2 / p.motor_inertia + (out > 0.0 ? 1.0 / out : 0.0);
    rate = std::max({rate, std::sqrt(p.mesh_stiffness * inv_mu), p.mesh_damping * inv_mu});
  }
  if (p.torsionalShaft() && p.gear_inertia > 0.0)
  {
    const double inv = 1.0 / p.gear_inertia + 1.0 / p.load_inertia;
    rate = std::max({rate, std::sqrt(p.shaft_stiffness * inv), p.shaft_damping * inv});
  }
  return rate;
}

namespace
{
/// The work a point may take while it settles, in steps — a sample of the period, or one of the joint's fastest time
/// scales the period spans (the event search follows the motion at that scale): an automatic settling runs at most
/// AUTO_POINT_WORK (a few seconds; a point that has not settled by then says so) and is refused beyond
/// AUTO_LEAST_WORK for its fewest periods; max_periods given, at most MAX_POINT_WORK.
constexpr double AUTO_POINT_WORK = 5e6;
constexpr double AUTO_LEAST_WORK = 2e7;
constexpr double MAX_POINT_WORK = 1e9;
/// A point's events (impacts, apart rests, law switches) beyond its drive's samples, unless max_events says otherwise.
constexpr double POINT_EVENTS = 1e6;
/// The fewest periods a point runs: enough to compare period starts at every multiple up to MAX_PERIOD_MULTIPLE.
constexpr long MIN_PERIODS = 2 * MAX_PERIOD_MULTIPLE + 2;

/**
 * The most periods a point at `sampling` runs to settle: max_periods when given, else 40 of the joint's slowest time
 * constant in [1000, 1e7] periods, fewer where that would take more than AUTO_POINT_WORK (at least MIN_PERIODS).
 * Refuses, naming the figures and the key, a point beyond its budget: max_periods too many, or a period too long
 * against the joint's fastest time scale (or of too many samples) for even MIN_PERIODS.
 */
long settlingPeriods(const RunConfig& config, const FrfSettings& settings, const FrfSampling& sampling)
{
  const double samples = static_cast<double>(sampling.samples_per_period);
  const double period = samples / sampling.rate;              // [s]
  const double scales = period * fastestRate(config.params);  // the joint's fastest time scales a period
  const double per_period = samples + scales;                 // [steps]
  const long given = settings.max_periods;
  const long fewest = given > 0 ? given : MIN_PERIODS;
  const double budget = given > 0 ? MAX_POINT_WORK : AUTO_LEAST_WORK;
  if (static_cast<double>(fewest) * per_period > budget)
  {
    char advice[120];
    const double room = budget / static_cast<double>(fewest) - samples;  // the scales a period may span [steps]
    if (given > 0)
    {
      std::snprintf(advice, sizeof advice, "fewer max_periods");
    }
    else if (scales > samples && room > 0.0)
    {
      std::snprintf(advice, sizeof advice, "measure at %.3g rad/s or above", sampling.frequency * scales / room);
    }
    else
    {
      std::snprintf(advice, sizeof advice, "a higher frequency, or a lower sample rate");
    }
    char text[480];
    std::snprintf(text, sizeof text,
                  "%.6g rad/s: %ld periods of %.3g samples and %.3g of the joint's fastest time scale (%.3g s) each = "
                  "%.3g steps, more than the %.0e a point may take: %s",
                  sampling.frequency, fewest, samples, scales, period / scales,
                  static_cast<double>(fewest) * per_period, budget, advice);
    throw InvalidParameterError(given > 0 ? "max_periods" : "frequency", text);
  }
  if (given > 0)
  {
    return given;
  }
  const double settling = std::min(
      1e7, std::max(1000.0, std::ceil(AUTO_SETTLING_SCALES * slowestTimeScale(config, settings.channel) / period)));
  return static_cast<long>(
      std::min(settling, std::max(static_cast<double>(MIN_PERIODS), std::floor(AUTO_POINT_WORK / per_period))));
}
}  // namespace

FrfSampling frfSampling(const RunConfig& config, const FrfSettings& settings, double omega)
{
  if (!(std::isfinite(omega) && omega > 0.0))
  {
    throw InvalidParameterError("frequency", "must be finite and > 0 rad/s (got " + std::to_string(omega) + ")");
  }
  const bool torque = torqueInput(settings.channel);
  FrfSampling out;
  // The sine itself: the command under the continuous law, or the torque when asked for. Its
  // period is then observed at CONTINUOUS_POINTS instants (the steady-state test and the Fourier pieces' cuts).
  if (setpointInput(settings.channel) && settings.continuous)
  {
    throw InvalidParameterError("continuous",
                                "the set-point injection is the digital drive's, sampled at its "
                                "controller_rate: leave continuous out");
  }
  const bool load = loadTorqueInput(settings.channel);
  if (load && settings.continuous)
  {
    throw InvalidParameterError("continuous", "the load torque's sine is always the sine itself: leave continuous out");
  }
  out.continuous = torque ? settings.continuous : !setpointInput(settings.channel) && !config.drive.sampled();
  if (out.continuous || load)
  {
    requireExactWave(config.params, torque ? "an exact sine torque (--continuous)"
                                    : load ? "a sine load torque"
                                           : "a sine command");
  }
  out.rate = out.continuous ? CONTINUOUS_POINTS * omega / (2.0 * PI)
                            : excitationRate(config, settings.channel, settings.injection_rate);
  const double per_period = out.continuous ? CONTINUOUS_POINTS : 2.0 * PI * out.rate / omega;
  if (per_period < 3.5)
  {
    throw InvalidParameterError("frequency", std::to_string(omega) + " rad/s is above a quarter of the sample rate (" +
                                                 std::to_string(out.rate) + " Hz): at most " +
                                                 std::to_string(2.0 * PI * out.rate / 4.0) + " rad/s");
  }
  if (per_period > 1e9)
  {
    throw InvalidParameterError("frequency", std::to_string(omega) + " rad/s puts more than 1e9 samples in a period");
  }
  out.samples_per_period = std::lround(per_period);
  out.frequency = out.continuous ? omega : 2.0 * PI * out.rate / static_cast<double>(out.samples_per_period);
  out.max_periods = settlingPeriods(config, settings, out);
  return out;
}

namespace
{
void checkFrfInputs(const FrfSettings& settings, double amplitude, double omega)
{
  if (!(std::isfinite(amplitude) && amplitude > 0.0))
  {
    throw InvalidParameterError("amplitude", "must be finite and > 0 (got " + std::to_string(amplitude) + ")");
  }
  if (!(std::isfinite(omega) && omega > 0.0))
  {
    throw InvalidParameterError("frequency", "must be finite and > 0 rad/s (got " + std::to_string(omega) + ")");
  }
  if (!std::isfinite(settings.offset))
  {
    throw InvalidParameterError("offset", "must be finite");
  }
  if (!(settings.tolerance > 0.0 && settings.tolerance < 1.0))
  {
    throw InvalidParameterError("tolerance", "must be in (0, 1) (got " + std::to_string(settings.tolerance) + ")");
  }
  if (settings.max_periods != 0 && settings.max_periods < 3)
  {
    throw InvalidParameterError(
        "max_periods", "must be 0 (automatic) or at least 3 (got " + std::to_string(settings.max_periods) + ")");
  }
  if (settings.harmonics < 1 || settings.harmonics > 1000)
  {
    throw InvalidParameterError("harmonics", "must be in [1, 1000] (got " + std::to_string(settings.harmonics) + ")");
  }
}

/// The sine as the samples see it: sample k at t₀ + k/rate [s], its phase from k mod N (exact however long the run);
/// a torque input `held` is set sample by sample.
struct SampledSine
{
  double t0 = 0.0, rate = 0.0, offset = 0.0, amplitude = 0.0;
  long n_samples = 1;
  bool held = false;

  double time(long k) const { return t0 + static_cast<double>(k) / rate; }
  double input(long k) const
  {
    return offset + amplitude * std::sin(2.0 * PI * static_cast<double>(k % n_samples) / n_samples);
  }
  /// Advances sim over samples [k0, k1), applying a held torque input at each; `each` sees the state at every sample.
  template <class Each>
  void advance(Simulator& s, long k0, long k1, EventSink* sink, const Each& each) const
  {
    for (long k = k0; k < k1; ++k)
    {
      s.advanceTo(time(k), sink);
      each(s.state());
      if (held)
      {
        s.setMotorTorque(input(k), sink);
        s.setInputHorizon(time(k + 1));
      }
    }
    s.advanceTo(time(k1), sink);
  }
};

/// A point's event budget: max_events as the user set it, or — where it is the run's default — POINT_EVENTS beyond
/// the drive's samples over the point's `samples` (an impact storm at a very low frequency, teeth chattering at every
/// reversal, stops the point within seconds, not minutes).
double pointEventBudget(const RunConfig& config, double samples)
{
  return config.max_events == RunConfig().max_events ? std::min(config.max_events, POINT_EVENTS + samples)
                                                     : config.max_events;
}

/// The simulator driven by the sine on the channel's input: the command, a set-point injection, the motor torque or
/// the load torque, for up to `duration` [s].
Simulator sineDrivenSimulator(const RunConfig& config, const FrfSettings& settings, const SampledSine& sine, double w,
                              bool continuous, double duration)
{
  const FrfChannel channel = settings.channel;
  const bool torque = torqueInput(channel), setpoint = setpointInput(channel);
  const double t0 = sine.t0, rate = sine.rate, amplitude = sine.amplitude;
  const long n_samples = sine.n_samples;
  RunConfig run = config;
  run.track_energy = false;
  run.duration = 0.0;
  run.max_events = pointEventBudget(config, config.drive.sampled() ? duration * config.drive.controller_rate : 0.0);
  const bool load = loadTorqueInput(channel);
  if (load)
  {
    // The loop holds the configured command; the load torque's constant part is the offset on top of load_torque.
    run.profile.reset();
    run.params.load_torque += settings.offset;
  }
  else if (setpoint)
  {
    run.profile = speedOffsetProfile(config, settings.offset, duration);
  }
  else if (!torque && !continuous)
  {
    ProfileSegment segment;
    segment.kind = ProfileSegment::Kind::Sine;
    segment.time = t0;
    segment.amplitude = amplitude;
    segment.frequency = rate / static_cast<double>(n_samples);
    segment.duration = duration;
    run.profile = std::make_shared<const CommandProfile>(settings.offset, std::vector<ProfileSegment>{segment});
  }
  Simulator sim = makeSimulator(run);
  if (setpoint)
  {
    sim.sampledDrive()->setInjection(amplitude, n_samples);  // (the next sample is sample 0, at t₀)
  }
  if (load)
  {
    sim.setLoadTorqueWave(Sinusoid{amplitude, w, 0.0, t0});
  }
  else if (continuous)
  {
    const Sinusoid wave{amplitude, w, 0.0, t0};
    torque ? sim.setMotorTorque(settings.offset, wave) : sim.setCommandWave(settings.offset, wave);
  }
  return sim;
}

/// Where the periods repeat: the period starts compared after each period until they do (every multiple up to
/// MAX_PERIOD_MULTIPLE), or to one count of the loop's encoder COUNT_REPEATS times running, or max_periods passed.
constexpr int COUNT_REPEATS = 3;

struct Settling
{
  long n = 0;  ///< periods run
  int multiple = 0, count_multiple = 0, count_streak = 0;
  /// The channel's output at the latest period starts.
  RecentHistory<double> start_outputs{2 * MAX_PERIOD_MULTIPLE + 1};
};

Settling settle(Simulator& sim, const SampledSine& sine, const RunConfig& config, const FrfSettings& settings,
                long max_periods, const std::function<bool()>& cancelled)
{
  const FrfChannel channel = settings.channel;
  const double rho = config.params.gear_ratio, rate = sine.rate;
  const long n_samples = sine.n_samples;
  Settling out;
  long& n = out.n;
  int &multiple = out.multiple, &count_multiple = out.count_multiple, &count_streak = out.count_streak;
  RecentHistory<double>& start_outputs = out.start_outputs;
  // Settle: period starts compared until they repeat (every multiple up to MAX_PERIOD_MULTIPLE). A loop reading a
  // quantised encoder may never repeat to the tolerance, only to its resolution: period starts that repeat within one
  // count [rad at the load] (and one count per sample in the speeds) for COUNT_REPEATS comparisons running are
  // periodic to one count.
  const double count = loopCount(config);
  RecentHistory<Snapshot> starts(2 * MAX_PERIOD_MULTIPLE + 1);
  RecentHistory<Ranges> ranges(2 * MAX_PERIOD_MULTIPLE);
  for (; n <= max_periods; ++n)
  {
    starts.push_back(snapshotOf(sim.state(), rho));
    start_outputs.push_back(frfOutput(channel, sim.state()));
    for (int m = 1; m <= MAX_PERIOD_MULTIPLE && multiple == 0; ++m)
    {
      const std::size_t um = static_cast<std::size_t>(m), un = static_cast<std::size_t>(n);
      if (un < 2 * um)
      {
        continue;
      }
      double angle = 0.0, speed = 0.0;
      for (std::size_t j = un - 2 * um; j < un; ++j)
      {
        angle = std::max(angle, ranges[j].angleScale());
        speed = std::max(speed, ranges[j].speedScale());
      }
      if (repeats(starts, un, um, angle, speed, settings.tolerance))
      {
        multiple = m;
      }
    }
    if (multiple == 0 && count > 0.0)
    {
      int within = 0;
      for (int m = 1; m <= MAX_PERIOD_MULTIPLE && within == 0; ++m)
      {
        if (n >= 2 * m &&
            repeats(starts, static_cast<std::size_t>(n), static_cast<std::size_t>(m), count, count * rate, 1.0))
        {
          within = m;
        }
      }
      count_streak = within != 0 && within == count_multiple ? count_streak + 1 : (within != 0 ? 1 : 0);
      count_multiple = within;
    }
    if (multiple != 0 || count_streak >= COUNT_REPEATS || n == max_periods || (cancelled && cancelled()))
    {
      break;
    }
    Ranges r;
    sine.advance(sim, n * n_samples, (n + 1) * n_samples, nullptr, [&](const State& s) { r.add(snapshotOf(s, rho)); });
    ranges.push_back(r);
  }
  return out;
}

/// The Fourier integrals over the analysed window [k_begin, k_end) samples: Gauss–Legendre over pieces cut at the
/// motion's breaks, each no longer than h_max [s]; the output's and the mesh torque's extremes at the way.
struct WindowSums
{
  std::vector<std::complex<double>> y;     ///< ∫ y e^{−jhω(t − t₀)}, h = 0 … harmonics
  std::complex<double> torque_line = 0.0;  ///< ∫ T_m e^{−jω(t − t₀)}: the set-point channels' input
  std::complex<double> mesh_line = 0.0;    ///< ∫ Q e^{−jω(t − t₀)}
  double mesh_sum = 0.0, mesh_lo = INFINITY, mesh_hi = -INFINITY;
  double lo = INFINITY, hi = -INFINITY;  ///< the output at the samples
};

WindowSums integrateWindow(Simulator& sim, const SampledSine& sine, const std::vector<double>& break_times,
                           long k_begin, long k_end, FrfChannel channel, int harmonics, double w, double h_max)
{
  const bool setpoint = setpointInput(channel), held = sine.held;
  const long n_samples = sine.n_samples;
  WindowSums out;
  out.y.assign(static_cast<std::size_t>(harmonics) + 1, 0.0);
  std::vector<std::complex<double>>& y = out.y;
  std::complex<double>&torque_line = out.torque_line, &mesh_line = out.mesh_line;
  double &mesh_sum = out.mesh_sum, &mesh_lo = out.mesh_lo, &mesh_hi = out.mesh_hi, &lo = out.lo, &hi = out.hi;
  std::size_t next_break = 0;
  for (long k = k_begin; k < k_end; ++k)
  {
    const double ta = sine.time(k), tb = sine.time(k + 1);
    sim.advanceTo(ta);
    const double at_sample = frfOutput(channel, sim.state());
    lo = std::min(lo, at_sample);
    hi = std::max(hi, at_sample);
    const double q_sample = sim.plant().meshTorque();
    mesh_lo = std::min(mesh_lo, q_sample);
    mesh_hi = std::max(mesh_hi, q_sample);
    if (held)
    {
      sim.setMotorTorque(sine.input(k));
      sim.setInputHorizon(tb);
    }
    // The interval's pieces: cut at its breaks, each no longer than h_max.
    std::vector<double> cuts = {ta};
    while (next_break < break_times.size() && break_times[next_break] <= ta)
    {
      ++next_break;
    }
    while (next_break < break_times.size() && break_times[next_break] < tb)
    {
      if (break_times[next_break] > cuts.back())
      {
        cuts.push_back(break_times[next_break]);
      }
      ++next_break;
    }
    cuts.push_back(tb);
    const double phase0 = 2.0 * PI * static_cast<double>(k % n_samples) / static_cast<double>(n_samples);
    for (std::size_t c = 0; c + 1 < cuts.size(); ++c)
    {
      const double len = cuts[c + 1] - cuts[c];
      const long pieces = std::max(1L, static_cast<long>(std::ceil(len / h_max)));
      const double h = len / static_cast<double>(pieces);
      for (long p = 0; p < pieces; ++p)
      {
        const double a = cuts[c] + h * static_cast<double>(p);
        for (int i = 0; i < 8; ++i)
        {
          const double t = a + 0.5 * h * (1.0 + GAUSS_NODE[i]);
          sim.advanceTo(t);
          const double v = frfOutput(channel, sim.state());
          const double theta = phase0 + w * (t - ta);
          const double wt = GAUSS_WEIGHT[i] * 0.5 * h;
          y[0] += wt * v;
          for (int j = 1; j <= harmonics; ++j)
          {
            y[static_cast<std::size_t>(j)] += wt * v * std::polar(1.0, -j * theta);
          }
          if (setpoint)
          {
            torque_line += wt * sim.plant().motorTorque() * std::polar(1.0, -theta);
          }
          const double q = sim.plant().meshTorque();
          mesh_sum += wt * q;
          mesh_line += wt * q * std::polar(1.0, -theta);
          mesh_lo = std::min(mesh_lo, q);
          mesh_hi = std::max(mesh_hi, q);
        }
      }
    }
  }
  return out;
}
}  // namespace

FrfPoint measureFrequencyResponse(const RunConfig& config, const FrfSettings& settings, double amplitude, double omega,
                                  const std::function<bool()>& cancelled)
{
  checkFrfInputs(settings, amplitude, omega);
  const FrfChannel channel = settings.channel;
  const bool torque = torqueInput(channel), setpoint = setpointInput(channel);
  const FrfSampling sampling = frfSampling(config, settings, omega);
  const bool continuous = sampling.continuous;
  const double rate = sampling.rate;
  const long n_samples = sampling.samples_per_period;
  FrfPoint out;
  out.amplitude = amplitude;
  out.requested_frequency = omega;
  out.samples_per_period = static_cast<int>(n_samples);
  out.frequency = sampling.frequency;
  const double w = out.frequency, period = static_cast<double>(n_samples) / rate;
  const double t0 = config.initial.time;
  const long max_periods = sampling.max_periods;
  SampledSine sine;
  sine.t0 = t0;
  sine.rate = rate;
  sine.offset = settings.offset;
  sine.amplitude = amplitude;
  sine.n_samples = n_samples;
  sine.held = torque && !continuous;  // the torque set sample by sample

  Simulator sim = sineDrivenSimulator(config, settings, sine, w, continuous,
                                      period * (static_cast<double>(max_periods) + MAX_PERIOD_MULTIPLE + 2.0));
  const Settling settled = settle(sim, sine, config, settings, max_periods, cancelled);
  const long n = settled.n;
  const int multiple = settled.multiple, count_multiple = settled.count_multiple;
  const int count_streak = settled.count_streak;
  const RecentHistory<double>& start_outputs = settled.start_outputs;
  out.periodic_to_count = multiple == 0 && count_streak >= COUNT_REPEATS;
  out.periodic = multiple != 0 || out.periodic_to_count;
  out.period_multiple = multiple != 0 ? multiple : (out.periodic_to_count ? count_multiple : 0);
  const int m = std::max(1, out.period_multiple);
  // The analysed window [t_n, t_n + mT]: its breaks found on a copy, then integrated on the original, which passes
  // through the same events bit for bit (the motion does not depend on where it is stopped).
  const long k_begin = n * n_samples, k_end = (n + m) * n_samples;
  out.settled_at = sine.time(k_begin);
  out.settled_state = sim.state();
  BreakSink breaks;
  {
    Simulator probe = sim;
    sine.advance(probe, k_begin, k_end, &breaks, [](const State&) {});
  }
  out.flank_changes = static_cast<double>(breaks.flankChanges()) / m;
  out.separations = static_cast<double>(breaks.separations) / m;
  const double h_max = 0.5 / std::max(fastestRate(config.params), 1e-300);
  const int harmonics = settings.harmonics;
  const WindowSums sums = integrateWindow(sim, sine, breaks.breaks, k_begin, k_end, channel, harmonics, w, h_max);
  const std::vector<std::complex<double>>& y = sums.y;
  const double lo = sums.lo, hi = sums.hi;
  sim.advanceTo(sine.time(k_end));
  const double span = period * m;
  out.mean = y[0].real() / span;
  out.peak_to_peak = hi - lo;
  out.mesh_torque_mean = sums.mesh_sum / span;
  out.mesh_torque_min = sums.mesh_lo;
  out.mesh_torque_max = sums.mesh_hi;
  if (continuous && breaks.flankChanges() == 0 && breaks.separations == 0 && m == 1)
  {
    // The sine itself on one flank: the mesh torque is its mean and its fundamental (the joint is linear there).
    const double q1 = std::abs(2.0 / span * sums.mesh_line);
    out.mesh_torque_min = out.mesh_torque_mean - q1;
    out.mesh_torque_max = out.mesh_torque_mean + q1;
  }
  // Y_h = (2/span)∫ y e^{−jhω(t − t₀)} over the window of m periods (a subharmonic's own lines at ω/m are not read).
  std::vector<std::complex<double>> coef(static_cast<std::size_t>(harmonics) + 1);
  for (int j = 1; j <= harmonics; ++j)
  {
    coef[static_cast<std::size_t>(j)] = 2.0 / span * y[static_cast<std::size_t>(j)];
  }
  // The input's fundamental as a phasor: −jA for the sine itself; the applied torque's for the set-point channels.
  const std::complex<double> u1 = setpoint ? 2.0 / span * sums.torque_line : std::complex<double>(0.0, -amplitude);
  out.response = coef[1] / u1;
  out.gain = std::abs(out.response);
  out.phase = std::arg(out.response);
  double distortion = 0.0;
  for (int j = 2; j <= harmonics; ++j)
  {
    distortion += std::norm(coef[static_cast<std::size_t>(j)]);
  }
  out.distortion = std::abs(coef[1]) > 0.0 ? std::sqrt(distortion) / std::abs(coef[1]) : 0.0;
  out.periods = static_cast<int>(n + m);
  if (out.periodic_to_count)
  {
    // How far the last period starts differ beyond a steady drift, against the output's fundamental amplitude.
    const std::size_t un = static_cast<std::size_t>(n), um = static_cast<std::size_t>(m);
    const double second =
        (start_outputs[un] - start_outputs[un - um]) - (start_outputs[un - um] - start_outputs[un - 2 * um]);
    out.count_spread = std::abs(coef[1]) > 0.0 ? std::fabs(second) / std::abs(coef[1]) : NAN;
  }
  return out;
}

double releaseAmplitude(const FrfPoint& linear)
{
  const double mean = linear.mesh_torque_mean;
  const double swing = mean >= 0.0 ? mean - linear.mesh_torque_min : linear.mesh_torque_max - mean;
  if (!linear.periodic || !(swing > 0.0))
  {
    return NAN;
  }
  // A mean within what the steady state's detection leaves of a transient (1e-8 of the swing, the default
  // tolerance) holds nothing: the teeth leave the flank at any amplitude.
  if (std::fabs(mean) <= 1e-8 * swing)
  {
    return 0.0;
  }
  return linear.amplitude * std::fabs(mean) / swing;
}

}  // namespace backlash_servo
