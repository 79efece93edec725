/**
 * @file run_config_loader.h
 * @brief Key values (flags, YAML, ROS params) → a validated RunConfig, by the parameter table (param_table.h).
 *        Shared by every command-line tool and the ROS node, so a YAML file means the same to all of them.
 *        No ROS dependency.
 *
 * Physical form (motor_inertia … gain) or chart form (zeta, inertia_ratio, friction_ratio, …), never both;
 * gear_ratio, backlash and restitution belong to both. Keys of the Node section are ignored here.
 */
#pragma once

#include <set>
#include <string>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
/**
 * Builds a RunConfig from key values. Throws ConfigError for mixed forms, missing chart keys, bad numbers or
 * choices, InvalidParameterError (naming key, value and range) for out-of-range values or a state that does not
 * fit the mesh. `mode` is how the joint is driven: in effort mode the encoders are the plant's (read by an external
 * controller), so they need no controller_rate (DriveParams::validate).
 */
RunConfig runConfigFrom(const KeyValues& kv, ControlMode mode = ControlMode::Position);

/**
 * Values that are valid but probably not what the user meant, one sentence each naming the key, the value and the
 * unit: a gearbox's backlash (ρ ≤ 0.2, a reduction of 5:1 or more) above 2° at the load — degrees typed as radians
 * (0.15 for 0.15° is 8.6°). Empty when nothing looks wrong. The tools print them as warnings and still run.
 */
std::vector<std::string> inputWarnings(const RunConfig& config);

/// What a user knows of a joint to identify (backlash_identify's prior YAML, Python's identify(prior=…)).
struct IdentificationPrior
{
  ServoParams params;            ///< the stated keys in place; the others at placeholders, never reported as known
  std::set<std::string> stated;  ///< the plant keys the prior gives
  double motor_encoder_resolution = 0.0;  ///< N_m [counts/rev] of the recording's motor angle; 0: not stated
  double load_encoder_resolution = 0.0;   ///< N_L [counts/rev] of the recording's load angle; 0: not stated
};

/**
 * The prior from key values: the gear ratio is required; every other key is optional and checked against its own
 * range only — nothing is filled from the table's defaults as if known, no drive is needed for the encoders'
 * resolutions, and the validated envelope is not checked (the identified model is). Throws ConfigError for the chart
 * form or a missing gear ratio, InvalidParameterError naming a key outside its range or keys that contradict each
 * other (a static level below its Coulomb level, mesh damping without a mesh).
 */
IdentificationPrior identificationPriorFrom(const KeyValues& kv);

/// The Servo keys present in kv into *p, absent ones left as they are (a live change); not validated here
/// (ServoParams::validate).
void updateServoKeys(const KeyValues& kv, ServoParams* p);

/**
 * The drive keys of kv into *drive, range-checked: absent keys at their table defaults, or, with keep_absent, as
 * they are in *drive (a live change of some keys). The combination is not checked here (DriveParams::validate).
 */
void readDriveKeys(const KeyValues& kv, bool keep_absent, DriveParams* drive);

/// Every drive key of *drive as key values (numbers, and the choices as their names): what readDriveKeys reads.
KeyValues driveKeyValues(const DriveParams& drive);

/// Throws ConfigError "<source>: unknown key 'x'" for a key that is not in the parameter table.
void requireKnownKeys(const KeyValues& kv, const std::string& source);

}  // namespace backlash_servo
