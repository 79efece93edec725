#include "backlash_servo/impact.h"

namespace backlash_servo
{
ImpactOutcome resolveImpact(const ServoParams& p, double v, double w, double e)
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
