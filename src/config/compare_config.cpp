#include "backlash_servo/config/compare_config.h"

#include <yaml-cpp/yaml.h>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/profile_loader.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
namespace
{
/// st->config from st->keys, with the file's duration and profile (null: a step to the run's `command`, created
/// here); `where` names the strategy in errors.
void buildRun(CompareStrategy* st, double duration, std::shared_ptr<const CommandProfile>* profile,
              const std::string& where)
{
  try
  {
    st->config = runConfigFrom(st->keys);
  }
  catch (const std::exception& e)
  {
    throw ConfigError(where + ": " + e.what());
  }
  st->config.duration = duration;
  if (!*profile)
  {
    ProfileSegment step;
    step.target = st->config.command;
    *profile = std::make_shared<CommandProfile>(st->config.initial.load_position, std::vector<ProfileSegment>{step});
  }
  st->config.profile = *profile;
  try
  {
    // The continuous law (controller_rate 0) takes steps, points and ramps (without dry friction) only.
    st->config.profile->requireTakenBy(st->config.drive.sampled(), st->config.params.hasDryFriction());
  }
  catch (const std::exception& e)
  {
    throw ConfigError(where + ": " + e.what());
  }
}
}  // namespace

CompareConfig loadCompareConfig(const std::string& path)
{
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap())
  {
    throw ConfigError("config file '" + path + "' must be a mapping (joint keys, duration, profile, strategies)");
  }
  CompareConfig c;
  c.duration = yamlNumber(root, "duration", path, true);
  c.sample_rate = yamlNumber(root, "sample_rate", path, false, 1000.0);
  if (!(c.duration > 0.0) || !(c.duration <= 1e6))
  {
    throw ConfigError(path + ": duration must be in (0, 1e6] s");
  }
  if (!(c.sample_rate > 0.0) || c.duration * c.sample_rate > 5e7)
  {
    throw ConfigError(path + ": sample_rate must be > 0 Hz with at most 5e7 samples per strategy");
  }
  KeyValues shared;
  readYamlKeys(root, {"duration", "sample_rate", "profile", "strategies"}, path, &shared);
  if (!root["strategies"] || !root["strategies"].IsSequence() || root["strategies"].size() == 0)
  {
    throw ConfigError(path + ": strategies: a non-empty list of {name: ..., keys...} is required");
  }
  if (root["profile"])
  {
    c.profile = profileFromYaml(root["profile"], directoryOf(path), 0.0);
  }
  for (std::size_t i = 0; i < root["strategies"].size(); ++i)
  {
    const YAML::Node s = root["strategies"][i];
    const std::string where = "strategy " + std::to_string(i + 1);
    if (!s.IsMap() || !s["name"])
    {
      throw ConfigError(where + ": needs a name");
    }
    CompareStrategy st;
    st.name = yamlScalar(s["name"], where + ": name");
    st.keys = shared;
    readYamlKeys(s, {"name"}, where + " (" + st.name + ")", &st.keys);
    buildRun(&st, c.duration, &c.profile, where + " (" + st.name + ")");
    c.strategies.push_back(st);
  }
  return c;
}

double valueOf(const CompareStrategy& strategy, const std::string& key)
{
  const ParamSpec& spec = param(key);
  if (spec.type != ParamType::Real)
  {
    throw ConfigError("'" + key + "' is not a numeric parameter");
  }
  if (strategy.keys.has(key))
  {
    return strategy.keys.number(key);
  }
  const RunConfig& c = strategy.config;
  if (const auto* f = std::get_if<double ServoParams::*>(&spec.field))
  {
    return c.params.*(*f);
  }
  if (const auto* f = std::get_if<double DriveParams::*>(&spec.field))
  {
    return c.drive.*(*f);
  }
  if (const auto* f = std::get_if<double State::*>(&spec.field))
  {
    return c.initial.*(*f);
  }
  if (const auto* f = std::get_if<double RunConfig::*>(&spec.field))
  {
    return c.*(*f);
  }
  throw ConfigError("'" + key + "' has no value of its own in a strategy (a chart-form key: vary the physical one)");
}

CompareStrategy withValue(const CompareStrategy& strategy, const std::string& key, double value,
                          const CompareConfig& config)
{
  CompareStrategy out = strategy;
  out.keys.setNumber(key, value);
  std::shared_ptr<const CommandProfile> profile = config.profile;
  buildRun(&out, config.duration, &profile,
           "strategy '" + strategy.name + "' with " + key + " = " + formatNumber(value));
  return out;
}

}  // namespace backlash_servo
