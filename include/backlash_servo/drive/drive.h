/**
 * @file drive.h
 * @brief The drive: what produces the motor torque. Apart from the plant (plant.h), which is only given the torque
 *        as a law over a segment and knows nothing of set-points. No ROS dependency.
 *
 * Every law the plant accepts is affine in the load position over a segment, \f$ T_m = a - k\,\theta_c \f$
 * (MotorInput), so each mode stays linear with constant input and keeps its closed form. A drive may also have
 * events of its own at known times (a controller sample, a saturation switch, a change of input): the simulator
 * stops there and lets the drive update its law.
 *
 * Where a new control law goes: a class derived from Drive in this header and drive.cpp (sampled laws implement
 * nextEventTime() and sample()); the plant does not change.
 */
#pragma once

#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/drive/compensator.h"
#include "backlash_servo/model/drive_params.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"

namespace backlash_servo
{
class Drive
{
 public:
  virtual ~Drive() = default;
  /// How the torque is produced (reported by the tools and the node).
  virtual ControlMode mode() const = 0;
  /// The motor torque law valid from now until the next drive event.
  virtual MotorInput law() const = 0;
  /// Time [s] of the next drive event strictly after time t [s]; +inf when the law never changes by itself.
  virtual double nextEventTime(double /*t*/) const { return std::numeric_limits<double>::infinity(); }
  /// Called at a drive event with the plant state there; updates the law.
  virtual void sample(const State& /*state*/) {}
  /// New parameters (e.g. the gain) from now on; throws InvalidParameterError keeping the old ones.
  virtual void configure(const ServoParams& /*params*/) {}
  /// A continuous law whose form depends on the state (saturation) re-evaluates it here: at a watch event (the load
  /// left watchInterval()) or after a change of parameters or set-point. Sampled laws change only at samples.
  virtual void reevaluate(const State& /*state*/) {}
  /// The interval [lo, hi] of θ_c [rad] in which law() stays valid; the plant stops exactly where θ_c leaves it.
  virtual void watchInterval(double* lo, double* hi) const
  {
    *lo = -std::numeric_limits<double>::infinity();
    *hi = std::numeric_limits<double>::infinity();
  }
  virtual std::unique_ptr<Drive> clone() const = 0;
  /// Whether the drive's own state still moves its output with the plant standing still (an integrator whose input
  /// is beyond rounding of zero): a joint stuck by dry friction is not converged while this holds.
  virtual bool winding() const { return false; }
  /// The output stays what it is for ever while the plant stands still and the set-point does not change: no
  /// integrator moving beyond rounding, no derivative or delay still changing, no dither ahead. Together with a plant
  /// held by stiction under that output and no profile change ahead (Simulator::atRestForever) the joint can never
  /// move again. Default: a law with no events of its own.
  virtual bool steady() const { return std::isinf(nextEventTime(-std::numeric_limits<double>::infinity())); }
  /// A digital drive (samples at known instants) rather than a continuous law.
  virtual bool sampled() const { return false; }
  /// The output may depend on the motor's angle or speed (motor feedback, the cascade's speed loop, a compensator):
  /// a motor still moving may change it although the load stands. Default: no.
  virtual bool readsMotor() const { return false; }
  /// What the controller read at its latest sample: quantised motor angle on the motor shaft and load angle [rad].
  /// False for a continuous law (it reads nothing at instants).
  virtual bool readings(double* /*motor*/, double* /*load*/) const { return false; }
  /// The fast path through a stick phase: the plant holds `state` (nothing moves) and would stay held under any
  /// motor torque in [lo, hi] [N·m]. Takes the drive's samples at instants before `until` [s], at most `max_count`,
  /// exactly as sample(state) at each would, and stops after the first whose torque leaves [lo, hi]. Returns how
  /// many it took and the instant of the last in *last [s]. 0: not supported (the caller samples one by one).
  virtual long holdSamples(const State& /*state*/, double /*until*/, double /*lo*/, double /*hi*/, long /*max_count*/,
                           double* /*last*/)
  {
    return 0;
  }
};

/**
 * The thesis' continuous proportional law on the load position, optionally saturated and compensated:
 * \f[ T_m = \mathrm{sat}_{T_{max}}\big(K e + F_{ff}(e) + A\,s(t)\big), \quad e = \theta_R - \theta_c \f]
 * with the friction feed-forward F_ff(e) = F sign(e) for |e| > w, 0 inside (`friction_feedforward`: F =
 * compensation_friction [N·m], w = compensation_width [rad] > 0) and the square dither s(t) = sign(sin 2πft) (+1 at
 * 0; `dither`: A = dither_amplitude [N·m], f = dither_frequency [Hz]). Every piece is the linear law a − kθ_c with
 * a = Kθ_R + F_ff + A s [N·m], k = K [N·m/rad] on the band where |Ke + F_ff + A s| ≤ T_max, else the constant ±T_max.
 * The switches in θ_c (θ_R ± w, the band edges) are watch events located exactly by the plant; at an edge the side
 * the load is moving to decides, so a switch never repeats at the same instant. The dither's switches t = n/(2f)
 * are drive events at known instants. So the compensated continuous law stays exact.
 */
class ProportionalDrive : public Drive
{
 public:
  /// gain K [N·m/rad] > 0, command θ_R [rad] (finite), torque_limit T_max [N·m] (0 = none).
  ProportionalDrive(double gain, double command, double torque_limit = 0.0);
  /// The law `drive` describes with controller_rate 0: its torque limit and compensation (friction_feedforward, or
  /// a square dither; DriveParams::validate refuses the others for the continuous law).
  ProportionalDrive(const DriveParams& drive, double gain, double command);
  ControlMode mode() const override { return ControlMode::Position; }
  MotorInput law() const override;
  /// The dither's next switch (n+1)/(2f) [s], n the present half period (+inf without dither).
  double nextEventTime(double t) const override;
  /// At a dither switch (and at the start): s(t) for the half period beginning at state.time, and the band again.
  void sample(const State& state) override;
  void configure(const ServoParams& params) override;
  void reevaluate(const State& state) override;
  void watchInterval(double* lo, double* hi) const override;
  std::unique_ptr<Drive> clone() const override { return std::make_unique<ProportionalDrive>(*this); }

  double command() const { return command_; }
  /// A step of the set-point θ_R [rad] (finite); call reevaluate() with the state after it. Ends a command wave.
  void setCommand(double command);
  /// θ_R = command + Σ A_i sin(ω_i(t − t₀,i) + φ_i) [rad] from now on (`wave` in rad): the law gains the torque
  /// wave K·A_i sin(…). The linear law only (no torque limit, compensation or dither): InvalidParameterError otherwise.
  void setCommandWave(double command, const Waveform& wave);
  /// The law is linear (no torque limit, compensation or dither): it takes a command wave.
  bool linear() const { return limit_ == 0.0 && friction_ == 0.0 && amplitude_ == 0.0; }

 private:
  /// The linear band [θ_R − (T_max − c)/K, θ_R + (T_max + c)/K] [rad], c = F_ff + A s of the present piece.
  void band(double* lo, double* hi) const;
  /// The torque the compensator adds on the present piece, F_ff + A s [N·m].
  double added() const { return feedforward_ * friction_ + dither_sign_ * amplitude_; }

  enum class Region
  {
    Linear,
    High,  ///< θ_c below the band: +T_max
    Low    ///< θ_c above the band: −T_max
  };
  double gain_;
  double command_;
  double limit_;
  Waveform wave_;  // the command's wave [rad] (empty: none)
  Region region_ = Region::Linear;
  double friction_ = 0.0;   // F [N·m] (0: no feed-forward)
  double width_ = 0.0;      // w [rad]
  double amplitude_ = 0.0;  // A [N·m] (0: no dither)
  double frequency_ = 0.0;  // f [Hz]
  int feedforward_ = 0;     // sign of F_ff on the present piece: +1 (θ_c < θ_R − w), 0 (inside), −1
  int dither_sign_ = 0;     // s(t) on the present half period (0 without dither)
  double half_ = 0.0;       // index n of the present half period [n/(2f), (n+1)/(2f))
};

/// Torque given directly by an external controller: \f$ T_m = u \f$ [N·m], held until the next input.
class EffortDrive : public Drive
{
 public:
  /// T_m = torque + wave(t) [N·m] (wave: none by default; finite, frequency > 0 when active).
  explicit EffortDrive(double torque, const Waveform& wave = Waveform());
  ControlMode mode() const override { return ControlMode::Effort; }
  MotorInput law() const override { return {torque_, 0.0, wave_}; }
  std::unique_ptr<Drive> clone() const override { return std::make_unique<EffortDrive>(*this); }

  double torque() const { return torque_; }
  /// An external controller may change the torque at any time: never steady.
  bool steady() const override { return false; }
  /// New torque u [N·m] (finite) from now on (ends a wave).
  void setTorque(double torque);

 private:
  double torque_;
  Waveform wave_;
};

/**
 * A digital drive: samples at t_k = t_0 + k/f_s, reads its encoders, holds u_k (zero-order hold) on [t_k, t_{k+1})
 * — or one sample later with controller_delay 1 (u = 0 on [t_0, t_0 + T)) — saturated at ±T_max.
 * Encoder reading of an angle θ: \f$ q(\theta) = \frac{2\pi}{N}\lfloor N\theta/2\pi \rfloor \f$ (N = 0: ideal);
 * feedback y_k = q_L(θ_c) or ρ q_m(θ_m); e_k = θ_R − y_k. Laws:
 * - proportional: u_k = K e_k;
 * - pid: \f$ u_k = K e_k + I_k - K_d (y_k - y_{k-1})/T,\; I_k = I_{k-1} + K_i T e_k \f$;
 * - cascade: ω_ref = K_p e_k, ω̂_k = ρ (q_m(θ_m,k) − q_m(θ_m,k−1))/T (0 at k = 0), u_k = K_v (ω_ref − ω̂_k) + I_k,
 *   I_k = I_{k−1} + K_vi T (ω_ref − ω̂_k).
 * Anti-windup (conditional integration): with T_max > 0, when the unsaturated u_k lies beyond the limit on the side
 * of the integrated error's sign, I_k = I_{k−1}.
 */
/// An incremental encoder's reading q(θ) = 2π/N floor(Nθ/2π) [rad] of the angle θ [rad] of its own shaft, for a
/// resolution of N counts/rev; N ≤ 0: an ideal encoder (θ itself). Inline: most encoders in a run are ideal.
double quantiseAngle(double angle, double resolution);
inline double encoderReading(double angle, double resolution)
{
  return resolution <= 0.0 ? angle : quantiseAngle(angle, resolution);
}

class SampledDrive : public Drive
{
 public:
  /// gain K [N·m/rad], gear ratio ρ, command θ_R [rad], t0 [s] the time of sample 0.
  SampledDrive(const DriveParams& drive, double gain, double gear_ratio, double command, double t0);
  ControlMode mode() const override { return ControlMode::Position; }
  MotorInput law() const override { return {held_, 0.0}; }
  double nextEventTime(double t) const override;
  void sample(const State& state) override;
  void configure(const ServoParams& params) override;
  /**
   * New drive settings from the next sample on, without a bump: the integrator's value I [N·m] is kept (a new K_i or
   * K_vi changes only its later increments), so are the previous readings (derivative, velocity estimate) and the
   * compensator's state. A new controller_rate keeps the next sample where it is due and spaces the later ones by
   * the new period; a delay 0 → 1 holds the present output one more sample. Returns false, changing nothing, when
   * the law, the feedback, the compensator's kind or a continuous (0 Hz) rate is asked for: those need a fresh
   * controller (makePositionDrive). Throws InvalidParameterError for invalid settings.
   */
  bool retune(const DriveParams& drive);
  std::unique_ptr<Drive> clone() const override { return std::make_unique<SampledDrive>(*this); }
  /// The integrator moved beyond rounding at the latest sample (pid, cascade).
  bool winding() const override { return winding_; }
  /// At the latest sample: the integrator frozen, the measurement unchanged (no derivative or velocity estimate),
  /// the delayed output equal to the held one, no compensator. (A profile change ahead is the simulator's to see.)
  bool steady() const override { return steady_; }
  bool readsMotor() const override { return motor_feedback_ || law_ == Law::Cascade || compensator_.active(); }
  bool sampled() const override { return true; }
  long holdSamples(const State& state, double until, double lo, double hi, long max_count, double* last) override;
  bool readings(double* motor, double* load) const override
  {
    *motor = qm_prev_;  // q(θ_m) of the latest sample (kept for the next velocity estimate)
    *load = load_reading_;
    return started_;
  }

  /// A new set-point θ_R [rad] from the next sample on (replaces a profile).
  void setCommand(double command);
  /// The set-point follows this profile from now on (sampled at the drive's instants); null: back to the command.
  void setProfile(std::shared_ptr<const CommandProfile> profile) { profile_ = std::move(profile); }
  /// The reference θ_R,k [rad] used at the latest sample.
  double reference() const { return reference_; }
  double command() const { return command_; }
  /// The controller's latest readings [rad] (what it sees): motor (referred to the load shaft) and load.
  double motorReading() const { return motor_reading_; }
  double loadReading() const { return load_reading_; }
  /**
   * A torque injected into the drive's output at every sample from now on — the torque (current) set-point
   * injection a commissioning tool uses to measure the mechanics with the loops closed: u_k += A sin(2π (k − k₀)/N)
   * [N·m], k the sample's index (k₀ the next sample's), added after the law and the compensator and before the
   * torque limit. amplitude 0: none. Throws InvalidParameterError unless A is finite and N ≥ 2.
   */
  void setInjection(double amplitude, long period_samples);
  /**
   * The same with any periodic shape: u_k += A s[(k − k₀) mod N] [N·m], N = shape->size() (a PRBS or a chirp, one
   * period). Throws InvalidParameterError unless A and every s are finite and N ≥ 2.
   */
  void setInjection(double amplitude, std::shared_ptr<const std::vector<double>> shape);
  /// The torque injected at the latest sample [N·m].
  double injected() const { return injected_; }

 private:
  DriveParams p_;
  enum class Law
  {
    Proportional,
    Pid,
    Cascade
  } law_ = Law::Proportional;    // p_.control_law, parsed once (no string compare per sample)
  bool motor_feedback_ = false;  // p_.feedback == "motor"
  Compensator compensator_;
  std::shared_ptr<const CommandProfile> profile_;
  double reference_ = 0.0;  // θ_R,k of the latest sample [rad]
  double gain_, rho_, command_, t0_;
  double period_;          // 1/f_s [s]
  long next_ = 0;          // index of the next sample since t0_ (t0_ moves when the rate changes)
  bool started_ = false;   // a sample was taken (readings, previous measurement and velocity estimate exist)
  double held_ = 0.0;      // torque held now [N·m]
  double pending_ = 0.0;   // computed, applied at the next sample (delay 1) [N·m]
  double integral_ = 0.0;  // I_{k−1} [N·m]
  double y_prev_ = 0.0;    // y_{k−1} [rad]
  double qm_prev_ = 0.0;   // q_m(θ_m,k−1) [rad]
  double motor_reading_ = 0.0, load_reading_ = 0.0;
  bool winding_ = false;
  bool steady_ = false;
  double injection_amplitude_ = 0.0;                            // A [N·m]
  long injection_period_ = 0;                                   // N [samples]
  long injection_start_ = 0;                                    // k₀
  std::shared_ptr<const std::vector<double>> injection_shape_;  // one period s_k (null: a sine of N samples)
  double injected_ = 0.0;                                       // at the latest sample [N·m]
};

/**
 * The position-mode drive a DriveParams describes: the SampledDrive when controller_rate > 0, else the continuous
 * P law (saturated when torque_limit > 0). gain K [N·m/rad], gear ratio ρ, command θ_R [rad], t0 [s] of sample 0.
 */
std::unique_ptr<Drive> makePositionDrive(const DriveParams& drive, double gain, double gear_ratio, double command,
                                         double t0);

}  // namespace backlash_servo
