/**
 * @file node_config.h
 * @brief Everything backlash_servo_node reads from its private parameters (loaded from the YAML files in config/).
 *
 * The physical keys are parsed by the same code as backlash_sim's --config (sim_options.h), so a YAML file means
 * the same thing to both. Errors name the offending key.
 */
#pragma once

#include <ros/node_handle.h>

#include <string>

#include "backlash_servo/step_response.h"

namespace backlash_servo
{
struct NodeConfig
{
  RunConfig run;                                     ///< physical parameters, initial state, initial command θ_R [rad]
  ControlMode control_mode = ControlMode::Position;  ///< position (internal P loop) or effort (motor_effort topic)
  double motor_effort = 0.0;                         ///< initial motor torque in effort mode [N·m]
  double publish_rate = 100.0;                       ///< joint_states / backlash_state rate [Hz of sim time], > 0
  double real_time_factor = 1.0;  ///< sim seconds per wall second; 0 = as fast as possible (clock mode only)
  bool publish_clock = false;     ///< the node publishes /clock (use with use_sim_time)
  std::string motor_joint_name = "motor_joint";
  std::string load_joint_name = "load_joint";
  double min_impact_speed = 0.0;  ///< publish only impacts with approach speed >= this [rad/s]; 0 = all
  bool paused = false;            ///< start paused (resume with ~resume)
  double stop_after = 0.0;        ///< shut down after this much sim time [s]; 0 = run until stopped
  double start_delay = 0.0;       ///< wall time to wait before sim time starts, e.g. for rosbag [s]
};

/// Reads and validates the private parameters; throws std::runtime_error naming the key on any problem.
NodeConfig loadNodeConfig(const ros::NodeHandle& private_nh);

/// Checks the node-only values (rates, names); throws std::runtime_error naming the key.
void validateNodeSettings(const NodeConfig& config);

}  // namespace backlash_servo
