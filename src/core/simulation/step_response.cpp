#include "backlash_servo/simulation/step_response.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/simulation/steady_state.h"

namespace backlash_servo
{
namespace
{
/// Running until settled, each chunk (a natural period) is advanced in this many steps, so that the run stops within
/// one of them after the maximum that settles the verdict.
constexpr int SETTLE_STEPS = 16;

/// Feeds every event to the monitor and forwards it.
class Tee : public EventSink
{
 public:
  Tee(ResponseMonitor* monitor, EventSink* next) : monitor_(monitor), next_(next) {}
  void onEvent(const Event& e) override
  {
    monitor_->onEvent(e);
    if (next_ != nullptr)
    {
      next_->onEvent(e);
    }
  }
  bool wantsImpacts() const override { return monitor_->wantsImpacts() || (next_ != nullptr && next_->wantsImpacts()); }

 private:
  ResponseMonitor* monitor_;
  EventSink* next_;
};

/**
 * The tracking figures of a run sampled every dt [s] from t₀: in the run's own pass, every advanceTo of the run goes
 * through advanceTo() here, which stops at the sample times t₀ + k·dt on the way — the plant's closed forms stay
 * anchored where their segments began, so the run is the same to the bit — and takes each sample as
 * replayTracking()'s replay does (record(): a drive's sample due there taken first, as a drive logs its torque).
 */
class TrackingPass
{
 public:
  static constexpr double MAX_SAMPLES = 1e6;

  /// rate: samples a second [Hz]; t_end: the run's end as known at the start [s] (+inf: until settled, when the
  /// pass gives up past MAX_SAMPLES: replayTracking() would lower the rate).
  TrackingPass(const RunConfig& config, double rate, double t_end)
      : metrics_(trackingOf(config, 1.0 / rate, t_end)),
        rate_(rate),
        dt_(1.0 / rate),
        t_end_(t_end),
        t0_(config.initial.time),
        profile_(config.profile.get()),
        command_(config.command)
  {}

  /// Advances sim to t [s], sampling every grid time before it (the run's own sink sees every event).
  void advanceTo(Simulator& sim, double t, EventSink* sink)
  {
    for (double ts = nextTime(); on_ && ts < t; ts = nextTime())
    {
      sim.advanceTo(ts, sink);
      sim.takeSampleDue(sink);
      record(sim);
      if (std::isinf(t_end_) && static_cast<double>(next_) > MAX_SAMPLES + 1.0)
      {
        on_ = false;  // a run until settled past the sample budget: replayTracking() lowers the rate instead
      }
    }
    sim.advanceTo(t, sink);
  }
  /// One sample: the state of sim now, the reference there and the motor torque.
  void record(const Simulator& sim)
  {
    const State& s = sim.state();
    metrics_.add(s.time, profile_ ? profile_->at(s.time) : command_, s.load_position, sim.motorTorque());
    ++next_;
  }
  /// The last sample, at the run's end (a drive's sample due there taken first; the run's summary is taken).
  void finish(Simulator& sim)
  {
    sim.takeSampleDue(nullptr);
    record(sim);
  }
  /// The figures of the samples so far for a run that ended as `run` did (its cycle tells whether it keeps leaving
  /// the band).
  TrackingFigures figuresOf(const RunSummary& run) const
  {
    const double command = profile_ ? profile_->finalValue() : command_;
    return metrics_.figures(t0_ + run.simulated, dt_, cycleLeavesBand(run.status, run.cycle, command, metrics_.band()));
  }
  /// Every grid sample was taken (not given up past MAX_SAMPLES).
  bool complete() const { return on_; }
  double rate() const { return rate_; }
  /// The run's end assumed at the start [s] (+inf: until settled).
  double assumedEnd() const { return t_end_; }

 private:
  double nextTime() const { return t0_ + static_cast<double>(next_) * dt_; }

  TrackingMetrics metrics_;
  double rate_, dt_, t_end_, t0_;
  const CommandProfile* profile_;
  double command_;
  long next_ = 0;  // samples taken, the initial one included
  bool on_ = true;
};

/// The tracking figures' sample rate [Hz] before any lowering: the digital drive's rate, else 100 samples per
/// natural period 2π/ω_n.
double nominalTrackingRate(const RunConfig& config)
{
  return config.drive.sampled() ? config.drive.controller_rate : 100.0 * config.params.naturalFrequency() / (2.0 * PI);
}

/// replayTracking()'s rate for a run of `simulated` [s]: the nominal rate, lowered to keep within `max_samples`.
double trackingRateFor(const RunConfig& config, double simulated, double max_samples)
{
  const double rate = nominalTrackingRate(config);
  return simulated * rate > max_samples ? max_samples / simulated : rate;
}
}  // namespace

void checkProfile(const RunConfig& config)
{
  if (config.profile)
  {
    config.profile->requireTakenBy(config.drive.sampled(), config.params.hasDryFriction(), config.params.compliant());
  }
}

double driveTimeScale(const RunConfig& config)
{
  const DriveParams& d = config.drive;
  double slowest = 0.0;
  auto consider = [&](double numerator, double rate) {
    if (rate > 0.0 && numerator > 0.0)
    {
      slowest = std::max(slowest, numerator / rate);
    }
  };
  if (d.sampled() && d.control_law == "pid")
  {
    consider(config.params.gain, d.integral_gain);
  }
  if (d.sampled() && d.control_law == "cascade")
  {
    consider(1.0, d.position_loop_gain);
    consider(d.velocity_loop_gain, d.velocity_loop_integral_gain);
  }
  if (d.compensation == "dual_loop")
  {
    consider(1.0, d.outer_loop_gain);
  }
  if (d.compensation == "dither")
  {
    consider(1.0, d.dither_frequency);
  }
  return slowest;
}

double plantTimeScale(const ServoParams& p)
{
  double slowest = 0.0;
  for (const auto& [inertia, friction] :
       {std::pair{p.motor_inertia, p.motor_friction}, std::pair{p.load_inertia, p.load_friction}})
  {
    if (friction > 0.0)
    {
      slowest = std::max(slowest, inertia / friction);
    }
  }
  return slowest;
}

double loopCount(const RunConfig& config)
{
  const DriveParams& d = config.drive;
  if (d.sampled() && d.feedback == "motor" && d.motor_encoder_resolution > 0.0)
  {
    return config.params.gear_ratio * TWO_PI / d.motor_encoder_resolution;
  }
  if (d.sampled() && d.feedback != "motor" && d.load_encoder_resolution > 0.0)
  {
    return TWO_PI / d.load_encoder_resolution;
  }
  return 0.0;
}

CycleResolution cycleResolution(const CycleShape& cycle, double count)
{
  CycleResolution r;
  if (!std::isfinite(cycle.peak_to_peak))
  {
    return r;
  }
  constexpr double ARCMIN_PER_RAD = 10800.0 / 3.14159265358979323846;
  r.arcmin = cycle.peak_to_peak * ARCMIN_PER_RAD;
  if (count > 0.0)
  {
    r.counts = cycle.peak_to_peak / count;
    r.below_count = r.counts < 1.0;
  }
  return r;
}

double settlingBand(const RunConfig& config, double excursion)
{
  if (config.settling_band > 0.0)
  {
    return config.settling_band;
  }
  const double own = std::max(config.params.backlash, loopCount(config));
  return own > 0.0 ? own : 0.02 * std::max(excursion, 1e-12);
}

TrackingMetrics trackingOf(const RunConfig& config, double dt, double t_end)
{
  const double t0 = config.initial.time;
  if (!config.profile)
  {
    const double step = config.command - config.initial.load_position;
    return TrackingMetrics(settlingBand(config, std::fabs(step)), t0, config.command, step >= 0.0 ? 1.0 : -1.0);
  }
  const CommandProfile& profile = *config.profile;
  const double final_ref = profile.finalValue();
  const double profile_end = profile.endTime();
  // The reference's excursion over the samples (for the classical 2 % band) and the direction of its last move.
  double lo = profile.at(t0), hi = lo;
  const double scan_end = std::min(t_end, std::max(profile_end, t0));  // constant from its end on
  const long n = static_cast<long>(std::floor((scan_end - t0) / dt + 1e-9));
  for (long k = 0; k <= n; ++k)
  {
    const double r = profile.at(t0 + k * dt);
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  const double before_end = profile.at(std::max(0.0, profile_end - 1e-9));
  double direction = final_ref >= before_end ? 1.0 : -1.0;
  if (final_ref == before_end)
  {
    direction = final_ref >= profile.at(0.0) ? 1.0 : -1.0;
  }
  return TrackingMetrics(settlingBand(config, hi - lo), profile_end, final_ref, direction);
}

TrackingFigures replayTracking(const RunConfig& config, const RunSummary& run, double* sample_rate)
{
  const double rate = trackingRateFor(config, run.simulated, TrackingPass::MAX_SAMPLES);
  *sample_rate = rate;
  TrackingPass replayed(config, rate, config.initial.time + run.simulated);
  if (run.stopped_by == "diverged" || !(run.simulated > 0.0))
  {
    return replayed.figuresOf(run);  // nothing to replay (a runaway motion has no tracking figures)
  }
  RunConfig replay = config;
  replay.duration = run.simulated;
  replay.track_energy = false;
  replay.tracking = false;
  replay.steady_answer = false;
  runResponse(replay, nullptr, 1.0 / rate, [&](const Simulator& sim) { replayed.record(sim); });
  return replayed.figuresOf(run);
}

bool cycleLeavesBand(const LimitCycleReport& status, const CycleShape& cycle, double command, double band)
{
  const bool sustained = status.verdict == Verdict::LimitCycle || status.verdict == Verdict::Irregular;
  return sustained && std::max(std::fabs(cycle.top - command), std::fabs(cycle.bottom - command)) > band;
}

Simulator makeSimulator(const RunConfig& config)
{
  checkProfile(config);
  const double command = config.profile ? config.profile->finalValue() : config.command;
  const double t0 = config.initial.time;
  // With a profile the law starts from θ_R(t₀) (a digital drive's first sample reads it there).
  Simulator sim(config.params, config.initial, config.profile ? config.profile->at(t0) : command);
  // The simulator's own law is the thesis' plain P law; any other (digital, saturated, compensated) is the drive's.
  if (!config.drive.thesisLaw())
  {
    sim.setDrive(makePositionDrive(config.drive, config.params.gain, config.params.gear_ratio, sim.command(), t0));
  }
  if (config.profile)
  {
    sim.setProfile(config.profile);
  }
  sim.setEnergyTracking(config.track_energy);
  sim.setShortFlights(config.short_flights);
  sim.setEventBudget(static_cast<std::uint64_t>(config.max_events));
  return sim;
}

namespace
{
/// The figures of a run's own pass into out->tracking, or — where they could differ from replayTracking()'s (its rate
/// lowered after all, its end not the one assumed at the start, a run cut short) — the replay's.
void finishTracking(const RunConfig& config, TrackingPass* pass, Simulator& sim, RunSummary* out)
{
  const double rate = trackingRateFor(config, out->simulated, TrackingPass::MAX_SAMPLES);
  const double t_end = config.initial.time + out->simulated;
  const bool same_end =
      !config.profile || std::min(pass->assumedEnd(), std::max(config.profile->endTime(), config.initial.time)) ==
                             std::min(t_end, std::max(config.profile->endTime(), config.initial.time));
  const bool cut_short = out->stopped_by == "event_budget" || out->stopped_by == "diverged" || !(out->simulated > 0.0);
  if (!pass->complete() || cut_short || rate != pass->rate() || !same_end || sim.state().time != t_end)
  {
    out->tracking = replayTracking(config, *out, &out->tracking_rate);
    return;
  }
  pass->finish(sim);
  out->tracking_rate = rate;
  out->tracking = pass->figuresOf(*out);
}
}  // namespace

namespace
{
/// The run's summary from the monitor and the simulator where the run stopped (out->stopped_by set).
void summarise(const RunConfig& config, Simulator& sim, const ResponseMonitor& monitor, double command,
               RunSummary* summary)
{
  RunSummary& out = *summary;
  const double t0 = config.initial.time;
  out.status = monitor.status();
  if (out.stopped_by == "diverged")
  {
    out.status.verdict = Verdict::Diverged;
  }
  out.maxima = monitor.maxima();
  out.cycle = monitor.cycleShape();
  out.resolution = cycleResolution(out.cycle, loopCount(config));
  out.impacts = sim.impactCount();
  out.contact_phases = sim.contactPhases();
  out.energy = sim.energy();
  if (!sim.energyValid())
  {
    // A ramp of the continuous law ran in its moving frame: the plant's ledger is the frame's, not the joint's; a
    // compliant mesh keeps none.
    for (double* f : {&out.energy.input, &out.energy.motor_friction, &out.energy.load_friction, &out.energy.impact_loss,
                      &out.energy.load_work, &out.energy.motor_dry_friction, &out.energy.load_dry_friction,
                      &out.energy.input_magnitude, &out.energy.initial_kinetic})
    {
      *f = NAN;
    }
  }
  out.kinetic = sim.kineticEnergy();
  out.balance_error = sim.energyBalanceError();
  out.final_state = sim.state();
  out.simulated = sim.state().time - t0;
  out.equilibrium = monitor.equilibrium();
  out.settled = monitor.settled();
  if (config.steady_answer && out.status.verdict == Verdict::Converged)
  {
    out.steady = steadyAnswer(sim, config.drive, command, out.equilibrium, monitor.scale());
  }
}
}  // namespace

namespace
{
/**
 * One run of runResponse(): the simulator, the monitor that judges it and the tracking pass, advanced chunk by chunk
 * (a controller period for a sampled run, a natural period otherwise) until the run stops.
 */
class ResponseRun
{
 public:
  ResponseRun(const RunConfig& config, EventSink* sink, double sample_period)
      : config_(config),
        command_(config.profile ? config.profile->finalValue() : config.command),
        t0_(config.initial.time),
        sample_period_(sample_period),
        until_settled_(config.duration <= 0.0),
        sim_(makeSimulator(config)),
        monitor_(config.params, command_, loopEquilibrium(config.params, config.drive, command_), config.initial,
                 sim_.drive().sampled()),
        tee_(&monitor_, sink)
  {
    startTracking();
    // With a profile the verdict is judged from its end on, against its final value: a fresh monitor there (a hunt
    // around an intermediate set-point is not the final limit cycle).
    judge_from_ = config.profile && config.profile->endTime() > t0_ ? config.profile->endTime() : -INFINITY;
    t_stop_ = t0_ + (until_settled_
                         ? (config.max_duration > 0.0 ? config.max_duration : steadyBudget(config.params, config.drive))
                         : config.duration);
    chunk_ = sample_period > 0.0 ? sample_period : 2.0 * PI / config.params.naturalFrequency();
  }

  const Simulator& simulator() const { return sim_; }
  /// The end of the i-th chunk [s].
  double chunkEnd(long i) const { return std::min(t0_ + static_cast<double>(i) * chunk_, t_stop_); }

  /// Advances to t [s] (restarting the verdict where a profile ends); false when the run stopped on the way (why in
  /// out->stopped_by and out->message).
  bool advanceChunk(double t, RunSummary* out)
  {
    try
    {
      if (judge_from_ >= sim_.state().time && judge_from_ <= t)
      {
        advance(judge_from_);
        monitor_.restartAt(sim_.state());
        judge_from_ = -INFINITY;
      }
      if (settledWithin(t))
      {
        out->stopped_by = "settled";
        return false;
      }
      advance(t);
    }
    catch (const EventBudgetExceeded& e)
    {
      out->stopped_by = "event_budget";
      out->message = e.what();
      return false;
    }
    catch (const MotionDiverged& e)
    {
      out->stopped_by = "diverged";
      out->message = e.what();
      return false;
    }
    return true;
  }

  /// A sample on a controller update (to rounding: t_k = k/f and i·T differ in their last bits) shows the torque
  /// applied from it on, as a drive logs it — not, now and then, the one before.
  void takeSampleDue() { sim_.takeSampleDue(&tee_); }

  /// The verdict's tests at a chunk's end t [s]; a run until settled without a cap of the user's then lasts at least
  /// REPETITIONS times the slowest oscillation seen (the longest interval between maxima): a stick–slip hunt or a
  /// slow drive loop whose cycle is long against 2π/ω_n (ω_n is the P law's; it means nothing for a PID or a
  /// cascade) is given the repetitions its verdict needs.
  void check()
  {
    constexpr double REPETITIONS = 100.0;
    monitor_.check(sim_.state(), sim_.drive().winding(), judging() && sim_.atRestForever());
    if (until_settled_ && config_.max_duration <= 0.0)
    {
      t_stop_ = std::max(t_stop_, t0_ + REPETITIONS * monitor_.longestInterval());
    }
  }

  /// The share of the run done at t [s], in [0, 1].
  double progress(double t) const { return (t - t0_) / (t_stop_ - t0_); }

  /// Whether the run ends at the chunk's end t [s] (why in out->stopped_by). A convergence seen in the decay of the
  /// maxima alone runs on until the joint is near its equilibrium, so that the steady error is the joint's, not a
  /// point of a wide swing.
  bool endsAt(double t, RunSummary* out) const
  {
    if (until_settled_ && monitor_.settled() && judging() &&
        (monitor_.status().verdict != Verdict::Converged || monitor_.convergedNear(sim_.state())))
    {
      out->stopped_by = "settled";
      return true;
    }
    if (t >= t_stop_)
    {
      out->stopped_by = until_settled_ ? "max_duration" : "duration";
      return true;
    }
    return false;
  }

  /// The run's summary and tracking figures into out (out->stopped_by set).
  void finish(RunSummary* out)
  {
    summarise(config_, sim_, monitor_, command_, out);
    if (pass_)
    {
      finishTracking(config_, &*pass_, sim_, out);
    }
  }

 private:
  /// The tracking figures in this pass, at the rate replayTracking() would choose when the run's length is known now
  /// (a run until settled: the nominal rate, replayed at a lower one only when it outlasts the sample budget).
  void startTracking()
  {
    if (!config_.tracking)
    {
      return;
    }
    const double rate = until_settled_ ? nominalTrackingRate(config_)
                                       : trackingRateFor(config_, config_.duration, TrackingPass::MAX_SAMPLES);
    pass_.emplace(config_, rate, until_settled_ ? INFINITY : t0_ + config_.duration);
    pass_->record(sim_);  // (the state as constructed: no drive sample taken yet)
  }

  void advance(double t)
  {
    if (pass_)
    {
      pass_->advanceTo(sim_, t, &tee_);
    }
    else
    {
      sim_.advanceTo(t, &tee_);
    }
  }

  /// Whether the verdict is judged now (not before a profile's end).
  bool judging() const { return judge_from_ == -INFINITY; }

  /// Running until settled unsampled, a sustained oscillation settled by a maximum ends the run within a sub-step of
  /// it, not at the chunk's end t [s] (up to a natural period later: in elastic chatter, 10⁵ impacts). Its figures
  /// come from the maxima, and the motion does not depend on where advanceTo stops: the same verdict, error and
  /// period. (A convergence runs on to the chunk's end: its steady error is read there; the rest tests run at chunk
  /// ends only. Sub-steps only once four maxima are recorded: no sustained oscillation is settled before its fifth.)
  bool settledWithin(double t)
  {
    if (!until_settled_ || sample_period_ > 0.0 || monitor_.judged().size() < 4)
    {
      return false;
    }
    const double from = sim_.state().time;
    for (int k = 1; k < SETTLE_STEPS && !monitor_.oscillating(); ++k)
    {
      advance(from + (t - from) * k / SETTLE_STEPS);
    }
    return monitor_.oscillating() && judging();
  }

  const RunConfig& config_;
  const double command_;  ///< the set-point judged against [rad]
  const double t0_;       ///< [s]
  const double sample_period_;
  const bool until_settled_;
  Simulator sim_;
  ResponseMonitor monitor_;
  Tee tee_;
  std::optional<TrackingPass> pass_;
  double judge_from_ = -INFINITY;  ///< where the verdict starts [s]; -inf once it has
  double t_stop_ = 0.0;            ///< [s]
  double chunk_ = 0.0;             ///< [s]
};
}  // namespace

RunSummary runResponse(const RunConfig& config, EventSink* sink, double sample_period, const SampleCallback& on_sample,
                       const ProgressCallback& on_progress)
{
  ResponseRun run(config, sink, sample_period);
  RunSummary out;
  if (on_sample)
  {
    on_sample(run.simulator());
  }
  for (long i = 1;; ++i)
  {
    const double t = run.chunkEnd(i);
    if (!run.advanceChunk(t, &out))
    {
      break;
    }
    if (on_sample && sample_period > 0.0)
    {
      run.takeSampleDue();
      on_sample(run.simulator());
    }
    run.check();
    if (on_progress)
    {
      on_progress(run.progress(t));
    }
    if (run.endsAt(t, &out))
    {
      break;
    }
  }
  run.finish(&out);
  return out;
}

}  // namespace backlash_servo
