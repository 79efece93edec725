#include "sim_options.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace backlash_servo
{
namespace
{
const std::vector<std::string> PHYSICAL_KEYS = {"motor_inertia", "load_inertia", "motor_friction", "load_friction",
                                                "gain"};
const std::vector<std::string> CHART_KEYS = {"zeta", "natural_frequency", "total_inertia", "inertia_ratio",
                                             "friction_ratio"};

bool anyOf(const KeyValues& kv, const std::vector<std::string>& keys)
{
  return std::any_of(keys.begin(), keys.end(), [&](const std::string& k) { return kv.has(k); });
}
}  // namespace

std::string flagName(const std::string& key)
{
  std::string f = "--" + key;
  std::replace(f.begin(), f.end(), '_', '-');
  return f;
}

const std::vector<std::string>& modelKeys()
{
  static const std::vector<std::string> keys = {
      "motor_inertia",  "load_inertia",      "motor_friction", "load_friction", "gain",           "gear_ratio",
      "zeta",           "natural_frequency", "total_inertia",  "inertia_ratio", "friction_ratio", "backlash",
      "restitution",    "command",           "duration",       "max_duration",  "load_position",  "load_velocity",
      "motor_position", "motor_velocity",    "contact"};
  return keys;
}

const std::vector<std::string>& nodeOnlyKeys()
{
  static const std::vector<std::string> keys = {
      "control_mode",    "motor_effort",     "publish_rate", "real_time_factor", "publish_clock", "motor_joint_name",
      "load_joint_name", "min_impact_speed", "paused",       "stop_after",       "start_delay"};
  return keys;
}

void KeyValues::loadYaml(const std::string& path)
{
  YAML::Node root;
  try
  {
    root = YAML::LoadFile(path);
  }
  catch (const YAML::BadFile&)
  {
    throw UsageError("cannot read config file '" + path + "'");
  }
  catch (const YAML::Exception& e)
  {
    throw UsageError("config file '" + path + "' is not valid YAML: " + e.what());
  }
  if (root.IsNull())
  {
    return;  // empty file: nothing to set
  }
  if (!root.IsMap())
  {
    throw UsageError("config file '" + path + "' must be a mapping of key: value");
  }
  for (const auto& item : root)
  {
    const std::string key = item.first.as<std::string>();
    if (!item.second.IsScalar())
    {
      throw UsageError("config file '" + path + "': key '" + key + "' must have a single value");
    }
    values_[key] = item.second.as<std::string>();
  }
}

double KeyValues::number(const std::string& key) const
{
  const std::string& text = values_.at(key);
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end == text.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v))
  {
    throw UsageError(name(key) + ": expected a finite number, got '" + text + "'");
  }
  return v;
}

std::string KeyValues::text(const std::string& key, const std::string& fallback) const
{
  auto it = values_.find(key);
  return it == values_.end() ? fallback : it->second;
}

RunConfig runConfigFrom(const KeyValues& kv)
{
  RunConfig c;
  const bool chart = anyOf(kv, CHART_KEYS);
  if (chart && anyOf(kv, PHYSICAL_KEYS))
  {
    throw UsageError("give either physical parameters (" + kv.name("motor_inertia") + " ... " + kv.name("gain") +
                     ") or the chart form (" + kv.name("zeta") + " " + kv.name("inertia_ratio") + " " +
                     kv.name("friction_ratio") + " ...), not both");
  }
  if (chart)
  {
    for (const char* required : {"zeta", "inertia_ratio", "friction_ratio"})
    {
      if (!kv.has(required))
      {
        throw UsageError(kv.name(required) + " is required in the chart form");
      }
    }
    ChartParams ch;
    ch.zeta = kv.number("zeta");
    ch.natural_frequency = kv.number("natural_frequency", 1.0);
    ch.total_inertia = kv.number("total_inertia", 1.0);
    ch.inertia_ratio = kv.number("inertia_ratio");
    ch.friction_ratio = kv.number("friction_ratio");
    ch.gear_ratio = kv.number("gear_ratio", 1.0);
    ch.backlash = kv.number("backlash", ch.backlash);
    ch.restitution = kv.number("restitution", ch.restitution);
    c.params = ch.toServoParams();
  }
  else
  {
    ServoParams& p = c.params;
    p.motor_inertia = kv.number("motor_inertia", p.motor_inertia);
    p.load_inertia = kv.number("load_inertia", p.load_inertia);
    p.motor_friction = kv.number("motor_friction", p.motor_friction);
    p.load_friction = kv.number("load_friction", p.load_friction);
    p.gain = kv.number("gain", p.gain);
    p.gear_ratio = kv.number("gear_ratio", p.gear_ratio);
    p.backlash = kv.number("backlash", p.backlash);
    p.restitution = kv.number("restitution", p.restitution);
    p.validate();
  }
  c.command = kv.number("command", 1.0);
  c.duration = kv.number("duration", 0.0);
  c.max_duration = kv.number("max_duration", 0.0);
  if (c.duration < 0.0 || c.max_duration < 0.0)
  {
    throw UsageError(kv.name("duration") + " and " + kv.name("max_duration") +
                     " must be >= 0 s (0 = run until the verdict is settled)");
  }
  State& s = c.initial;
  try
  {
    s.contact = contactFromString(kv.text("contact", "forward"));
  }
  catch (const std::invalid_argument& e)
  {
    throw UsageError(kv.name("contact") + ": " + e.what());
  }
  const double rho = c.params.gear_ratio;
  s.load_position = kv.number("load_position", 0.0);
  s.load_velocity = kv.number("load_velocity", 0.0);
  const double wall = s.contact == Contact::Backward ? c.params.backlash : 0.0;
  s.motor_position = kv.number("motor_position", (s.load_position - wall) / rho);
  s.motor_velocity = kv.number("motor_velocity", s.load_velocity / rho);
  // Let the simulator's own validation (gap range, contact consistency) speak now, before any output is written.
  Simulator check(c.params, s, c.command);
  return c;
}

}  // namespace backlash_servo
