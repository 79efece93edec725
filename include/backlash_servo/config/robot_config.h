/**
 * @file robot_config.h
 * @brief An arm's joints from key values and its URDF: the file's top-level keys are every joint's defaults (a
 *        single joint's keys, as in any config/ YAML), `joints:` gives each joint by its URDF name with its own keys
 *        over them, and the URDF supplies what it knows. No ROS dependency.
 *
 * From the URDF (ArmModel): gear_ratio = 1 / <mechanicalReduction> of the joint's SimpleTransmission and the motor's
 * name = its actuator's; a key given both ways is refused naming both places. A joint whose keys do not give
 * load_torque takes gravity's torque from the arm at the pose, one whose keys do not give load_inertia the arm's
 * M(q)_ii (both recomputed as the joints move: robot_simulator.h); a key given keeps its constant. Without a URDF
 * the joints are independent single joints under one clock.
 */
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/robot/robot_simulator.h"

namespace backlash_servo
{
/// A robot file as read: the top-level keys, each joint's own keys (in the file's order), the URDF's path.
struct RobotFile
{
  KeyValues top;                                          ///< every joint's defaults
  std::vector<std::pair<std::string, KeyValues>> joints;  ///< URDF joint name → its own keys
  std::string urdf;  ///< `urdf:` path to the robot description (relative paths from the file's folder); "" = none
};

/// Whether a YAML file describes an arm: a mapping with a `joints:` key.
bool isRobotFile(const std::string& path);

/// Reads a robot YAML file. Throws ConfigError naming the file and the key: an unknown key (with its nearest),
/// `joints:` that is not a mapping of names to mappings, a joint named twice, a joint's key that is not a single value.
RobotFile loadRobotFile(const std::string& path);

/**
 * The joints: each joint's keys over the top level's, the URDF's gear ratio and motor name, the arm's load where
 * the keys leave it. `arm` may be null (no URDF). The load inertia of an arm-loaded joint is validated at the
 * initial pose (every joint's initial load_position, the others 0). Throws ConfigError naming the joint and the key
 * (a joint the URDF does not have, with its nearest; a key given both in the YAML and by the URDF) or the
 * joint's invalid parameter ("joints/NAME: …"). The joints come in the URDF's order (depth-first from its root), or
 * in the given order without one.
 */
std::vector<RobotJoint> robotJointsFrom(const KeyValues& top,
                                        const std::vector<std::pair<std::string, KeyValues>>& joints,
                                        const ArmModel* arm, ControlMode mode = ControlMode::Position);

/// The largest URDF file read [bytes].
constexpr std::size_t MAX_URDF_BYTES = 64u << 20;

/// The arm of URDF text, its errors as ConfigError naming `source` ("urdf 'PATH'", "robot_description"); null for
/// an empty text (independent joints).
std::unique_ptr<ArmModel> armModelFrom(const std::string& urdf_text, const std::string& source);

/// A robot file read whole: its arm (null without `urdf:`), its joints, its top-level keys (the run's keys among them).
struct RobotModel
{
  std::unique_ptr<ArmModel> arm;
  std::vector<RobotJoint> joints;
  KeyValues top;
};

/// loadRobotFile(), the URDF read (a regular file of at most 64 MiB) and robotJointsFrom(). Throws ConfigError naming
/// the file and the key, "urdf 'PATH': …" for a URDF it cannot read.
RobotModel loadRobot(const std::string& path);

}  // namespace backlash_servo
