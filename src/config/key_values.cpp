#include "backlash_servo/config/key_values.h"

#include "backlash_servo/config/safe_input.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "backlash_servo/model/param_table.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
std::string flagName(const std::string& key)
{
  std::string f = "--" + key;
  std::replace(f.begin(), f.end(), '_', '-');
  return f;
}

namespace
{
/// Optimal-string-alignment distance: Levenshtein's edits plus the swap of two neighbours ("derivitive" is 1 from
/// "derivative", "gian" 1 from "gain").
std::size_t editDistance(const std::string& a, const std::string& b)
{
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i)
  {
    d[i][0] = i;
  }
  for (std::size_t j = 0; j <= b.size(); ++j)
  {
    d[0][j] = j;
  }
  for (std::size_t i = 1; i <= a.size(); ++i)
  {
    for (std::size_t j = 1; j <= b.size(); ++j)
    {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
      {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[a.size()][b.size()];
}
}  // namespace

std::string nearestName(const std::string& name, const std::vector<std::string>& candidates)
{
  if (name.size() > 200)
  {
    return "";  // (no key is that long: not a typo of one)
  }
  std::string best;
  std::size_t best_distance = std::max<std::size_t>(2, name.size() / 4) + 1;
  for (const std::string& c : candidates)
  {
    const std::size_t distance = editDistance(name, c);
    if (distance < best_distance)
    {
      best = c;
      best_distance = distance;
    }
  }
  return best;
}

std::string nearestKey(const std::string& key)
{
  std::vector<std::string> keys;
  for (const ParamSpec& p : parameterTable())
  {
    keys.push_back(p.key);
  }
  return nearestName(key, keys);
}

std::string didYouMean(const std::string& key)
{
  const std::string near = nearestKey(key);
  return near.empty() ? "" : " (did you mean '" + near + "'?)";
}

namespace
{
/// Throws ConfigError when a mapping anywhere in `node` holds the same key twice.
void refuseDuplicateKeys(const YAML::Node& node, const std::string& where)
{
  if (node.IsMap())
  {
    std::vector<std::string> seen;
    for (const auto& item : node)
    {
      const std::string key = item.first.IsScalar() ? item.first.Scalar() : std::string();
      if (!key.empty() && std::find(seen.begin(), seen.end(), key) != seen.end())
      {
        const YAML::Mark mark = item.first.Mark();
        throw ConfigError(where + ": key '" + key + "' is given twice" +
                          (mark.line >= 0 ? " (again at line " + std::to_string(mark.line + 1) + ")" : ""));
      }
      seen.push_back(key);
      refuseDuplicateKeys(item.second, where);
    }
  }
  else if (node.IsSequence())
  {
    for (const auto& item : node)
    {
      refuseDuplicateKeys(item, where);
    }
  }
}
}  // namespace

YAML::Node loadYamlFile(const std::string& path, const std::string& what)
{
  const std::string text = readRegularFile(what, path, std::size_t(64) << 20);
  if (text.find('\0') != std::string::npos)
  {
    throw ConfigError(what + " '" + path + "' contains a NUL byte (not a text file)");
  }
  YAML::Node root;
  try
  {
    root = YAML::Load(text);
  }
  catch (const YAML::Exception& e)
  {
    throw ConfigError(what + " '" + path + "' is not valid YAML: " + e.what());
  }
  refuseDuplicateKeys(root, what + " '" + path + "'");
  return root;
}

double yamlNumber(const YAML::Node& node, const std::string& key, const std::string& where, bool required,
                  double fallback)
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
  kv.set(key, yamlScalar(node[key], where + ": '" + key + "'"));
  try
  {
    return kv.number(key);
  }
  catch (const std::exception&)
  {
    throw ConfigError(where + ": '" + key + "' must be a number (got '" + node[key].Scalar() + "')");
  }
}

std::string yamlScalar(const YAML::Node& node, const std::string& what)
{
  if (!node.IsScalar())
  {
    throw ConfigError(what + " must be a single value (a name or a number), not a list or a mapping");
  }
  return node.Scalar();
}

void readYamlKeys(const YAML::Node& map, const std::vector<std::string>& skip, const std::string& where, KeyValues* kv)
{
  for (const auto& item : map)
  {
    const std::string key = yamlScalar(item.first, where + ": a key");
    if (std::find(skip.begin(), skip.end(), key) != skip.end())
    {
      continue;
    }
    if (findParam(key) == nullptr)
    {
      throw ConfigError(where + ": unknown key '" + key + "'" + didYouMean(key));
    }
    if (!item.second.IsScalar())
    {
      throw ConfigError(where + ": key '" + key + "' must have a single value");
    }
    kv->set(key, item.second.Scalar());
  }
}

void KeyValues::loadYaml(const std::string& path)
{
  const YAML::Node root = loadYamlFile(path);
  if (root.IsNull())
  {
    return;  // empty file: nothing to set
  }
  if (!root.IsMap())
  {
    throw ConfigError("config file '" + path + "' must be a mapping of key: value");
  }
  for (const auto& item : root)
  {
    const std::string key = yamlScalar(item.first, "config file '" + path + "': a key");
    if (key == "profile" && item.second.IsSequence())
    {
      set(key, path);  // an inline profile: the profile loader reads this file's `profile:` list
      continue;
    }
    if (key == "joints" && item.second.IsMap())
    {
      throw ConfigError("config file '" + path +
                        "' describes an arm (joints:): backlash_sim --config runs it, a joint at a time elsewhere "
                        "(docs/robot.md)");
    }
    if (!item.second.IsScalar())
    {
      throw ConfigError("config file '" + path + "': key '" + key + "' must have a single value");
    }
    std::string value = item.second.Scalar();
    if (key == "profile" && !value.empty() && value[0] != '/' && path.find('/') != std::string::npos)
    {
      value = path.substr(0, path.rfind('/') + 1) + value;  // a profile file next to the YAML
    }
    set(key, value);
  }
}

void KeyValues::set(const std::string& key, const std::string& text)
{
  Value v;
  v.text = text;
  values_[key] = v;
}

void KeyValues::setNumber(const std::string& key, double number)
{
  Value v;
  v.kind = Value::Kind::Number;
  v.number = number;
  values_[key] = v;
}

void KeyValues::setBoolean(const std::string& key, bool boolean)
{
  Value v;
  v.kind = Value::Kind::Boolean;
  v.boolean = boolean;
  values_[key] = v;
}

void KeyValues::overrideWith(const KeyValues& other)
{
  for (const auto& kv : other.values_)
  {
    values_[kv.first] = kv.second;
  }
}

double KeyValues::number(const std::string& key) const
{
  const Value& v = values_.at(key);
  if (v.kind == Value::Kind::Number)
  {
    if (!std::isfinite(v.number))
    {
      throw ConfigError(name(key) + ": expected a finite number, got " + formatNumber(v.number));
    }
    return v.number;
  }
  if (v.kind == Value::Kind::Boolean)
  {
    throw ConfigError(name(key) + ": expected a finite number, got " + (v.boolean ? "true" : "false"));
  }
  errno = 0;
  char* end = nullptr;
  const double d = std::strtod(v.text.c_str(), &end);
  if (v.text.empty() || end == v.text.c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(d))
  {
    throw ConfigError(name(key) + ": expected a finite number, got '" + v.text + "'");
  }
  return d;
}

bool KeyValues::boolean(const std::string& key) const
{
  const Value& v = values_.at(key);
  if (v.kind == Value::Kind::Boolean)
  {
    return v.boolean;
  }
  if (v.kind == Value::Kind::Text && (v.text == "true" || v.text == "false"))
  {
    return v.text == "true";
  }
  throw ConfigError(name(key) + ": expected true or false, got '" + text(key, "") + "'");
}

std::string KeyValues::text(const std::string& key, const std::string& fallback) const
{
  auto it = values_.find(key);
  if (it == values_.end())
  {
    return fallback;
  }
  switch (it->second.kind)
  {
    case Value::Kind::Number:
      return formatNumber(it->second.number);
    case Value::Kind::Boolean:
      return it->second.boolean ? "true" : "false";
    default:
      return it->second.text;
  }
}

std::map<std::string, std::string> KeyValues::keys() const
{
  std::map<std::string, std::string> out;
  for (const auto& kv : values_)
  {
    out[kv.first] = text(kv.first, "");
  }
  return out;
}

}  // namespace backlash_servo
