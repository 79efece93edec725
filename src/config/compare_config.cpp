#include "backlash_servo/config/compare_config.h"

#include <yaml-cpp/yaml.h>

#include <fstream>
#include <sstream>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/param_table.h"

namespace backlash_servo
{
namespace
{
double number(const YAML::Node& node, const std::string& key, const std::string& where, bool required,
              double fallback = 0.0)
{
  if (!node[key])
  {
    if (required)
    {
      throw ConfigError(where + ": '" + key + "' is required");
    }
    return fallback;
  }
  KeyValues kv;
  kv.set(key, node[key].as<std::string>());
  try
  {
    return kv.number(key);
  }
  catch (const std::exception&)
  {
    throw ConfigError(where + ": '" + key + "' must be a number (got '" + node[key].as<std::string>() + "')");
  }
}

std::vector<std::pair<double, double>> readPoints(const std::string& path, const std::string& where)
{
  std::ifstream in(path);
  if (!in)
  {
    throw ConfigError(where + ": cannot read '" + path + "'");
  }
  std::vector<std::pair<double, double>> points;
  std::string line;
  int row = 0;
  while (std::getline(in, line))
  {
    ++row;
    if (line.empty() || line[0] == '#' || (row == 1 && line.find_first_of("0123456789") != 0 && line[0] != '-'))
    {
      continue;  // header or comment
    }
    std::stringstream ss(line);
    std::string a, b;
    if (!std::getline(ss, a, ',') || !std::getline(ss, b, ','))
    {
      throw ConfigError(where + ": '" + path + "' row " + std::to_string(row) + " is not time,value");
    }
    KeyValues kv;
    kv.set("time", a);
    kv.set("value", b);
    points.emplace_back(kv.number("time"), kv.number("value"));
  }
  return points;
}

std::shared_ptr<const CommandProfile> profileFrom(const YAML::Node& list, const std::string& dir)
{
  if (!list.IsSequence())
  {
    throw ConfigError("profile: must be a list of segments (- step: {...}, - ramp: {...}, ...)");
  }
  std::vector<ProfileSegment> segments;
  for (std::size_t i = 0; i < list.size(); ++i)
  {
    const std::string where = "profile segment " + std::to_string(i + 1);
    const YAML::Node item = list[i];
    if (!item.IsMap() || item.size() != 1)
    {
      throw ConfigError(where + ": must be one of step, ramp, sine, move, points with its fields");
    }
    const std::string kind = item.begin()->first.as<std::string>();
    const YAML::Node f = item.begin()->second;
    ProfileSegment s;
    s.time = number(f, "time", where, true);
    if (kind == "step")
    {
      s.kind = ProfileSegment::Kind::Step;
      s.target = number(f, "target", where, true);
    }
    else if (kind == "ramp")
    {
      s.kind = ProfileSegment::Kind::Ramp;
      s.target = number(f, "target", where, true);
      s.duration = number(f, "duration", where, false);
      s.rate = number(f, "rate", where, false);
    }
    else if (kind == "sine")
    {
      s.kind = ProfileSegment::Kind::Sine;
      s.amplitude = number(f, "amplitude", where, true);
      s.frequency = number(f, "frequency", where, true);
      s.duration = number(f, "duration", where, true);
    }
    else if (kind == "move")
    {
      s.kind = ProfileSegment::Kind::Move;
      s.distance = number(f, "distance", where, true);
      s.max_velocity = number(f, "max_velocity", where, true);
      s.max_acceleration = number(f, "max_acceleration", where, true);
    }
    else if (kind == "points")
    {
      s.kind = ProfileSegment::Kind::Points;
      if (!f["csv"])
      {
        throw ConfigError(where + ": points needs csv: FILE (time,value rows)");
      }
      std::string file = f["csv"].as<std::string>();
      if (!file.empty() && file[0] != '/')
      {
        file = dir + "/" + file;
      }
      s.points = readPoints(file, where);
      for (auto& p : s.points)
      {
        p.first += s.time;
      }
    }
    else
    {
      throw ConfigError(where + ": unknown segment '" + kind + "' (step, ramp, sine, move or points)");
    }
    segments.push_back(s);
  }
  return std::make_shared<CommandProfile>(0.0, segments);
}

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
  const std::string dir = path.find('/') == std::string::npos ? "." : path.substr(0, path.rfind('/'));
  CompareConfig c;
  c.duration = number(root, "duration", path, true);
  c.sample_rate = number(root, "sample_rate", path, false, 1000.0);
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
    c.profile = profileFrom(root["profile"], dir);
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
