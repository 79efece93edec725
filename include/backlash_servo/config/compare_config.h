/**
 * @file compare_config.h
 * @brief The compensation workbench's experiment file (backlash_compare --config FILE.yaml): one joint, one command
 *        profile, N strategies. See docs/workbench.md.
 *
 * ```yaml
 * motor_inertia: 1.0e-4      # any parameter-table key: the joint and the settings every strategy shares
 * duration: 20               # [s] simulated per strategy (required)
 * sample_rate: 1000          # [Hz] metrics sampling (default 1000)
 * profile:                   # optional; default: a step to `command` at t = 0
 *   - step: {time: 0, target: 0.5}
 *   - ramp: {time: 5, target: 0, duration: 2}        # or rate: [rad/s]
 *   - sine: {time: 8, amplitude: 0.05, frequency: 1, duration: 4}
 *   - move: {time: 12, distance: 0.3, max_velocity: 0.5, max_acceleration: 5}
 *   - points: {time: 15, csv: setpoints.csv}         # time,value rows (relative to the YAML's directory)
 * strategies:
 *   - name: PID on load      # any keys again: they override the shared ones for this strategy
 *     control_law: pid
 *     integral_gain: 30
 * ```
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
