/**
 * @file frequency_response.h
 * @brief The joint's frequency response as a drive's commissioning tool measures it — one sine at a time (stepped
 *        sine) — but from the exact motion: the periodic steady state is detected (not assumed), and the output's
 *        fundamental and harmonics are exact Fourier integrals over one period. No ROS dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "Stepped-sine frequency response".
 */
#pragma once

#include <complex>
#include <functional>
#include <string>

#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
/// What is excited and what is measured.
enum class FrfChannel
{
  CommandToLoadPosition,    ///< θ_R [rad] through the digital drive → θ_c [rad]
  TorqueToMotorVelocity,    ///< T_m [N·m] in effort mode → ω_m [rad/s]
  TorqueToLoadVelocity,     ///< T_m [N·m] in effort mode → ω_c [rad/s]
  SetpointToMotorVelocity,  ///< a torque injected into the digital drive's set-point, its loops closed → ω_m [rad/s]
                            ///< per N·m of the motor torque (the mechanics measured in closed loop)
  SetpointToLoadVelocity,   ///< the same → ω_c [rad/s] per N·m of the motor torque
  LoadTorqueToLoadPosition  ///< a sine torque on the load [N·m], the configured loop holding the command → θ_c [rad]
                            ///< (the servo's dynamic compliance; the sine itself, exact)
};

/// "command:load_position", "motor_torque:motor_velocity", "motor_torque:load_velocity",
/// "torque_setpoint:motor_velocity", "torque_setpoint:load_velocity", "load_torque:load_position".
const char* toString(FrfChannel c);
/// The channel named by toString(); throws InvalidParameterError(key, …) naming the value otherwise.
FrfChannel frfChannelFrom(const std::string& name, const std::string& key);

struct FrfSettings
{
  FrfChannel channel = FrfChannel::CommandToLoadPosition;
  /// u₀, the input's constant part [rad for the command, N·m for the torque]; for the set-point channels the speed
  /// offset of the drive's command, θ_R = θ₀ + u₀(t − t₀) [rad/s], so that the joint keeps turning.
  double offset = 0.0;
  /// Samples per second of the torque injection [Hz] (torque channels; 0 = the drive's controller_rate, else
  /// DEFAULT_INJECTION_RATE). The command is sampled by the drive at its controller_rate.
  double injection_rate = 0.0;
  /// Torque channels: the sine itself, T_m = u₀ + A sin(ω(t − t₀)), instead of sampled and held. The command channel
  /// takes the sine itself under the continuous P law. Either is refused on rigid teeth with dry friction.
  bool continuous = false;
  double tolerance = 1e-8;  ///< steady state: relative repeat of the state from one period to the next [-]
  /// Periods run before a point is declared not periodic; 0 = enough to cover AUTO_SETTLING_SCALES of the joint's
  /// slowest time constant (its bodies' viscous decay J/f, the drive's integral time, and for the command 1/ω_n),
  /// and at least 1000, within the point's work budget (frfSampling).
  int max_periods = 0;
  int harmonics = 10;  ///< harmonics integrated (distortion from 2 … harmonics)
};

/// Automatic max_periods: this many of the slowest time constant (a transient decays by e^{−40} ≈ 4e-18).
constexpr double AUTO_SETTLING_SCALES = 40.0;
/// The torque injection's rate [Hz] when neither the settings nor the drive give one.
constexpr double DEFAULT_INJECTION_RATE = 10000.0;

struct FrfPoint
{
  double amplitude = 0.0;            ///< A [rad or N·m]
  double requested_frequency = 0.0;  ///< ω asked for [rad/s]
  double frequency = 0.0;            ///< ω used [rad/s]: a whole number of samples per period
  int samples_per_period = 0;        ///< N
  /// H = Y₁/U₁ [output unit per input unit]; for the set-point channels Y₁/T₁, T₁ the fundamental of the motor
  /// torque the drive applied (its law's output with the injection, held), which takes the loops out of the ratio
  std::complex<double> response;
  double gain = 0.0;          ///< |H|
  double phase = 0.0;         ///< arg H [rad], in (−π, π]
  double distortion = 0.0;    ///< √(Σ_{h≥2}|Y_h|²)/|Y₁| [-]
  double mean = 0.0;          ///< the output's mean over the period [rad or rad/s]
  double peak_to_peak = 0.0;  ///< the output's range over the period, at the samples [rad or rad/s]
  bool periodic = false;      ///< the steady state repeated within the tolerance (or to one count: below)
  /// The loop reads a quantised encoder and the steady state repeated only to within one count (in the angles; one
  /// count per sample in the speeds), for three periods running: periodic as far as the loop can tell
  bool periodic_to_count = false;
  /// With periodic_to_count: the change of the output at the period starts beyond a steady drift, over the
  /// output's fundamental amplitude [-] — how much the quantisation lets one period differ from the next
  double count_spread = NAN;
  int period_multiple = 0;     ///< 1: periodic at T; m = 2…4: subharmonic (repeats after mT); 0: not periodic
  int periods = 0;             ///< periods simulated
  double flank_changes = 0.0;  ///< the teeth changed flank (crossed the backlash) this often per period [1]
  double separations = 0.0;    ///< the teeth came apart (a contact ended) this often per period [1]
  /// The mesh torque on the load over the analysed period [N·m]: its mean, and its least and greatest values (at
  /// the samples and the quadrature's nodes — for the sine itself on a joint that stays on one flank, from its
  /// fundamental: mean ∓ |Q₁|, exact).
  double mesh_torque_mean = 0.0, mesh_torque_min = 0.0, mesh_torque_max = 0.0;
  double settled_at = 0.0;  ///< sim time where the analysed period began [s]
  State settled_state;      ///< the joint's state there (with a memoryless drive law, a run started on it at
                            ///< that time with the same excitation is periodic from its first period)
};

/// The rate [Hz] at which the channel's input is sampled and held: the drive's controller_rate for the command
/// (InvalidParameterError without a digital drive), else `injection_rate` (> 0), the drive's controller_rate, or
/// DEFAULT_INJECTION_RATE.
double excitationRate(const RunConfig& config, FrfChannel channel, double injection_rate);
/// The joint's slowest time constant [s] for the channel: its bodies' viscous decay J/f, the drive's integral time,
/// and — when the loops are closed (the command and set-point channels) — 1/ω_n. Settling is judged against it.
double slowestTimeScale(const RunConfig& config, FrfChannel channel);
/// The command a set-point channel's loops follow from `config.initial.time` for `duration` [s]: the configured
/// command held (speed 0), or turning at `speed` [rad/s] from it (a ramp the drive samples) — so that the joint keeps
/// to one flank while the injection measures it. Null for speed 0 (the constant command).
std::shared_ptr<const CommandProfile> speedOffsetProfile(const RunConfig& config, double speed, double duration);
/// The channel's output in a state: θ_c [rad], ω_m or ω_c [rad/s].
double frfOutput(FrfChannel channel, const State& state);
/// True for the channels whose input is the motor torque (effort mode).
inline bool torqueInput(FrfChannel channel)
{
  return channel == FrfChannel::TorqueToMotorVelocity || channel == FrfChannel::TorqueToLoadVelocity;
}
/// True for the channel whose input is a torque on the load (a disturbance: the sine itself, exact).
inline bool loadTorqueInput(FrfChannel channel)
{
  return channel == FrfChannel::LoadTorqueToLoadPosition;
}
/// True for the channels that inject into the digital drive's torque set-point, its loops closed.
inline bool setpointInput(FrfChannel channel)
{
  return channel == FrfChannel::SetpointToMotorVelocity || channel == FrfChannel::SetpointToLoadVelocity;
}

/// The joint's fastest own rate [1/s] under the configuration (natural frequencies of the loop, the contact, the
/// mesh and shaft springs; viscous and damper rates): the Fourier pieces are no longer than half its inverse.
double fastestRate(const ServoParams& params);

/// How a point's sine is applied.
struct FrfSampling
{
  bool continuous = false;  ///< the sine itself, else sampled and held
  double rate = 0.0;        ///< samples [Hz]: the hold's, or the observation points' for the sine itself
  long samples_per_period = 0;
  double frequency = 0.0;  ///< ω used [rad/s]: the one asked for, or placed on the sample grid 2πf_s/N
  long max_periods = 0;    ///< the most periods run to settle (max_periods, or automatic within a sample budget)
};

/**
 * The sampling of a point at ω [rad/s] (> 0): the exact sine (the command under the continuous law, or a torque with
 * `settings.continuous`) is refused on rigid teeth with dry friction; a held sine at least 4 samples a period (ω at
 * most a quarter of the sample rate, placed on the grid ω = 2πf_s/N, N the nearest whole number); at most 1e9 samples a
 * period; and the most periods the point runs to settle, within its work budget (docs/frequency_response.md,
 * "Bounded work"). Throws InvalidParameterError naming `continuous`, `controller_rate`, `injection_rate`, `frequency`
 * or `max_periods` otherwise — what measureFrequencyResponse and backlash_frf's checks before any run both use.
 */
FrfSampling frfSampling(const RunConfig& config, const FrfSettings& settings, double omega);

/**
 * One stepped-sine point: amplitude A (> 0) [rad or N·m] at ω (> 0) [rad/s]. The config's command and profile are
 * replaced by the excitation; its initial state is where the run starts. Throws InvalidParameterError for bad
 * parameters and for a channel the configuration cannot take (the command channel needs a digital drive; ω above a
 * quarter of the sample rate). `cancelled`, polled once per period, stops the point early (it is then
 * reported as it stands, not periodic).
 */
FrfPoint measureFrequencyResponse(const RunConfig& config, const FrfSettings& settings, double amplitude, double omega,
                                  const std::function<bool()>& cancelled = nullptr);

/**
 * The release amplitude at the point's frequency, from the point measured on the same joint without backlash
 * (`linear`, periodic): the largest amplitude at which the teeth stay on their flank — below it the joint with
 * backlash moves exactly as the one without. The linear joint's mesh torque is Q(t) = Q̄ + (A/A_lin)·q(t) (the
 * offsets' part does not depend on the amplitude, q has mean 0), so the flank is released where it first reaches 0:
 * A* = A_lin·Q̄/(Q̄ − min Q) when Q̄ > 0, A_lin·|Q̄|/(max Q − Q̄) when Q̄ < 0; 0 when |Q̄| is below 1e-8 of the
 * swing (nothing holds the teeth on a flank). NaN when the point is not periodic or its mesh torque does not move.
 */
double releaseAmplitude(const FrfPoint& linear);

}  // namespace backlash_servo
