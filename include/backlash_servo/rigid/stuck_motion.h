/**
 * @file stuck_motion.h
 * @brief Closed-form motion while dry friction holds a body: one body slides (or none) while the other is stuck; the
 *        sliding body's velocity is monotone, so every event (coming to rest, the gap reaching a wall, θ_c [rad]
 *        crossing a level) is a closed form or a bisection on a monotone piece. Who sticks: dry_friction.h. The
 *        closed forms: docs/model.md, Part 4, "Motion while a body is stuck". No ROS dependency.
 */
#pragma once

#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"
#include "backlash_servo/rigid/dry_friction.h"
#include "backlash_servo/rigid/modes.h"

namespace backlash_servo
{
class StuckMotion
{
 public:
  /// Which body slides.
  enum class Moving
  {
    None,   ///< both stuck (apart, or the meshed pair in contact)
    Motor,  ///< the load is stuck, teeth apart
    Load    ///< the motor is stuck, teeth apart
  };

  /// direction: slide direction of the moving body (its kinetic friction opposes it). params with dry friction.
  StuckMotion(const ServoParams& params, const MotorInput& law, const State& start, Moving moving, Slide direction);

  /// Positions [rad] and velocities [rad/s] at local time tau [s] (time and contact of out are not touched).
  void at(double tau, State* out) const;
  /// Energy flows over [0, tau] (viscous loss from the body's own balance f∫ω² = cΔθ − ½J(ω² − ω0²)).
  EnergyFlows energy(double tau) const;
  /// First τ in (0, horizon] where θ_c leaves [lo, hi] beyond rounding, or +inf.
  double exitTime(double lo, double hi, double horizon) const;
  /// Teeth apart: first τ in (0, horizon] where the gap leaves [0, Δ]; *wall gets the wall hit. +inf if none.
  double impactTime(double horizon, Contact* wall) const;
  /// First τ in (0, horizon] where the moving body's velocity reaches zero, or +inf.
  double restTime(double horizon) const;
  /// Load sliding, motor stuck: first τ in (0, horizon] where the motor torque a − kθ_c leaves the static band
  /// [−T_sm, T_sm] (the continuous law pulls the motor free), or +inf.
  double breakawayTime(double horizon) const;

 private:
  double velocity(double tau) const;
  double displacement(double tau) const;
  /// First τ in (0, horizon] where x0 + scale·displacement(τ) leaves [lo, hi] beyond rounding (magnitude: the
  /// size of the numbers it was computed from), or +inf.
  double firstExit(double x0, double scale, double lo, double hi, double magnitude, double horizon) const;

  ServoParams params_;
  MotorInput law_;
  State start_;
  Moving moving_;
  Slide direction_;
  double inertia_ = 1.0;  ///< J of the moving body [kg·m²]
  double rate_ = 0.0;     ///< p = f/J [1/s]
  double torque_ = 0.0;   ///< c: constant torque on the moving body, kinetic friction included [N·m]
  double v0_ = 0.0;       ///< its velocity at τ = 0 [rad/s]
};

}  // namespace backlash_servo
