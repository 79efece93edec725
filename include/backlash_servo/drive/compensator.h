/**
 * @file compensator.h
 * @brief Backlash compensators of the digital drive (`inverse`, `dual_loop`, `friction_feedforward`, `dither`): what
 *        they add at each controller sample to the position reference [rad] or to the torque [N·m], before the torque
 *        limit. They only change the held torque at samples, so every mode keeps its closed form. Their laws and
 *        keys: docs/workbench.md, the strategies' table. No ROS dependency.
 */
#pragma once

#include <string>

namespace backlash_servo
{
struct DriveParams;

class Compensator
{
 public:
  Compensator() = default;
  explicit Compensator(const DriveParams& drive);
  /// New settings of the same kind from the next sample on, the state kept (the inverse's offset and direction, the
  /// dual loop's outer integrator x_k): a live change without a bump. False (nothing changed) for another kind.
  bool retune(const DriveParams& drive);

  /// Whether a compensator is configured (the drive skips both calls otherwise).
  bool active() const { return kind_ != Kind::None; }
  /// The position reference the loop tracks at this sample [rad] (inverse, dual loop; else `reference`).
  double reference(double reference, double load_reading, double period);
  /// The torque after the feed-forward terms [N·m] (friction feed-forward, dither; else `torque`).
  double torque(double torque, double error, double time) const;

 private:
  enum class Kind
  {
    None,
    Inverse,
    DualLoop,
    FrictionFeedforward,
    Dither
  } kind_ = Kind::None;
  double backlash_ = 0.0, width_ = 0.0, outer_gain_ = 0.0, friction_ = 0.0, amplitude_ = 0.0, frequency_ = 0.0;
  bool square_ = true;
  bool started_ = false;
  int direction_ = 1;  // last direction of the commanded motion
  double last_reference_ = 0.0;
  double offset_ = 0.0;  // inverse: o_k [rad]; dual loop: x_k [rad]
};

}  // namespace backlash_servo
