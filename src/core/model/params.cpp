#include "backlash_servo/model/params.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
void requireFinite(const std::string& field, double value)
{
  if (!std::isfinite(value))
  {
    throw InvalidParameterError(field, "must be a finite number (got " + formatNumber(value) + ")");
  }
}

void requireThat(bool ok, const std::string& field, const std::string& what)
{
  if (!ok)
  {
    throw InvalidParameterError(field, what);
  }
}

std::string formatNumber(double value)
{
  char buf[40];
  // Shortest of %.15g / %.17g that reads back as the same double: "0.1", not "0.10000000000000001".
  std::snprintf(buf, sizeof buf, "%.15g", value);
  if (std::isfinite(value) && std::strtod(buf, nullptr) != value)
  {
    std::snprintf(buf, sizeof buf, "%.17g", value);
  }
  return buf;
}

void ServoParams::validateValues() const
{
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
    {
      if (!spec->isChoice(this->*(*text)))
      {
        std::string list;
        for (const char* c : spec->choices)
        {
          list += (list.empty() ? "" : " or ") + std::string(c);
        }
        throw InvalidParameterError(spec->key, "must be " + list + " (got '" + this->*(*text) + "')");
      }
      continue;
    }
    spec->check(this->*std::get<double ServoParams::*>(spec->field));
  }
  // A body that sticks must need at least the sliding torque to break away (docs/model.md Part 2).
  auto requireStaticAtLeastCoulomb = [](const char* key, double static_value, const char* coulomb_key, double coulomb) {
    if (static_value < coulomb)
    {
      throw InvalidParameterError(key, "must be >= " + std::string(coulomb_key) + " " + formatNumber(coulomb) +
                                           " N·m (got " + formatNumber(static_value) + ")");
    }
  };
  requireStaticAtLeastCoulomb("motor_static_friction", motor_static_friction, "motor_coulomb_friction",
                              motor_coulomb_friction);
  requireStaticAtLeastCoulomb("load_static_friction", load_static_friction, "load_coulomb_friction",
                              load_coulomb_friction);
  // The compliant joint's keys (docs/model.md, "The compliant joint") belong together.
  auto requireWith = [](bool ok, const char* key, double value, const char* why) {
    if (!ok)
    {
      throw InvalidParameterError(key, formatNumber(value) + " " + why);
    }
  };
  const char* const RIGID = "needs mesh_stiffness > 0 (a compliant mesh; rigid teeth have none)";
  requireWith(compliant() || mesh_damping == 0.0, "mesh_damping", mesh_damping, RIGID);
  requireWith(compliant() || gear_inertia == 0.0, "gear_inertia", gear_inertia,
              "needs mesh_stiffness > 0 (with rigid teeth the output gear is part of load_inertia)");
  requireWith(compliant() || shaft_stiffness == 0.0, "shaft_stiffness", shaft_stiffness,
              "needs mesh_stiffness > 0 (a torsional shaft is modelled behind a compliant mesh)");
  requireWith(shaft_damping == 0.0 || torsionalShaft(), "shaft_damping", shaft_damping,
              "needs shaft_stiffness > 0 (a rigid shaft has no twist to damp)");
  requireWith(!torsionalShaft() || gear_inertia > 0.0, "shaft_stiffness", shaft_stiffness,
              "needs gear_inertia > 0 (the output gear between the mesh and the shaft)");
}

void ServoParams::validate() const
{
  validateValues();
  validateEnvelope(true);
}

void ServoParams::validateEnvelope(bool with_gain) const
{
  // The derived quantities of the validated envelope (docs/validation.md): outside it the core's promises were not
  // measured. The message names every key the quantity follows from, with its value (an absent key has its default, the
  // thesis' App. D1 value for the mechanics: a robot joint that leaves out motor_friction gets 0.48 N·m·s/rad).
  auto refuse = [&](const char* what, double value, const char* range, std::initializer_list<const char*> keys) {
    std::string from;
    for (const char* key : keys)
    {
      from += (from.empty() ? "" : ", ") + std::string(key) + " " +
              formatNumber(this->*std::get<double ServoParams::*>(param(key).field));
    }
    throw InvalidParameterError(what, formatNumber(value) + " lies outside the validated envelope " + range +
                                          "; it follows from " + from +
                                          " (a key not given has its default; see the parameter table)");
  };
  // Derived values get a rounding slack: the chart form's bounds must convert back inside.
  constexpr double SLACK = 1e-9;
  const double split = inertiaRatio();
  if (!(split >= INERTIA_SPLIT_MIN * (1.0 - SLACK) && split <= INERTIA_SPLIT_MAX * (1.0 + SLACK)))
  {
    refuse("inertia split ρ²J_L/J_m", split, "[0.001, 1000]", {"load_inertia", "motor_inertia", "gear_ratio"});
  }
  const double omega_n = naturalFrequency();
  if (with_gain &&
      !(omega_n >= NATURAL_FREQUENCY_MIN * (1.0 - SLACK) && omega_n <= NATURAL_FREQUENCY_MAX * (1.0 + SLACK)))
  {
    refuse("natural frequency ω_n = √(ρK/J) [rad/s]", omega_n, "[0.001, 10000] rad/s",
           {"gain", "gear_ratio", "motor_inertia", "load_inertia"});
  }
  const double zeta = dampingRatio();
  if (with_gain && !(zeta <= DAMPING_RATIO_MAX * (1.0 + SLACK)))
  {
    refuse("damping ratio ζ = (f_m + ρ²f_L)/(2ω_n J)", zeta, "[0, 100]",
           {"motor_friction", "load_friction", "gain", "gear_ratio", "motor_inertia", "load_inertia"});
  }
  if (compliant())
  {
    // The compliant joint's envelope: the two sides of the mesh (and of the shaft) within the rigid inertia split's
    // range of each other, their contact (shaft) frequency at most COMPLIANT_FREQUENCY_RATIO_MAX times ω_n and their
    // damping rate at most COMPLIANT_DAMPING_RATE_RATIO_MAX times.
    const double rho = gear_ratio;
    const double jo = torsionalShaft() ? gear_inertia : load_inertia + gear_inertia;
    const double mesh_split = rho * rho * jo / motor_inertia;
    if (!(mesh_split >= INERTIA_SPLIT_MIN * (1.0 - SLACK) && mesh_split <= INERTIA_SPLIT_MAX * (1.0 + SLACK)))
    {
      refuse("mesh inertia split ρ²J_o/J_m (J_o: the output side of the mesh)", mesh_split, "[0.001, 1000]",
             {"gear_inertia", "load_inertia", "motor_inertia", "gear_ratio", "shaft_stiffness"});
    }
    const double mu = motor_inertia * jo / (motor_inertia + rho * rho * jo);
    const double contact = std::sqrt(mesh_stiffness / mu) / omega_n;
    if (with_gain && !(contact <= COMPLIANT_FREQUENCY_RATIO_MAX * (1.0 + SLACK)))
    {
      refuse("contact frequency ratio √(c/μ)/ω_n", contact, "[0, 10000]",
             {"mesh_stiffness", "gear_inertia", "load_inertia", "motor_inertia", "gear_ratio", "gain"});
    }
    const double contact_damping = mesh_damping / mu / omega_n;
    if (with_gain && !(contact_damping <= COMPLIANT_DAMPING_RATE_RATIO_MAX * (1.0 + SLACK)))
    {
      refuse("contact damping rate ratio (d/μ)/ω_n", contact_damping, "[0, 100000]",
             {"mesh_damping", "gear_inertia", "load_inertia", "motor_inertia", "gear_ratio", "gain"});
    }
    if (torsionalShaft())
    {
      const double shaft_split = gear_inertia / load_inertia;
      if (!(shaft_split >= INERTIA_SPLIT_MIN * (1.0 - SLACK) && shaft_split <= INERTIA_SPLIT_MAX * (1.0 + SLACK)))
      {
        refuse("shaft inertia split J_g/J_L", shaft_split, "[0.001, 1000]", {"gear_inertia", "load_inertia"});
      }
      const double shaft =
          std::sqrt(shaft_stiffness * (gear_inertia + load_inertia) / (gear_inertia * load_inertia)) / omega_n;
      if (with_gain && !(shaft <= COMPLIANT_FREQUENCY_RATIO_MAX * (1.0 + SLACK)))
      {
        refuse("shaft frequency ratio √(k_s(J_g + J_L)/(J_g J_L))/ω_n", shaft, "[0, 10000]",
               {"shaft_stiffness", "gear_inertia", "load_inertia", "gain", "gear_ratio", "motor_inertia"});
      }
      const double shaft_damping_rate =
          shaft_damping * (gear_inertia + load_inertia) / (gear_inertia * load_inertia) / omega_n;
      if (with_gain && !(shaft_damping_rate <= COMPLIANT_DAMPING_RATE_RATIO_MAX * (1.0 + SLACK)))
      {
        refuse("shaft damping rate ratio (d_s(J_g + J_L)/(J_g J_L))/ω_n", shaft_damping_rate, "[0, 100000]",
               {"shaft_damping", "gear_inertia", "load_inertia", "gain", "gear_ratio", "motor_inertia"});
      }
    }
  }
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
  for (const ParamSpec* spec : paramsIn(ParamSection::Chart))
  {
    spec->check(this->*std::get<double ChartParams::*>(spec->field));
  }
  param("gear_ratio").check(gear_ratio);
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
  p.load_torque = load_torque;
  p.motor_coulomb_friction = motor_coulomb_friction;
  p.motor_static_friction = motor_static_friction;
  p.load_coulomb_friction = load_coulomb_friction;
  p.load_static_friction = load_static_friction;
  p.validate();
  return p;
}

}  // namespace backlash_servo
