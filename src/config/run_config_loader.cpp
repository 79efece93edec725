#include "backlash_servo/config/run_config_loader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "backlash_servo/config/profile_loader.h"
#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/simulation/simulator.h"

namespace backlash_servo
{
namespace
{
bool anyPresent(const KeyValues& kv, bool chart_form)
{
  for (const ParamSpec& spec : parameterTable())
  {
    const bool physical_only = spec.section == ParamSection::Servo && !inChartForm(spec);
    const bool chart_only = spec.section == ParamSection::Chart;
    if ((chart_form ? chart_only : physical_only) && kv.has(spec.key))
    {
      return true;
    }
  }
  return false;
}

/// The value of a Real key, or `fallback` (default: its table default); range-checked.
double realValue(const KeyValues& kv, const ParamSpec& spec, const double* fallback = nullptr)
{
  const double v = kv.has(spec.key) ? kv.number(spec.key) : fallback ? *fallback : spec.fallbackNumber();
  spec.check(v);
  return v;
}

std::string choiceValue(const KeyValues& kv, const ParamSpec& spec, const std::string* fallback = nullptr)
{
  const std::string v = kv.text(spec.key, fallback ? *fallback : std::string(spec.fallback));
  if (!spec.isChoice(v))
  {
    std::string list;
    for (const char* c : spec.choices)
    {
      list += (list.empty() ? "" : ", ") + std::string(c);
    }
    throw ConfigError(kv.name(spec.key) + ": must be one of " + list + " (got '" + v + "')");
  }
  return v;
}

/// The Servo keys (only those shared with the chart form if chart_shared) into p: given, or their default.
void readServoKeys(const KeyValues& kv, bool chart_shared, ServoParams* p)
{
  auto value_of = [&](const char* key) { return p->*std::get<double ServoParams::*>(param(key).field); };
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (chart_shared && !inChartForm(*spec))
    {
      continue;
    }
    if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
    {
      p->*(*text) = choiceValue(kv, *spec);
    }
    else
    {
      p->*std::get<double ServoParams::*>(spec->field) =
          kv.has(spec->key) ? kv.number(spec->key) : spec->defaultValue(value_of);
    }
  }
}

}  // namespace

namespace
{
/// The drive's Choice keys and their fields (the Real keys name their fields in the table).
constexpr std::pair<const char*, std::string DriveParams::*> DRIVE_CHOICES[] = {
    {"control_law", &DriveParams::control_law},
    {"feedback", &DriveParams::feedback},
    {"compensation", &DriveParams::compensation},
    {"dither_shape", &DriveParams::dither_shape}};
}  // namespace

KeyValues driveKeyValues(const DriveParams& d)
{
  KeyValues kv;
  kv.nameKeysAsFlags(false);
  for (const ParamSpec* spec : paramsIn(ParamSection::Drive))
  {
    if (const auto* f = std::get_if<double DriveParams::*>(&spec->field))
    {
      kv.setNumber(spec->key, d.*(*f));
    }
  }
  for (const auto& [key, field] : DRIVE_CHOICES)
  {
    kv.set(key, d.*field);
  }
  return kv;
}

void updateServoKeys(const KeyValues& kv, ServoParams* p)
{
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (!kv.has(spec->key))
    {
      continue;
    }
    if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
    {
      p->*(*text) = choiceValue(kv, *spec);
    }
    else
    {
      p->*std::get<double ServoParams::*>(spec->field) = kv.number(spec->key);
    }
  }
}

IdentificationPrior identificationPriorFrom(const KeyValues& kv)
{
  for (const ParamSpec* spec : paramsIn(ParamSection::Chart))
  {
    if (kv.has(spec->key))
    {
      throw ConfigError("the prior must be in physical form (motor_inertia, …), not the chart form (" +
                        kv.name(spec->key) + "): the estimates replace physical keys");
    }
  }
  if (!kv.has("gear_ratio"))
  {
    throw ConfigError("the gear ratio must be known: give gear_ratio in the prior (or --gear-ratio)");
  }
  IdentificationPrior prior;
  ServoParams& p = prior.params;
  // Placeholders for what is not stated: no dry friction, no load torque, rigid teeth; the identification replaces
  // them or reports them unknown.
  p.motor_static_friction = p.load_static_friction = 0.0;
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (kv.has(spec->key))
    {
      prior.stated.insert(spec->key);
    }
  }
  updateServoKeys(kv, &p);
  for (const std::string& key : prior.stated)
  {
    const ParamSpec& spec = param(key);
    if (const auto* field = std::get_if<double ServoParams::*>(&spec.field))
    {
      spec.check(p.*(*field));
    }
  }
  // A static level not stated is at least the Coulomb level stated.
  for (const auto& [stat, coulomb] :
       {std::make_pair(&ServoParams::motor_static_friction, &ServoParams::motor_coulomb_friction),
        std::make_pair(&ServoParams::load_static_friction, &ServoParams::load_coulomb_friction)})
  {
    p.*stat = std::max(p.*stat, p.*coulomb);
  }
  p.validateValues();
  // The drive's keys each in their range (a node's configuration is a valid prior); the encoders' resolutions say
  // how the recording's angles were measured.
  DriveParams drive;
  readDriveKeys(kv, false, &drive);
  prior.motor_encoder_resolution = drive.motor_encoder_resolution;
  prior.load_encoder_resolution = drive.load_encoder_resolution;
  return prior;
}

void readDriveKeys(const KeyValues& kv, bool keep_absent, DriveParams* d)
{
  for (const ParamSpec* spec : paramsIn(ParamSection::Drive))
  {
    if (const auto* f = std::get_if<double DriveParams::*>(&spec->field))
    {
      d->*(*f) = realValue(kv, *spec, keep_absent ? &(d->*(*f)) : nullptr);
    }
  }
  for (const auto& [key, field] : DRIVE_CHOICES)
  {
    d->*field = choiceValue(kv, param(key), keep_absent ? &(d->*field) : nullptr);
  }
}

void requireKnownKeys(const KeyValues& kv, const std::string& source)
{
  for (const auto& item : kv.keys())
  {
    if (findParam(item.first) == nullptr)
    {
      throw ConfigError(source + ": unknown key '" + item.first + "'" + didYouMean(item.first));
    }
  }
}

RunConfig runConfigFrom(const KeyValues& kv, ControlMode mode)
{
  RunConfig c;
  const bool chart = anyPresent(kv, true);
  if (chart && anyPresent(kv, false))
  {
    throw ConfigError("give either physical parameters (" + kv.name("motor_inertia") + " ... " + kv.name("gain") +
                      ") or the chart form (" + kv.name("zeta") + " " + kv.name("inertia_ratio") + " " +
                      kv.name("friction_ratio") + " ...), not both");
  }
  if (chart)
  {
    ChartParams ch;
    for (const ParamSpec* spec : paramsIn(ParamSection::Chart))
    {
      if (*spec->fallback == '\0' && !kv.has(spec->key))
      {
        throw ConfigError(kv.name(spec->key) + " is required in the chart form");
      }
      ch.*std::get<double ChartParams::*>(spec->field) =
          kv.has(spec->key) ? kv.number(spec->key) : spec->fallbackNumber();
    }
    // The keys both forms share.
    ch.gear_ratio = kv.number("gear_ratio", param("gear_ratio").fallbackNumber());
    ch.backlash = kv.number("backlash", param("backlash").fallbackNumber());
    ch.restitution = kv.number("restitution", param("restitution").fallbackNumber());
    ServoParams shared;
    readServoKeys(kv, true, &shared);
    ch.load_torque = shared.load_torque;
    ch.motor_coulomb_friction = shared.motor_coulomb_friction;
    ch.motor_static_friction = shared.motor_static_friction;
    ch.load_coulomb_friction = shared.load_coulomb_friction;
    ch.load_static_friction = shared.load_static_friction;
    c.params = ch.toServoParams();
    // Every other key the forms share (the compliant mesh and shaft) is the physical one as given.
    for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
    {
      if (!inChartForm(*spec))
      {
        continue;
      }
      if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
      {
        c.params.*(*text) = shared.*(*text);
      }
      else
      {
        const auto field = std::get<double ServoParams::*>(spec->field);
        c.params.*field = shared.*field;
      }
    }
    c.params.validate();
  }
  else
  {
    readServoKeys(kv, false, &c.params);
    c.params.validate();
  }
  readDriveKeys(kv, false, &c.drive);
  c.drive.validate(mode);
  c.command = realValue(kv, param("command"));
  if (kv.has("profile"))
  {
    if (kv.has("command"))
    {
      throw ConfigError("give either " + kv.name("command") + " or " + kv.name("profile") + ", not both");
    }
    c.profile = loadProfileFile(kv.text("profile", ""), realValue(kv, param("load_position")));
    c.command = c.profile->finalValue();
  }
  c.duration = realValue(kv, param("duration"));
  c.max_duration = realValue(kv, param("max_duration"));
  c.max_events = realValue(kv, param("max_events"));
  c.settling_band = realValue(kv, param("settling_band"));
  State& s = c.initial;
  s.contact = contactFromString(choiceValue(kv, param("contact")));
  s.load_position = realValue(kv, param("load_position"));
  s.load_velocity = realValue(kv, param("load_velocity"));
  const GearMesh mesh(c.params);
  s.motor_position = kv.has("motor_position") ? realValue(kv, param("motor_position"))
                                              : mesh.motorPositionOnWall(s.load_position, s.contact);
  s.motor_velocity =
      kv.has("motor_velocity") ? realValue(kv, param("motor_velocity")) : mesh.motorVelocityInContact(s.load_velocity);
  checkProfile(c);
  // Let the simulator's own validation (gap range, contact consistency) speak now, before any output is written.
  Simulator check(c.params, s, c.command);
  return c;
}

std::vector<std::string> inputWarnings(const RunConfig& config)
{
  std::vector<std::string> out;
  constexpr double DEGREE = 3.14159265358979323846 / 180.0;  // [rad]
  const ServoParams& p = config.params;
  if (p.gear_ratio <= 0.2 && p.backlash > 2.0 * DEGREE)
  {
    char buf[400];
    const double step = std::fabs(config.command - config.initial.load_position);
    std::snprintf(
        buf, sizeof buf,
        "backlash: %g rad is %.3g° at the load%s — a gearbox's backlash is usually a few arcmin (1 arcmin = "
        "2.909e-4 rad). backlash is in rad: %g° would be %.6g rad",
        p.backlash, p.backlash / DEGREE,
        step > 0.0 ? (" (" + formatNumber(std::round(100.0 * p.backlash / step)) + " % of the step)").c_str() : "",
        p.backlash, p.backlash * DEGREE);
    out.push_back(buf);
  }
  return out;
}

}  // namespace backlash_servo
