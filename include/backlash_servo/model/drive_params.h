/**
 * @file drive_params.h
 * @brief The drive's settings as plain data: the control law, its rate, encoders, gains, torque limit and
 *        compensator (docs/model.md Part 2, "Digital drive"). Gains in SI (N·m/rad, N·m/(rad·s), N·m·s/rad, 1/s),
 *        rates in Hz, encoder resolutions in counts/rev (0 = ideal). The drive itself is drive/drive.h.
 */
#pragma once

#include <string>

#include "backlash_servo/model/state.h"

namespace backlash_servo
{
/// Settings of the drive (docs/model.md Part 2, "Digital drive"); the P gain K is ServoParams::gain.
struct DriveParams
{
  /// The lowest sample rate of a digital drive [Hz] (a sample every 1000 s); 0 is the continuous law.
  static constexpr double MIN_CONTROLLER_RATE = 1e-3;
  std::string control_law = "proportional";  ///< proportional | pid | cascade
  double controller_rate = 0.0;              ///< f_s [Hz]; 0 = continuous (proportional only)
  double controller_delay = 0.0;             ///< samples of computation delay, 0 or 1
  double motor_encoder_resolution = 0.0;     ///< counts/rev, 0 = ideal
  double load_encoder_resolution = 0.0;      ///< counts/rev, 0 = ideal
  std::string feedback = "load";             ///< load | motor (the motor reading is referred to the load shaft)
  double integral_gain = 0.0;                ///< K_i [N·m/(rad·s)] (pid)
  double derivative_gain = 0.0;              ///< K_d [N·m·s/rad] (pid, on the measurement)
  double position_loop_gain = 0.0;           ///< K_p [1/s] (cascade, outer loop)
  double velocity_loop_gain = 0.0;           ///< K_v [N·m·s/rad] (cascade, inner loop)
  double velocity_loop_integral_gain = 0.0;  ///< K_vi [N·m/rad] (cascade, inner loop)
  double torque_limit = 0.0;                 ///< T_max [N·m], 0 = none
  // Backlash compensation (compensator.h; digital drives only).
  std::string compensation = "none";    ///< none | inverse | dual_loop | friction_feedforward | dither
  double compensation_backlash = 0.0;   ///< inverse: the compensator's estimate Δ̂ of the backlash [rad]
  double compensation_width = 0.0;      ///< inverse: travel the jump is spread over; feed-forward: deadband [rad]
  double outer_loop_gain = 0.0;         ///< dual_loop: K_o [1/s]
  double compensation_friction = 0.0;   ///< friction_feedforward: F [N·m]
  double dither_amplitude = 0.0;        ///< dither: A [N·m]
  double dither_frequency = 0.0;        ///< dither: f [Hz]
  std::string dither_shape = "square";  ///< dither: square | sine

  bool sampled() const { return controller_rate > 0.0; }
  /// The thesis' law: continuous P, unsaturated, uncompensated — the Simulator's own law, the one loop ζ and ω_n
  /// describe.
  bool thesisLaw() const { return !sampled() && torque_limit == 0.0 && compensation == "none"; }
  /// Throws InvalidParameterError for combinations the model does not define (pid without a rate, …). In effort
  /// mode the encoders are the plant's (read by an external controller), so they need no controller_rate.
  void validate(ControlMode mode = ControlMode::Position) const;
};

}  // namespace backlash_servo
