/**
 * @file key_values.h
 * @brief Raw parameter values by key, from a YAML file, command-line flags or ROS params, before they become a
 *        RunConfig. Values keep their type (text from files and flags, numbers and booleans from ROS): no text
 *        round trips. No ROS dependency.
 */
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace YAML
{
class Node;
}

namespace backlash_servo
{
/// Bad command line, config file or parameter set; tools print it on one line and exit with code 2, the node logs it.
class ConfigError : public std::runtime_error
{
 public:
  using std::runtime_error::runtime_error;
};

/// "--motor-inertia" for "motor_inertia".
std::string flagName(const std::string& key);

/// The candidate closest to `name` by edit distance (insertions, deletions, substitutions and swaps of neighbours),
/// if it is close enough to be a typo of it (at most 2 edits, or a quarter of the name's length); "" otherwise.
std::string nearestName(const std::string& name, const std::vector<std::string>& candidates);
/// nearestName() over the parameter table's keys.
std::string nearestKey(const std::string& key);
/// " (did you mean 'KEY'?)" for nearestKey(key), or "" — the end of an unknown key's message.
std::string didYouMean(const std::string& key);

/**
 * The YAML document in `path` (a regular file of at most 64 MiB). Throws ConfigError naming `what` ("config file",
 * "profile file") and the path when it cannot be read, is not valid YAML, or a mapping repeats a key (which value
 * wins would otherwise depend on the reader).
 */
YAML::Node loadYamlFile(const std::string& path, const std::string& what = "config file");

/// The text of a YAML scalar; throws ConfigError "<what> must be a single value …" for a list, a mapping or a
/// missing node (a key written as `? [a, b]` or `{a: 1}: 2` too).
std::string yamlScalar(const YAML::Node& node, const std::string& what);

/// A number under `key` of a YAML map (fallback when absent and not required); throws ConfigError naming `where`
/// and the key for a missing required key or a value that is not a finite number.
double yamlNumber(const YAML::Node& map, const std::string& key, const std::string& where, bool required,
                  double fallback = 0.0);

class KeyValues;
/// The scalar keys of a YAML map into *kv, each checked against the parameter table, skipping the keys in `skip`
/// (the file's own structure); throws ConfigError naming `where` and the key (an unknown key with its nearest).
void readYamlKeys(const YAML::Node& map, const std::vector<std::string>& skip, const std::string& where, KeyValues* kv);

class KeyValues
{
 public:
  /// Reads a flat YAML mapping of scalars; throws ConfigError naming the file and the problem.
  void loadYaml(const std::string& path);
  /// A value as text (flags, YAML); parsed when read.
  void set(const std::string& key, const std::string& text);
  /// A value that already is a number (ROS params, dynamic_reconfigure).
  void setNumber(const std::string& key, double value);
  /// A value that already is a boolean.
  void setBoolean(const std::string& key, bool value);
  /// (A view: the parameter table's keys are looked up for every run's configuration without a string built.)
  bool has(std::string_view key) const { return values_.count(key) != 0; }
  /// Later sources override earlier ones: copies every value of other over this.
  void overrideWith(const KeyValues& other);

  /// A finite number; throws ConfigError("--flag-name: expected a finite number, got 'abc'") otherwise.
  double number(const std::string& key) const;
  double number(const std::string& key, double fallback) const { return has(key) ? number(key) : fallback; }
  /// true/false (also "true"/"false" text); throws ConfigError otherwise.
  bool boolean(const std::string& key) const;
  /// The value as text (numbers formatted exactly); fallback when absent.
  std::string text(const std::string& key, const std::string& fallback) const;

  /// How errors name a key: "--motor-inertia" (command line, the default) or "motor_inertia" (YAML / ROS params).
  void nameKeysAsFlags(bool flags) { flags_ = flags; }
  std::string name(const std::string& key) const { return flags_ ? flagName(key) : key; }
  /// Every key present, in key order.
  std::map<std::string, std::string> keys() const;

 private:
  struct Value
  {
    enum class Kind
    {
      Text,
      Number,
      Boolean
    } kind = Kind::Text;
    std::string text;
    double number = 0.0;
    bool boolean = false;
  };
  std::map<std::string, Value, std::less<>> values_;  // transparent: looked up by std::string_view too
  bool flags_ = true;
};

}  // namespace backlash_servo
