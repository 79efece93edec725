#include "backlash_servo/config/profile_loader.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/model/params.h"

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
      {"sine", {"time", "amplitude", "frequency", "duration", "dither_amplitude", "dither_frequency"}},
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

/// True for a header cell: a name ("time", "command [rad]"), never something that reads as a number (".5", "nan").
bool isHeaderCell(const std::string& cell)
{
  if (cell.empty() || !std::isalpha(static_cast<unsigned char>(cell[0])))
  {
    return false;
  }
  std::string lower;
  for (char c : cell)
  {
    lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return lower.rfind("nan", 0) != 0 && lower.rfind("inf", 0) != 0;
}

/**
 * A CSV of time,value rows (time [s] from the segment's start, value [rad]): exactly two columns per row; '#' lines
 * and empty lines are comments; the first row may be a header of two names. NUL bytes, carriage returns (Windows
 * line ends) and anything that is not a number are refused with the row named.
 */
std::vector<std::pair<double, double>> readPoints(const std::string& path, const std::string& where)
{
  const std::string text = readRegularFile(where, path, std::size_t(256) << 20);
  std::vector<std::pair<double, double>> points;
  std::size_t start = 0;
  int row = 0;
  bool first_data_row = true;
  while (start < text.size())
  {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos)
    {
      end = text.size();
    }
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    ++row;
    const std::string at = where + ": '" + path + "' row " + std::to_string(row);
    if (line.find('\0') != std::string::npos)
    {
      throw ConfigError(at + " contains a NUL byte (not a text file)");
    }
    if (line.find('\r') != std::string::npos)
    {
      throw ConfigError(at + " ends in a carriage return (Windows line ends): convert the file, e.g. dos2unix");
    }
    if (line.empty() || line[0] == '#')
    {
      continue;
    }
    const std::vector<std::string> cells = splitCsvCells(line);
    if (cells.size() != 2)
    {
      throw ConfigError(at + " has " + std::to_string(cells.size()) + " columns; each row is time,value");
    }
    if (first_data_row && isHeaderCell(cells[0]) && isHeaderCell(cells[1]))
    {
      first_data_row = false;
      continue;  // the header
    }
    first_data_row = false;
    KeyValues kv;
    kv.set("time", cells[0]);
    kv.set("value", cells[1]);
    try
    {
      points.emplace_back(kv.number("time"), kv.number("value"));
    }
    catch (const ConfigError& e)
    {
      throw ConfigError(at + ": " + e.what());
    }
  }
  return points;
}

}  // namespace

std::shared_ptr<const CommandProfile> profileFromYaml(const YAML::Node& list, const std::string& dir, double start)
{
  if (!list.IsSequence() || list.size() == 0)
  {
    throw ConfigError("profile: must be a non-empty list of segments (- step: {...}, - ramp: {...}, ...)");
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
      s.dither_amplitude = yamlNumber(f, "dither_amplitude", where, false);
      s.dither_frequency = yamlNumber(f, "dither_frequency", where, false);
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
  const YAML::Node root = loadYamlFile(path, "profile file");
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
