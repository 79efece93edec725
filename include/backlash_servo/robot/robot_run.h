/**
 * @file robot_run.h
 * @brief An arm's run judged joint by joint: every joint's own ResponseMonitor (the single joint's judge: maxima,
 *        rest and quiet rules against its equilibrium) reads its events and its state at every check, for a fixed
 *        duration or until every joint's verdict is settled. Units SI (s, rad, N·m, kg·m²). No ROS dependency.
 */
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "backlash_servo/robot/robot_simulator.h"
#include "backlash_servo/simulation/response_monitor.h"

namespace backlash_servo
{
/// One joint at the end of an arm's run.
struct RobotJointResult
{
  std::string name;         ///< URDF joint name
  LimitCycleReport status;  ///< its verdict, limit-cycle error [rad] and period [s]
  CycleShape cycle;         ///< peak to peak [rad] of a sustained oscillation (NaN otherwise)
  std::uint64_t impacts = 0;
  State state;                ///< its state at the end
  double load_torque = 0.0;   ///< gravity's (or the constant) torque on its load at the end [N·m]
  double load_inertia = 0.0;  ///< the inertia its load moved at the end [kg·m²]
};

struct RobotRunResult
{
  double simulated = 0.0;  ///< simulated time [s]
  std::string stopped_by;  ///< "duration", "settled" (every verdict settled) or "max_duration"
  std::vector<RobotJointResult> joints;
};

/// How often an arm's judges check and its continuous laws' loads are updated [s]: a sample of the fastest
/// controller among the joints, at least 1 kHz.
double robotCheckPeriod(const std::vector<RobotJoint>& joints);

/**
 * Runs the arm from its current time: `duration` [s] > 0 exactly, or 0 = until every joint's verdict is settled,
 * at most `max_duration` [s]. The monitors check every `check_period` [s] (a sample of the fastest controller);
 * `on_check` (optional) sees the arm at each check, `progress` (optional) the fraction done.
 */
RobotRunResult runRobot(RobotSimulator* robot, double duration, double max_duration, double check_period,
                        const std::function<void(const RobotSimulator&)>& on_check = {},
                        const std::function<void(double)>& progress = {});

}  // namespace backlash_servo
