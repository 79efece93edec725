/**
 * @file simulator.h
 * @brief The simulated servo joint: a Plant (bodies, gear mesh, contact, impacts) driven by a Drive (the control
 *        law). The simulator composes them and stops at the earlier of a plant event and a drive event. No ROS
 *        dependency; the ROS node and the tools are thin layers over this class.
 */
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>

#include "backlash_servo/drive/drive.h"
#include "backlash_servo/plant/plant.h"

namespace backlash_servo
{
class Simulator
{
 public:
  /// Starts with the continuous proportional law and command θ_R = command [rad]. Throws InvalidParameterError.
  Simulator(const ServoParams& params, const State& initial, double command);
  Simulator(const Simulator& other);
  Simulator& operator=(const Simulator& other);

  const ServoParams& params() const { return frame_rate_ != 0.0 ? true_params_ : plant_.params(); }
  /// The state at the current time (during a ramp of the continuous law, converted from the ramp's frame).
  State state() const;
  const Plant& plant() const { return plant_; }
  const Drive& drive() const { return *drive_; }
  /// The digital drive, to inject into its torque set-point (SampledDrive::setInjection); null for another drive.
  SampledDrive* sampledDrive() { return dynamic_cast<SampledDrive*>(drive_.get()); }
  ControlMode controlMode() const { return drive_->mode(); }
  /// θ_R [rad] of the proportional law (the last one set, also while in effort mode).
  double command() const { return command_; }

  /// Position mode, T_m = K(θ_R − θ_c), with θ_R = command [rad] from now on (a step; ends a profile). Must be
  /// finite.
  void setCommand(double command, EventSink* sink = nullptr);
  /**
   * The continuous P law with θ_R = command + Σ A_i sin(ω_i(t − t₀,i) + φ_i) [rad] (`wave` in rad: a sine or a sum
   * of up to MAX_TONES) from now on, exactly: the motor torque gains the wave K·A sin(…), which the joint's modes
   * carry as oscillators (compliant_joint.h; with rigid teeth too). Ends a profile. InvalidParameterError ("wave")
   * for more sines than the modes carry (one with a torsional shaft). InvalidParameterError (key named) on rigid teeth
   * with dry friction (a digital drive samples sines instead), or when the law is not the linear continuous one (a
   * digital drive, a torque limit, compensation).
   */
  void setCommandWave(double command, const Waveform& wave, EventSink* sink = nullptr);
  /**
   * Position mode: θ_R follows the profile (times [s] of sim time) from now on. A digital drive samples it at its
   * instants. The continuous law takes steps and points as exact command steps at their known instants (advanceTo
   * stops there) and ramps exactly in the frame moving with the ramp: there y_c = θ_c − v(t − t_a), y_m = θ_m −
   * (v/ρ)(t − t_a), θ_R − θ_c = θ_R(t_a) − y_c, the gap and the impact law are unchanged, and viscous friction
   * becomes the constant torques −f_L v (load) and −f_m v/ρ (motor) — the same linear modes with constant inputs,
   * so every closed form and event search applies. Not with dry friction (|ω| is not shifted by a frame) and not
   * moves (InvalidParameterError); sines only with a compliant mesh, whose modes carry them exactly (setCommandWave,
   * the linear law only). In the frame the plant's maxima are not θ_c's (they are not reported)
   * and its energy ledger is the frame's (energyValid() turns false). A later setCommand, setDrive or
   * setMotorTorque ends the profile. Null: none.
   */
  void setProfile(std::shared_ptr<const CommandProfile> profile, EventSink* sink = nullptr);
  /// The profile θ_R follows, or null.
  const std::shared_ptr<const CommandProfile>& profile() const { return profile_; }
  /// Effort mode, T_m = torque [N·m] from now on (the internal P loop is off). Must be finite.
  void setMotorTorque(double torque, EventSink* sink = nullptr);
  /// Effort mode, T_m = torque + Σ A_i sin(ω_i(t − t₀,i) + φ_i) [N·m] exactly (InvalidParameterError, key named, on
  /// rigid teeth with dry friction, or for more sines than the modes carry).
  void setMotorTorque(double torque, const Waveform& wave, EventSink* sink = nullptr);
  /// A sinusoidal disturbance on the load from now on, T_ext(t) = load_torque + Σ B_i sin(ω_i(t − t₀,i) + φ_i)
  /// [N·m], exactly, under any drive (Plant::setLoadWave: refused, key named, on rigid teeth with dry friction or for
  /// more sines, the motor's and the load's together, than the modes carry). Empty: none.
  void setLoadTorqueWave(const Waveform& wave, EventSink* sink = nullptr);
  /**
   * The caller will change the input again at time t [s] (e.g. a torque held over the samples of an external
   * controller): events need not be searched beyond it, which spares a compliant joint's event search the stretch
   * after it. A hint only — the motion agrees with the unhinted one to rounding (the search windows move, so an event
   * refined to its last bit may land a bit apart); it must depend only on the caller's schedule (not on where
   * advanceTo() is called) for runs to stay chunk-independent. Cleared by the next input change; +inf: none.
   */
  void setInputHorizon(double t) { input_horizon_ = t; }
  /// Replaces the drive (its law applies from now on).
  void setDrive(std::unique_ptr<Drive> drive, EventSink* sink = nullptr);
  /// New settings for the digital drive in place, without a bump (SampledDrive::retune); false when the drive is
  /// not digital or the change needs a fresh one (then nothing changed: call setDrive).
  bool retuneDrive(const DriveParams& drive, EventSink* sink = nullptr);
  /**
   * Replaces the parameters at the current time without a jump in positions or velocities. If the current gap lies
   * outside the new [0, Δ], the motor is carried along: the gap is clamped to the nearest wall by moving θ_m (the
   * teeth touch there), then the usual contact rule decides. Throws InvalidParameterError, keeping the old ones.
   */
  void setParams(const ServoParams& params, EventSink* sink = nullptr);
  /// Replaces the state (validated: finite, gap within [0, Δ], contact consistent); resets the energy ledger.
  void setState(const State& state);

  /// The plant's chatter fast path (Plant::setShortFlights): on by default; off only to compare with the closed form.
  void setShortFlights(bool on) { plant_.setShortFlights(on); }
  /// Advances exactly to time t_end [s], stopping at drive events on the way; events go in order to sink. A digital
  /// drive's sample due at t_end itself is left for the next call (the state at t_end is the one its controller reads).
  void advanceTo(double t_end, EventSink* sink = nullptr);
  /// Takes a digital drive's sample due at the current time t, or within rounding after it (1e-12 max(1, |t|) s: a
  /// grid of samples i·T and the drive's k/f differ in their last bits; one advanceTo to it first): then the motor
  /// torque is the one applied from now on, as a drive logs it. Nothing when none is due.
  void takeSampleDue(EventSink* sink = nullptr);
  /// Called at every sample of a digital drive, just after the controller read its sensors (state at t_k, the
  /// drive with its readings and new output) — e.g. the node's `encoder_states`. Empty: none.
  using SampleObserver = std::function<void(const State&, const Drive&)>;
  void setSampleObserver(SampleObserver observer) { sample_observer_ = std::move(observer); }

  /// Gap g = θ_c − ρ θ_m [rad], in [0, Δ].
  double gap() const { return plant_.gap(); }
  /// Motor torque T_m [N·m].
  double motorTorque() const { return plant_.motorTorque() - motor_bias_; }
  /// Mesh torque on the load T_L [N·m] (0 when apart).
  double meshTorque() const { return plant_.meshTorque(); }
  /// ½ J_m ω_m² + ½ J_L ω_c² [J].
  double kineticEnergy() const;
  /// False once a ramp of the continuous law ran in its moving frame (until setState): energy() is then the
  /// frame's, not the joint's (report it as unknown; energyBalanceError() is NaN).
  bool energyValid() const { return energy_valid_; }
  const EnergyLedger& energy() const { return plant_.energy(); }
  /// Energy accounting costs ~25 % of the run time; sweeps that only need verdicts may switch it off (the ledger
  /// then stays at its last values and energyBalanceError() is meaningless).
  void setEnergyTracking(bool on) { plant_.setEnergyTracking(on); }
  /// input − friction − impact losses − (kinetic − initial kinetic) [J]; zero up to rounding.
  double energyBalanceError() const { return energyValid() ? plant_.energyBalanceError() : NAN; }
  std::uint64_t impactCount() const { return plant_.impactCount(); }
  /// Contact phases of a compliant mesh begun since the last setState (0 with rigid teeth: see impactCount()).
  std::uint64_t contactPhases() const;
  /**
   * The joint is at a state the dynamics can never leave: dry friction holds both bodies (and the contact) under the
   * motor torque in force, the hold has no end of its own, and the drive's output stays that torque for ever
   * (Drive::steady: no integrator moving beyond rounding, no derivative, delay, dither or profile change ahead) — so
   * no torque on either body ever changes and the rest rule keeps deciding "held". Sound because every torque the
   * rest rule weighs (the law's, the load torque, the static bands) is then constant.
   */
  bool atRestForever() const;
  /// Controller samples taken through stick phases in blocks (the digital drive's fast path, holdSamples()): a
  /// figure for benchmarks and tests.
  std::uint64_t heldSamples() const { return held_samples_; }
  /// At most this many impacts and, separately, this many drive samples (0 = no limit); one more throws
  /// EventBudgetExceeded (an impact storm, or a sampled loop asked for billions of samples).
  void setEventBudget(std::uint64_t max_events)
  {
    plant_.setEventBudget(max_events);
    event_budget_ = max_events;
  }

 private:
  /// The drive's current law and watch interval to the plant.
  void applyDriveLaw();
  double input_horizon_ = INFINITY;  // setInputHorizon [s]
  /// A stick phase under a digital drive: the drive takes its samples before t_end [s] in one block while the held
  /// torque keeps the joint held (Plant::heldTorqueRange); false when the fast path does not apply.
  bool holdSamples(double t_end);
  /// One drive sample, counted against the event budget.
  void takeSample();
  /// θ_R = command [rad] for the position law now (setCommand without ending the profile).
  /// θ_R = command (+ wave [rad], the continuous P law only) to the drive, from now on.
  void applyCommand(double command, EventSink* sink, const Waveform& wave = Waveform());
  /// advanceTo without the continuous law's profile steps.
  void advanceDriveTo(double t_end, EventSink* sink);
  /// The continuous law's profile piece in force at time t: its value as the command, its ramp as a frame.
  void applyPiece(double t, EventSink* sink);
  /// Into / out of the frame moving at v [rad/s] with a ramp of θ_R (see setProfile), at the current time.
  void enterFrame(double v);
  void leaveFrame();

  Plant plant_;
  std::unique_ptr<Drive> drive_;
  double command_;                                 // θ_R [rad] kept for switching back to position mode
  std::shared_ptr<const CommandProfile> profile_;  // θ_R(t), or null
  bool stepped_ = false;                           // the continuous law steps through profile_ itself
  double next_change_ = 0.0;                       // stepped_: next instant θ_R may change [s]
  double frame_rate_ = 0.0;   // v [rad/s] of the ramp whose frame the plant runs in (0: the true frame)
  double frame_start_ = 0.0;  // t_a [s], where the frames coincide
  double motor_bias_ = 0.0;   // −f_m v/ρ [N·m], added to the law in the frame
  ServoParams true_params_;   // in a frame: the joint's parameters (the plant holds the frame's)
  bool energy_valid_ = true;
  std::uint64_t event_budget_ = 0;
  std::uint64_t samples_ = 0;
  std::uint64_t held_samples_ = 0;  // samples taken by holdSamples()
  SampleObserver sample_observer_;
};

}  // namespace backlash_servo
