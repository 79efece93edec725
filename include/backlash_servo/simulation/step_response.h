/**
 * @file step_response.h
 * @brief One complete run: simulate a response, watch its maxima, stop when the limit-cycle verdict is settled.
 *
 * Shared by backlash_sim, the sweep and design tools and the benchmarks, so they all judge a run the same way.
 * No ROS dependency.
 */
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "backlash_servo/model/run_config.h"
#include "backlash_servo/simulation/response_monitor.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/steady_state.h"
#include "backlash_servo/simulation/tracking_metrics.h"

namespace backlash_servo
{
/// A sustained oscillation's size as the loop and a gearbox catalogue see it.
struct CycleResolution
{
  double counts = NAN;       ///< peak to peak in counts of the encoder the loop reads (NaN: ideal sensor, no cycle)
  double arcmin = NAN;       ///< peak to peak at the load [arcmin] (NaN: no cycle)
  bool below_count = false;  ///< under one count: a hunt the loop's own sensor cannot see
};

struct RunSummary
{
  LimitCycleReport status;
  std::vector<Maximum> maxima;  ///< positive maxima above the command, in time order (a profile: from its end on)
  CycleShape
      cycle;  ///< a sustained oscillation's peak-to-peak amplitude and centre [rad] (ResponseMonitor::cycleShape)
  CycleResolution resolution;  ///< the cycle in encoder counts and arcmin (cycleResolution(), loopCount())
  std::uint64_t impacts = 0;
  std::uint64_t contact_phases = 0;  ///< contact phases of a compliant mesh (0 with rigid teeth)
  EnergyLedger energy;
  double kinetic = 0.0;        ///< kinetic energy at the end [J]
  double balance_error = 0.0;  ///< energy balance residual [J]
  State final_state;
  double simulated = 0.0;  ///< simulated time [s]
  /// Where the loop rests [rad] (loopEquilibrium: θ_R shifted by ρT_ext/K unless integral action removes the offset),
  /// against which the verdict judged the maxima.
  double equilibrium = 0.0;
  bool settled = false;  ///< the verdict was settled (not cut off by the duration or the cap)
  /// Where a converged joint comes to rest and its steady error θ_∞ − θ_R [rad] (steady_state.h): the limit, not
  /// the offset at the end of the run. Basis None unless the verdict is converged.
  SteadyAnswer steady;
  /// With RunConfig::tracking: the tracking figures and their sample rate [Hz] (NaN without).
  TrackingFigures tracking;
  double tracking_rate = NAN;
  /// Why the run ended: "settled", "duration" (the requested length), "max_duration" (the cap), "event_budget",
  /// "diverged" (the motion ran away: verdict Diverged).
  std::string stopped_by;
  std::string message;  ///< for "event_budget": what was exceeded, where; for "diverged": where the motion ran away
};

/**
 * The drive's slowest own time constant [s]: a PID's integral time K/K_i, a cascade's 1/K_p and K_v/K_vi, a dual
 * loop's 1/K_o, a dither's period (0 for the P law). Before any oscillation shows, a run until settled lasts at most
 * max(2000/ω_n, 100 × the slower of this and plantTimeScale()) — the loop's scale under the gain K, or a hundred
 * of the drive's or the plant's own — and then at least 100 × the slowest oscillation seen.
 */
double driveTimeScale(const RunConfig& config);

/**
 * The plant's slowest own time constant [s]: the larger of the bodies' viscous decay times J_m/f_m and J_L/f_L (a
 * body without viscous friction has none) — how long a load coasting in the backlash, or a motor left without torque,
 * takes to slow down. Before any oscillation shows, a run until settled lasts at most max(2000/ω_n, 100 × the slower
 * of this and driveTimeScale()).
 */
double plantTimeScale(const ServoParams& params);

/// One count of the encoder the loop reads, referred to the load [rad]: 2π/N_L with load feedback, ρ·2π/N_m with
/// motor feedback; 0 for an ideal sensor or the continuous law.
double loopCount(const RunConfig& config);

/// The resolution figures of `cycle` (CycleShape) for a loop reading `count` [rad] (loopCount()).
CycleResolution cycleResolution(const CycleShape& cycle, double count);

/**
 * The error band [rad] of a run's settling figures: `settling_band` when set, else the joint's own resolution — the
 * larger of the backlash Δ (a load read through the motor cannot be placed better) and one count of the encoder the
 * loop reads (2π/N_L on the load, ρ·2π/N_m through the motor) — and, with neither, 2 % of `excursion` [rad] (the
 * command's travel), the classical band.
 */
double settlingBand(const RunConfig& config, double excursion);

/**
 * The tracking figures' accumulator of a run sampled every dt [s] up to t_end [s] (may be +inf): its reference stops
 * moving at the profile's end (the initial time for a step), its band is settlingBand() of the reference's excursion
 * (the profile's range over the samples, or the step |θ_R − θ_c(0)|), its overshoot is measured in the direction of
 * the last move.
 */
TrackingMetrics trackingOf(const RunConfig& config, double dt, double t_end);

/**
 * The tracking figures of a finished run (settling time, RMS errors, overshoot, torque), from a replay of the same
 * motion for the same simulated time sampled at `*sample_rate` [Hz]: the digital drive's rate, else 100 samples per
 * natural period 2π/ω_n, lowered to keep the replay within 1e6 samples (the rate used is written back). The run
 * itself stays exact and untouched (its stop and events do not depend on the sampling); the figures are a data
 * logger's view of it. RunConfig::tracking gives the same figures from the run's own pass, without the replay.
 */
TrackingFigures replayTracking(const RunConfig& config, const RunSummary& run, double* sample_rate);

/// Whether the verdict is a sustained oscillation whose cycle reaches beyond `band` [rad] from the final command
/// [rad]: it never settles into that band (TrackingMetrics::figures' `leaves_band`).
bool cycleLeavesBand(const LimitCycleReport& status, const CycleShape& cycle, double command, double band);

/// The simulator of a run at its start: the plant in its initial state under the configured law (the thesis' P law,
/// or the drive: digital, saturated or compensated) following the command or the profile, with the run's energy
/// tracking and event budget. Throws InvalidParameterError for a profile the law cannot take.
Simulator makeSimulator(const RunConfig& config);

/// Called at every sample time (sample_period > 0) with the simulator positioned there.
using SampleCallback = std::function<void(const Simulator&)>;
/// Called after every chunk with the fraction of the longest possible run done, in [0, 1].
using ProgressCallback = std::function<void(double)>;

/// Throws InvalidParameterError("profile", …) for a profile the control law cannot take (a sine or move, or a ramp
/// with dry friction, under the continuous law).
void checkProfile(const RunConfig& config);

/**
 * Runs config; events go to sink (may be null) as well as to the response monitor (checked every natural period,
 * or at every sample; running until settled without samples, an oscillation stops within 1/16 of a natural period of
 * the maximum that settles it, once four maxima are recorded); samples every
 * sample_period [s] (0 = none) go to on_sample. Throws InvalidParameterError on bad parameters.
 */
RunSummary runResponse(const RunConfig& config, EventSink* sink = nullptr, double sample_period = 0.0,
                       const SampleCallback& on_sample = nullptr, const ProgressCallback& on_progress = nullptr);

}  // namespace backlash_servo
