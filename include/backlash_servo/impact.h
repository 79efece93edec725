/**
 * @file impact.h
 * @brief The tooth impact map: momentum conservation and Newton's restitution law (no ROS dependency).
 */
#pragma once

#include "backlash_servo/params.h"

namespace backlash_servo
{
/// Velocities after an impact and what it did.
struct ImpactOutcome
{
  double load_velocity = 0.0;   ///< ω_c after [rad/s]
  double motor_velocity = 0.0;  ///< ω_m after [rad/s]
  double impulse = 0.0;         ///< angular impulse of the mesh on the load, J_L (ω_c' − ω_c) [N·m·s]
  double energy_loss = 0.0;     ///< kinetic energy lost [J], (1 − e²) ½ μ (ρω_m − ω_c)²
};

/**
 * Instantaneous impact of the teeth; positions are unchanged and only the mesh impulse acts.
 * \f[ J_m(\omega_m' - \omega_m) = \rho J_L(\omega_c - \omega_c'),\qquad
 *     \rho\omega_m' - \omega_c' = -e(\rho\omega_m - \omega_c) \f]
 * \f[ \Rightarrow \omega_c' = \frac{J_m}{J_m + \rho^2 J_L}\left[\rho\omega_m(1 + e)
 *     + \omega_c\left(\frac{\rho^2 J_L}{J_m} - e\right)\right] \f]
 * Energy lost: \f$ (1 - e^2)\tfrac12\mu(\rho\omega_m - \omega_c)^2 \f$, \f$ \mu = J_m J_L/(J_m + \rho^2 J_L) \f$.
 */
inline ImpactOutcome resolveImpact(const ServoParams& p, double v, double w, double e)
{
  const double rho = p.gear_ratio;
  const double jm = p.motor_inertia;
  const double jl = p.load_inertia;
  const double j = jm + rho * rho * jl;
  const double relative = rho * w - v;  // closing speed of the motor tooth onto the load tooth [rad/s]
  ImpactOutcome out;
  // Written with the relative speed so that e = 0 gives exactly equal velocities (no rounding residue); the constant
  // factors multiply (1/ρ as the gear mesh does), so no division lies on the chain from one impact to the next.
  out.load_velocity = v + (jm * (1.0 + e) / j) * relative;
  out.motor_velocity = (out.load_velocity - e * relative) * (1.0 / rho);
  out.impulse = jl * (out.load_velocity - v);
  const double mu = jm * jl / j;
  out.energy_loss = (1.0 - e * e) * 0.5 * mu * relative * relative;
  return out;
}

}  // namespace backlash_servo
