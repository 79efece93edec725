/**
 * @file compensator.h
 * @brief Backlash compensators of the digital drive: what they add to the position reference or to the
 *        torque at each controller sample. They only change the held torque at samples, so every mode keeps its
 *        closed form. No ROS dependency.
 *
 * At sample k (period T, reference θ_R,k, motor reading y_m,k referred to the load shaft, load reading y_L,k):
 * - `inverse` (the backlash inverse; needs `feedback: motor`): the motor-side reference jumps by the estimated
 *   backlash Δ̂ (`compensation_backlash` [rad], at the load shaft) when the commanded motion reverses:
 *   \f$ r_k = \theta_{R,k} + o_k \f$, o = 0 while the command last moved up (forward flank), −Δ̂ after it moved down
 *   (backward flank: θ_c = ρθ_m + Δ); with `compensation_width` w > 0 the jump is spread over a commanded travel w
 *   (|Δo| ≤ Δ̂|Δθ_R|/w per sample).
 * - `dual_loop` (needs `feedback: motor`): an outer load loop trims the inner motor loop's reference:
 *   \f$ r_k = \theta_{R,k} + x_k,\; x_k = x_{k-1} + K_o T (\theta_{R,k} - y_{L,k}) \f$ (K_o = `outer_loop_gain` [1/s]).
 * - `friction_feedforward`: \f$ u_k \mathrel{+}= F\,\mathrm{sign}(e_k) \f$, F = `compensation_friction` [N·m], e_k
 *   the loop error (the wanted motion); 0 inside |e_k| ≤ `compensation_width`.
 * - `dither`: \f$ u_k \mathrel{+}= A\,s(2\pi f t_k) \f$, A = `dither_amplitude` [N·m], f = `dither_frequency` [Hz],
 *   s = sin or the square wave sign(sin) (`dither_shape`), sampled by the drive (f ≤ f_s/2).
 * The torque terms are added before the torque limit.
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
