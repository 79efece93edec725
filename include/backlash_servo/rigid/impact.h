/**
 * @file impact.h
 * @brief The tooth impact map: momentum conservation and Newton's restitution law (no ROS dependency).
 */
#pragma once

#include "backlash_servo/model/params.h"

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
 *
 * The constant factors are formed once per parameter set and restitution (a plant keeps one map for e and one for
 * e = 0), so an impact multiplies and adds only: no division lies on the chain from one impact to the next.
 */
class ImpactMap
{
 public:
  ImpactMap() = default;
  /// @param e the restitution [-] this map applies (the parameters' own, or 0 for an impact made plastic)
  ImpactMap(const ServoParams& p, double e)
  {
    const double rho = p.gear_ratio;
    const double jm = p.motor_inertia;
    const double jl = p.load_inertia;
    const double j = jm + rho * rho * jl;
    const double mu = jm * jl / j;
    restitution_ = e;
    load_gain_ = jm * (1.0 + e) / j;
    inverse_ratio_ = 1.0 / rho;
    rho_ = rho;
    load_inertia_ = jl;
    loss_factor_ = (1.0 - e * e) * 0.5 * mu;
  }

  /// Velocities after the impact of teeth moving at ω_c = v, ω_m = w [rad/s].
  ImpactOutcome operator()(double v, double w) const
  {
    const double relative = rho_ * w - v;  // closing speed of the motor tooth onto the load tooth [rad/s]
    ImpactOutcome out;
    // Written with the relative speed so that e = 0 gives exactly equal velocities (no rounding residue).
    out.load_velocity = v + load_gain_ * relative;
    out.motor_velocity = (out.load_velocity - restitution_ * relative) * inverse_ratio_;
    out.impulse = load_inertia_ * (out.load_velocity - v);
    out.energy_loss = loss_factor_ * relative * relative;
    return out;
  }

  double restitution() const { return restitution_; }  ///< e [-]

 private:
  double restitution_ = 0.0;    // e [-]
  double load_gain_ = 0.0;      // J_m(1 + e)/J [-]
  double inverse_ratio_ = 1.0;  // 1/ρ [-]
  double rho_ = 1.0;            // ρ [-]
  double load_inertia_ = 0.0;   // J_L [kg·m²]
  double loss_factor_ = 0.0;    // (1 − e²)·½μ [kg·m²]
};

}  // namespace backlash_servo
