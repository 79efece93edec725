/**
 * @file sim_options.h
 * @brief Parameters of one run from command-line flags and/or a YAML file (the keys the ROS node loads too).
 *
 * Flag `--motor-inertia` ⇔ YAML key `motor_inertia`; flags override the file. Physical and chart forms cannot be
 * mixed. Every error is a UsageError whose message names the flag or key.
 */
#pragma once

#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "backlash_servo/step_response.h"

namespace backlash_servo
{
/// Bad command line or config file; main() prints it on one line and exits with code 2.
class UsageError : public std::runtime_error
{
 public:
  using std::runtime_error::runtime_error;
};

/// "--motor-inertia" for "motor_inertia".
std::string flagName(const std::string& key);

/// Raw key → value text, from YAML then flags (later sources override earlier ones).
class KeyValues
{
 public:
  /// Reads a flat YAML mapping of scalars; throws UsageError naming the file and problem.
  void loadYaml(const std::string& path);
  void set(const std::string& key, const std::string& value) { values_[key] = value; }
  bool has(const std::string& key) const { return values_.count(key) != 0; }
  /// Parses a finite number; throws UsageError("--flag-name: ...") otherwise.
  double number(const std::string& key) const;
  double number(const std::string& key, double fallback) const { return has(key) ? number(key) : fallback; }
  std::string text(const std::string& key, const std::string& fallback) const;
  /// How errors name a key: "--motor-inertia" (command line, the default) or "motor_inertia" (YAML / ROS params).
  void nameKeysAsFlags(bool flags) { flags_ = flags; }
  std::string name(const std::string& key) const { return flags_ ? flagName(key) : key; }
  const std::map<std::string, std::string>& all() const { return values_; }

 private:
  std::map<std::string, std::string> values_;
  bool flags_ = true;
};

/// Keys that describe the physical servo and its initial state (shared by every tool and the ROS node).
const std::vector<std::string>& modelKeys();
/// Keys the ROS node reads that the command-line tools accept in a YAML file and ignore.
const std::vector<std::string>& nodeOnlyKeys();

/**
 * Builds a RunConfig from key values (model keys only; the caller has checked for unknown keys).
 * Throws UsageError for mixed forms or bad numbers, InvalidParameterError for out-of-range values.
 */
RunConfig runConfigFrom(const KeyValues& kv);

}  // namespace backlash_servo
