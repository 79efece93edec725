#include "backlash_servo/rigid/stuck_motion.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/gear_mesh.h"
#include "numerics/event_search.h"

namespace backlash_servo
{
namespace
{
/// Φ1(τ) = (1 − e^{−pτ})/p [s] (τ when p = 0).
double phi1(double p, double tau)
{
  return p == 0.0 ? tau : -std::expm1(-p * tau) / p;
}

/// Φ2(τ) = (τ − Φ1(τ))/p [s²] (τ²/2 when p = 0); a series where the difference would cancel.
double phi2(double p, double tau)
{
  const double z = p * tau;
  if (z < 0.5)
  {
    // Σ_{n≥2} (−p)^{n−2} τ^n / n!
    double term = 0.5 * tau * tau;
    double sum = term;
    for (int n = 3; n < 60; ++n)
    {
      term *= -z / n;
      sum += term;
      if (std::fabs(term) <= 1e-17 * std::fabs(sum))
      {
        break;
      }
    }
    return sum;
  }
  return (tau - phi1(p, tau)) / p;
}
}  // namespace

StuckMotion::StuckMotion(const ServoParams& params, const MotorInput& law, const State& start, Moving moving,
                         Slide direction)
    : params_(params), law_(law), start_(start), moving_(moving), direction_(direction)
{
  if (moving == Moving::Motor)
  {
    inertia_ = params.motor_inertia;
    rate_ = params.motor_friction / params.motor_inertia;
    torque_ = law.torque(start.load_position) - direction * params.motor_coulomb_friction;
    v0_ = start.motor_velocity;
  }
  else if (moving == Moving::Load)
  {
    inertia_ = params.load_inertia;
    rate_ = params.load_friction / params.load_inertia;
    torque_ = params.load_torque - direction * params.load_coulomb_friction;
    v0_ = start.load_velocity;
  }
}

double StuckMotion::velocity(double tau) const
{
  return v0_ * std::exp(-rate_ * tau) + torque_ / inertia_ * phi1(rate_, tau);
}

double StuckMotion::displacement(double tau) const
{
  return v0_ * phi1(rate_, tau) + torque_ / inertia_ * phi2(rate_, tau);
}

void StuckMotion::at(double tau, State* out) const
{
  out->load_position = start_.load_position;
  out->motor_position = start_.motor_position;
  out->load_velocity = 0.0;
  out->motor_velocity = 0.0;
  if (moving_ == Moving::Motor)
  {
    out->motor_position += displacement(tau);
    out->motor_velocity = velocity(tau);
  }
  else if (moving_ == Moving::Load)
  {
    out->load_position += displacement(tau);
    out->load_velocity = velocity(tau);
  }
}

EnergyFlows StuckMotion::energy(double tau) const
{
  EnergyFlows e;
  if (moving_ == Moving::None)
  {
    return e;
  }
  const double d = displacement(tau);
  const double v = velocity(tau);
  // J ω ω̇ = c ω − f ω² integrated: the viscous loss without the cancellation of ∫ω² when p is slow.
  const double viscous = torque_ * d - 0.5 * inertia_ * (v * v - v0_ * v0_);
  if (moving_ == Moving::Motor)
  {
    e.input = law_.torque(start_.load_position) * d;
    e.motor_dry_friction = direction_ * params_.motor_coulomb_friction * d;
    e.motor_friction = viscous;
    e.motor_displacement = d;
  }
  else
  {
    e.load_work = params_.load_torque * d;
    e.load_dry_friction = direction_ * params_.load_coulomb_friction * d;
    e.load_friction = viscous;
    e.load_displacement = d;
  }
  return e;
}

double StuckMotion::restTime(double horizon) const
{
  if (moving_ == Moving::None || v0_ == 0.0 || !(v0_ * torque_ < 0.0))
  {
    return INF;  // not decelerating towards zero (a body breaking away from rest speeds up)
  }
  // ω(τ) = 0 ⇔ e^{−pτ} = c / (c − J p ω0) ⇔ τ = log1p(−J p ω0 / c) / p (τ = −J ω0 / c when p = 0).
  const double tau = rate_ == 0.0 ? -inertia_ * v0_ / torque_ : std::log1p(-inertia_ * rate_ * v0_ / torque_) / rate_;
  return tau > 0.0 && tau <= horizon ? tau : INF;
}

double StuckMotion::firstExit(double x0, double scale, double lo, double hi, double magnitude, double horizon) const
{
  // x is monotone on [0, τ*] and [τ*, horizon] (τ* = rest time, the only extremum).
  const double rest = restTime(horizon);
  const int m = rest < horizon ? 1 : 0;
  return backlash_servo::firstExit([&](double tau) { return x0 + scale * displacement(tau); }, &rest, m, horizon, lo,
                                   hi, magnitude);
}

double StuckMotion::exitTime(double lo, double hi, double horizon) const
{
  if (moving_ != Moving::Load)
  {
    return INF;  // θ_c does not move
  }
  return firstExit(start_.load_position, 1.0, lo, hi, levelMagnitude(lo, hi), horizon);
}

double StuckMotion::impactTime(double horizon, Contact* wall) const
{
  if (moving_ == Moving::None)
  {
    return INF;
  }
  const GearMesh mesh(params_);
  const double g0 = mesh.gap(start_.load_position, start_.motor_position);
  const double scale = moving_ == Moving::Load ? 1.0 : -params_.gear_ratio;
  const double magnitude = std::fabs(start_.load_position) + params_.backlash;
  const double t = firstExit(g0, scale, 0.0, params_.backlash, magnitude, horizon);
  if (t < INF)
  {
    *wall = g0 + scale * displacement(t) < 0.5 * params_.backlash ? Contact::Forward : Contact::Backward;
  }
  return t;
}

double StuckMotion::breakawayTime(double horizon) const
{
  if (moving_ != Moving::Load || law_.stiffness == 0.0)
  {
    return INF;  // the motor torque does not depend on anything that moves
  }
  // |a − kθ_c| ≤ T_sm ⇔ θ_c between (a − T_sm)/k and (a + T_sm)/k.
  const double t1 = (law_.offset - params_.motor_static_friction) / law_.stiffness;
  const double t2 = (law_.offset + params_.motor_static_friction) / law_.stiffness;
  return exitTime(std::min(t1, t2), std::max(t1, t2), horizon);
}

}  // namespace backlash_servo
