#include "backlash_servo/params.h"

#include <cmath>

namespace backlash_servo
{
void requireFinite(const std::string& field, double value)
{
  if (!std::isfinite(value))
  {
    throw InvalidParameterError(field, "must be a finite number");
  }
}

namespace
{
void requirePositive(const std::string& field, double value)
{
  requireFinite(field, value);
  if (!(value > 0.0))
  {
    throw InvalidParameterError(field, "must be > 0 (got " + std::to_string(value) + ")");
  }
}

void requireNonNegative(const std::string& field, double value)
{
  requireFinite(field, value);
  if (!(value >= 0.0))
  {
    throw InvalidParameterError(field, "must be >= 0 (got " + std::to_string(value) + ")");
  }
}

void requireUnitInterval(const std::string& field, double value)
{
  requireFinite(field, value);
  if (!(value >= 0.0 && value <= 1.0))
  {
    throw InvalidParameterError(field, "must be in [0, 1] (got " + std::to_string(value) + ")");
  }
}
}  // namespace

void ServoParams::validate() const
{
  requirePositive("motor_inertia", motor_inertia);
  requirePositive("load_inertia", load_inertia);
  requireNonNegative("motor_friction", motor_friction);
  requireNonNegative("load_friction", load_friction);
  requirePositive("gain", gain);
  requirePositive("gear_ratio", gear_ratio);
  requireNonNegative("backlash", backlash);
  requireUnitInterval("restitution", restitution);
}

double ServoParams::naturalFrequency() const
{
  return std::sqrt(gear_ratio * gain / totalInertia());
}

double ServoParams::dampingRatio() const
{
  return totalFriction() / (2.0 * naturalFrequency() * totalInertia());
}

double ServoParams::frictionRatio() const
{
  const double total = totalFriction();
  return total > 0.0 ? gear_ratio * gear_ratio * load_friction / total : 0.0;
}

ServoParams ChartParams::toServoParams() const
{
  requireNonNegative("zeta", zeta);
  requirePositive("natural_frequency", natural_frequency);
  requirePositive("total_inertia", total_inertia);
  requirePositive("inertia_ratio", inertia_ratio);
  requireUnitInterval("friction_ratio", friction_ratio);
  requirePositive("gear_ratio", gear_ratio);
  const double rho2 = gear_ratio * gear_ratio;
  ServoParams p;
  p.gear_ratio = gear_ratio;
  // J = J_m (1 + r) with r = ρ² J_L / J_m.
  p.motor_inertia = total_inertia / (1.0 + inertia_ratio);
  p.load_inertia = (total_inertia - p.motor_inertia) / rho2;
  const double total_friction = 2.0 * zeta * natural_frequency * total_inertia;
  p.load_friction = friction_ratio * total_friction / rho2;
  p.motor_friction = (1.0 - friction_ratio) * total_friction;
  // ω_n² = ρ K / J.
  p.gain = natural_frequency * natural_frequency * total_inertia / gear_ratio;
  p.backlash = backlash;
  p.restitution = restitution;
  p.validate();
  return p;
}

}  // namespace backlash_servo
