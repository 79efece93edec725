/**
 * @file gear_mesh.h
 * @brief Geometry of the gear mesh with backlash: the gap, its two walls, and where the motor is when the teeth
 *        touch a wall. The only place this geometry is written (no ROS dependency).
 *
 * \f[ g = \theta_c - \rho\,\theta_m \in [0, \Delta] \f]
 * g = 0 is the forward wall (the motor tooth pushes the load in +), g = Δ the backward wall (pushes in −).
 */
#pragma once

#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"

namespace backlash_servo
{
struct GearMesh
{
  double ratio = 1.0;          ///< ρ [-]
  double backlash = 0.0;       ///< Δ at the load shaft [rad]
  double inverse_ratio = 1.0;  ///< 1/ρ [-] (set with ρ)

  GearMesh() = default;
  GearMesh(double rho, double delta) : ratio(rho), backlash(delta), inverse_ratio(1.0 / rho) {}
  explicit GearMesh(const ServoParams& p) : GearMesh(p.gear_ratio, p.backlash) {}

  /// Gap g [rad] of wall `wall`: 0 (Forward) or Δ (Backward).
  double wallGap(Contact wall) const { return wall == Contact::Backward ? backlash : 0.0; }
  /// Gap g = θ_c − ρ θ_m [rad].
  double gap(double load_position, double motor_position) const { return load_position - ratio * motor_position; }
  /// Motor position θ_m = (θ_c − g)/ρ [rad] that puts the gap at g (multiplied by 1/ρ: no division on the impact's
  /// critical path).
  double motorPosition(double load_position, double gap) const { return (load_position - gap) * inverse_ratio; }
  /// Motor position on wall `wall` [rad].
  double motorPositionOnWall(double load_position, Contact wall) const
  {
    return motorPosition(load_position, wallGap(wall));
  }
  /// Motor velocity ω_m = ω_c/ρ of teeth moving together [rad/s].
  double motorVelocityInContact(double load_velocity) const { return load_velocity * inverse_ratio; }
  /// Speed [rad/s] at which the teeth close onto `wall` (> 0: approaching): −ġ forward, +ġ backward.
  double closingSpeed(Contact wall, double load_velocity, double motor_velocity) const
  {
    return (wall == Contact::Forward ? -1.0 : 1.0) * (load_velocity - ratio * motor_velocity);
  }
  /// With Δ > 0 teeth leaving a wall float; with Δ = 0 the other flank takes over at once.
  Contact afterSeparation(Contact wall) const { return backlash > 0.0 ? Contact::Apart : otherWall(wall); }

  /// The opposite wall.
  static Contact otherWall(Contact c) { return c == Contact::Forward ? Contact::Backward : Contact::Forward; }
  /// Sign of the mesh torque on the load that presses into `wall`: +1 forward, −1 backward.
  static double pressingSign(Contact wall) { return wall == Contact::Backward ? -1.0 : 1.0; }
};

}  // namespace backlash_servo
