#include "backlash_servo/config/compare_config.h"

#include <yaml-cpp/yaml.h>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/profile_loader.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/param_table.h"

namespace backlash_servo
{
namespace
{
/// Scalar keys of a map into kv (checked against the parameter table), skipping `skip`.
void readKeys(const YAML::Node& map, const std::vector<std::string>& skip, const std::string& where, KeyValues* kv)
{
  for (const auto& item : map)
  {
    const std::string key = item.first.as<std::string>();
    if (std::find(skip.begin(), skip.end(), key) != skip.end())
    {
      continue;
    }
    if (findParam(key) == nullptr)
    {
      throw ConfigError(where + ": unknown key '" + key + "'");
    }
    if (!item.second.IsScalar())
    {
      throw ConfigError(where + ": key '" + key + "' must have a single value");
    }
    kv->set(key, item.second.as<std::string>());
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
  readKeys(root, {"duration", "sample_rate", "profile", "strategies"}, path, &shared);
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
    st.name = s["name"].as<std::string>();
    KeyValues kv = shared;
    readKeys(s, {"name"}, where + " (" + st.name + ")", &kv);
    try
    {
      st.config = runConfigFrom(kv);
    }
    catch (const std::exception& e)
    {
      throw ConfigError(where + " (" + st.name + "): " + e.what());
    }
    st.config.duration = c.duration;
    if (!c.profile)
    {
      ProfileSegment step;
      step.target = st.config.command;
      c.profile = std::make_shared<CommandProfile>(st.config.initial.load_position, std::vector<ProfileSegment>{step});
    }
    st.config.profile = c.profile;
    if (!st.config.drive.sampled())
    {
      throw ConfigError(where + " (" + st.name +
                        "): the workbench compares digital drives: set controller_rate > 0 "
                        "Hz");
    }
    c.strategies.push_back(st);
  }
  return c;
}

}  // namespace backlash_servo
