/**
 * @file node_config.h
 * @brief Everything backlash_servo_node reads from its private parameters: ROS params (loaded from the YAML files in
 *        config/) → key values → RunConfig by the shared loader (run_config_loader.h), so a YAML file means the
 *        same to the node and to backlash_sim. Every key, unit, range and default is in the parameter table
 *        (param_table.h); this file only binds the Node-section keys to NodeConfig. Errors name the key.
 */
#pragma once

#include <ros/node_handle.h>

#include <string>
#include <utility>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
/// The node's settings; units, ranges and defaults are those of the parameter table (loadNodeConfig fills them).
struct NodeConfig
{
  RunConfig run;                                     ///< physical parameters, initial state, initial command θ_R [rad]
  ControlMode control_mode = ControlMode::Position;  ///< position (internal P loop) or effort (motor_effort topic)
  double motor_effort = 0.0;                         ///< initial motor torque in effort mode [N·m]
  double publish_rate = 0.0;                         ///< joint_states / backlash_state rate [Hz of sim time]
  double real_time_factor = 0.0;                     ///< sim seconds per wall second; 0 = as fast as possible
  bool publish_clock = false;                        ///< the node publishes /clock (use with use_sim_time)
  double clock_publish_rate = 1000.0;                ///< most /clock messages per wall second [Hz]; 0 = every sample
  std::string motor_joint_name;                      ///< JointState name of the motor shaft
  std::string load_joint_name;                       ///< JointState name of the load shaft
  std::string gear_joint_name;                       ///< JointState name of the output gear (compliant mesh)
  std::string shaft_twist_joint_name;                ///< JointState name of the shaft twist (compliant mesh)
  double min_impact_speed = 0.0;                     ///< publish only impacts at least this fast [rad/s]; 0 = all
  bool paused = false;                               ///< start paused (resume with ~resume)
  double stop_after = 0.0;                           ///< shut down after this much sim time [s]; 0 = never
  bool stop_launch = false;                          ///< at stop_after, SIGINT to the parent roslaunch
  double start_time = 0.0;                           ///< ROS time of sim time 0 when publishing /clock [s]
  double start_delay = 0.0;                          ///< wall time before sim time starts, e.g. for rosbag [s]
  std::string record_bag;       ///< the node records its outputs and inputs into this bag itself; empty = off
  bool sync = false;            ///< lockstep: one answer (effort or command) per published state before advancing
  double sync_timeout = 5.0;    ///< lockstep: wall time to wait for an answer [s]; 0 = for ever
  double effort_timeout = 0.0;  ///< effort mode: sim time without motor_effort before the torque drops to 0 [s]
};

/// Reads and validates the private parameters; throws std::runtime_error naming the key on any problem.
NodeConfig loadNodeConfig(const ros::NodeHandle& private_nh);

/// The private parameters as given: the table's keys, and an arm's `joints` (name → its keys) and `urdf` (a path).
struct PrivateParams
{
  KeyValues given;                                        ///< the table's keys given (no defaults filled)
  std::vector<std::pair<std::string, KeyValues>> joints;  ///< ~joints/NAME/KEY, in the server's order
  std::string urdf;                                       ///< ~urdf: the robot description's file; "" = none
  bool arm = false;                                       ///< ~joints is given: the node runs an arm
};
/// Reads ~: unknown keys (in the top level or a joint) refused naming them and their nearest key.
PrivateParams readPrivateParams(const ros::NodeHandle& private_nh);
/// The Node section's table defaults under the keys given.
KeyValues withNodeDefaults(const KeyValues& given);

/**
 * Node settings from key values (Node-section keys; absent keys keep the values of `base`), validated by the table
 * and by validateNodeSettings(). Throws ConfigError / InvalidParameterError naming the key.
 */
NodeConfig nodeSettingsFrom(const KeyValues& kv, const NodeConfig& base);

/// Checks what the table cannot (combinations, names); throws ConfigError naming the keys.
void validateNodeSettings(const NodeConfig& config);

}  // namespace backlash_servo
