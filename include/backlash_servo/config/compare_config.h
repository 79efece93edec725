/**
 * @file compare_config.h
 * @brief The compensation workbench's experiment file (backlash_compare --config FILE.yaml): one joint and its shared
 *        settings (any parameter-table key), `duration` [s] (required), `sample_rate` [Hz], an optional command
 *        `profile` (CSV paths relative to the YAML's directory), and N `strategies`, each overriding shared keys.
 *        The format with an example: docs/workbench.md. No ROS dependency.
 */
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
struct CompareStrategy
{
  std::string name;
  RunConfig config;  ///< the whole run: joint, drive, profile, duration
  KeyValues keys;    ///< the keys it was built from (the shared ones and its own)
};

struct CompareConfig
{
  std::vector<CompareStrategy> strategies;
  double duration = 0.0;                          ///< [s] per strategy
  double sample_rate = 1000;                      ///< [Hz] of the metrics sampling
  std::shared_ptr<const CommandProfile> profile;  ///< always set (a step when the file has none)
};

/// Reads and validates the file; throws ConfigError / InvalidParameterError naming the strategy and key.
CompareConfig loadCompareConfig(const std::string& path);

/// The value [SI] of a numeric parameter-table key in a strategy's run: the file's, else its default.
double valueOf(const CompareStrategy& strategy, const std::string& key);

/// The strategy re-built with key = value [SI], everything else as in the file (backlash_compare --vary); throws
/// ConfigError / InvalidParameterError naming the strategy, the key and the value.
CompareStrategy withValue(const CompareStrategy& strategy, const std::string& key, double value,
                          const CompareConfig& config);

}  // namespace backlash_servo
