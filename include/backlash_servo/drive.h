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

#include <limits>
#include <memory>

#include "backlash_servo/params.h"
#include "backlash_servo/state.h"

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
  virtual std::unique_ptr<Drive> clone() const = 0;
};

/**
 * The thesis' continuous proportional law on the load position:
 * \f[ T_m = K(\theta_R - \theta_c) \f]  (a = Kθ_R [N·m], k = K [N·m/rad]).
 */
class ProportionalDrive : public Drive
{
 public:
  /// gain K [N·m/rad] > 0, command θ_R [rad] (finite).
  ProportionalDrive(double gain, double command);
  ControlMode mode() const override { return ControlMode::Position; }
  MotorInput law() const override { return {gain_ * command_, gain_}; }
  void configure(const ServoParams& params) override;
  std::unique_ptr<Drive> clone() const override { return std::make_unique<ProportionalDrive>(*this); }

  double command() const { return command_; }
  /// A step of the set-point θ_R [rad] (finite).
  void setCommand(double command);

 private:
  double gain_;
  double command_;
};

/// Torque given directly by an external controller: \f$ T_m = u \f$ [N·m], held until the next input.
class EffortDrive : public Drive
{
 public:
  explicit EffortDrive(double torque);
  ControlMode mode() const override { return ControlMode::Effort; }
  MotorInput law() const override { return {torque_, 0.0}; }
  std::unique_ptr<Drive> clone() const override { return std::make_unique<EffortDrive>(*this); }

  double torque() const { return torque_; }
  /// New torque u [N·m] (finite) from now on.
  void setTorque(double torque);

 private:
  double torque_;
};

}  // namespace backlash_servo
