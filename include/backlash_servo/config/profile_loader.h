/**
 * @file profile_loader.h
 * @brief Command profiles from files: the `profile` key of every tool's YAML (and `--profile FILE`), the compare
 *        file's `profile:` list and CSV set-points. No ROS dependency. See docs/cli.md, "Command profiles".
 *
 * A profile file is either
 * - YAML: a list of segments, or a mapping whose `profile:` key holds that list (so a run's whole YAML can name
 *   itself), each item one of
 *   `- step: {time, target}`, `- ramp: {time, target, duration | rate}`, `- sine: {time, amplitude, frequency,
 *   duration}`, `- move: {time, distance, max_velocity, max_acceleration}`, `- points: {time, csv}`;
 * - CSV (`.csv`): `time,value` rows [s, rad] (one header line allowed), held from their time on.
 * Times [s] are from the start of the run, angles [rad] at the load, rates [rad/s], accelerations [rad/s²].
 * Unknown segment kinds or fields, missing fields, non-numbers, negative durations, unordered times and unreadable
 * files are refused with one line naming the segment and the field.
 */
#pragma once

#include <memory>
#include <string>

#include "backlash_servo/drive/command_profile.h"

namespace YAML
{
class Node;
}

namespace backlash_servo
{
/// A profile from a list of segments (YAML); relative CSV paths are taken from `dir`. `start`: θ_R before the first
/// segment [rad].
std::shared_ptr<const CommandProfile> profileFromYaml(const YAML::Node& list, const std::string& dir, double start);

/// A profile from a YAML or CSV file (see above). Throws ConfigError naming the file and the problem.
std::shared_ptr<const CommandProfile> loadProfileFile(const std::string& path, double start);

/// The directory part of a path ("." for a bare file name).
std::string directoryOf(const std::string& path);

}  // namespace backlash_servo
