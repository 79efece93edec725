#include "backlash_servo/config/profile_loader.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/params.h"

namespace backlash_servo
{
namespace
{
/// The fields each segment kind takes (anything else is refused: a typo must not be ignored).
const std::map<std::string, std::vector<std::string>>& fieldsOfKinds()
{
  static const std::map<std::string, std::vector<std::string>> fields = {
      {"step", {"time", "target"}},
      {"ramp", {"time", "target", "duration", "rate"}},
      {"sine", {"time", "amplitude", "frequency", "duration"}},
      {"move", {"time", "distance", "max_velocity", "max_acceleration"}},
      {"points", {"time", "csv"}}};
  return fields;
}

void requireFields(const YAML::Node& f, const std::string& kind, const std::string& where)
{
  const auto known = fieldsOfKinds().find(kind);
  if (known == fieldsOfKinds().end())
  {
    return;  // the unknown kind is reported below
  }
  for (const auto& field : f)
  {
    const std::string name = yamlScalar(field.first, where + ": a field name");
    if (std::find(known->second.begin(), known->second.end(), name) == known->second.end())
    {
      std::string list;
      for (const std::string& k : known->second)
      {
        list += (list.empty() ? "" : ", ") + k;
      }
      throw ConfigError(where + ": unknown field '" + name + "' of " + kind + " (" + list + ")");
    }
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

}  // namespace

std::shared_ptr<const CommandProfile> profileFromYaml(const YAML::Node& list, const std::string& dir, double start)
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
    const std::string kind = yamlScalar(item.begin()->first, where + ": the segment kind");
    const YAML::Node f = item.begin()->second;
    if (!f.IsMap())
    {
      throw ConfigError(where + ": '" + kind + "' needs its fields as a mapping ({time: ..., ...})");
    }
    requireFields(f, kind, where);
    ProfileSegment s;
    s.time = yamlNumber(f, "time", where, true);
    if (kind == "step")
    {
      s.kind = ProfileSegment::Kind::Step;
      s.target = yamlNumber(f, "target", where, true);
    }
    else if (kind == "ramp")
    {
      s.kind = ProfileSegment::Kind::Ramp;
      s.target = yamlNumber(f, "target", where, true);
      s.duration = yamlNumber(f, "duration", where, false);
      s.rate = yamlNumber(f, "rate", where, false);
    }
    else if (kind == "sine")
    {
      s.kind = ProfileSegment::Kind::Sine;
      s.amplitude = yamlNumber(f, "amplitude", where, true);
      s.frequency = yamlNumber(f, "frequency", where, true);
      s.duration = yamlNumber(f, "duration", where, true);
    }
    else if (kind == "move")
    {
      s.kind = ProfileSegment::Kind::Move;
      s.distance = yamlNumber(f, "distance", where, true);
      s.max_velocity = yamlNumber(f, "max_velocity", where, true);
      s.max_acceleration = yamlNumber(f, "max_acceleration", where, true);
    }
    else if (kind == "points")
    {
      s.kind = ProfileSegment::Kind::Points;
      if (!f["csv"])
      {
        throw ConfigError(where + ": points needs csv: FILE (time,value rows)");
      }
      std::string file = yamlScalar(f["csv"], where + ": csv");
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
  try
  {
    return std::make_shared<CommandProfile>(start, segments);
  }
  catch (const InvalidParameterError& e)
  {
    throw ConfigError(e.what());
  }
}

std::string directoryOf(const std::string& path)
{
  return path.find('/') == std::string::npos ? "." : path.substr(0, path.rfind('/'));
}

std::shared_ptr<const CommandProfile> loadProfileFile(const std::string& path, double start)
{
  if (path.size() > 4 && path.compare(path.size() - 4, 4, ".csv") == 0)
  {
    ProfileSegment s;
    s.kind = ProfileSegment::Kind::Points;
    s.points = readPoints(path, "profile");
    try
    {
      return std::make_shared<CommandProfile>(start, std::vector<ProfileSegment>{s});
    }
    catch (const InvalidParameterError& e)
    {
      throw ConfigError("profile file '" + path + "': " + e.what());
    }
  }
  const YAML::Node root = loadYamlFile(path);
  const YAML::Node list = root.IsMap() ? root["profile"] : root;
  if (!list || !list.IsSequence())
  {
    throw ConfigError("profile file '" + path +
                      "': needs a list of segments (or a `profile:` key holding one), or a .csv of time,value rows");
  }
  try
  {
    return profileFromYaml(list, directoryOf(path), start);
  }
  catch (const ConfigError& e)
  {
    throw ConfigError("profile file '" + path + "': " + e.what());
  }
}

}  // namespace backlash_servo
