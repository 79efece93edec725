// What the node takes: commands, trajectories, effort, the load torque, and the reset/pause/resume services.
#include "servo_node.h"

#include <algorithm>

#include "backlash_servo/model/param_table.h"
#include "trajectory_profile.h"
#include "wall_throttle.h"

namespace backlash_servo
{
void ServoNode::onCommand(const std_msgs::Float64& msg)
{
  record(command_topic_, msg);
  try
  {
    param("command").check(msg.data);  // finite and inside the validated envelope
  }
  catch (const std::exception& e)
  {
    BACKLASH_LOG_WALL_THROTTLE(WARN, 1.0, "backlash_servo_node: dropped command (%s); keeping %g rad", e.what(),
                               command_);
    return;
  }
  command_ = msg.data;
  profile_.reset();  // a command ends a profile or trajectory
  if (sim_.controlMode() == ControlMode::Position)
  {
    sim_.setCommand(command_);
    lockstep_.answered();  // lockstep: the answer for the state just published
  }
  restartMonitor("new command " + formatNumber(command_) + " rad");  // both modes judge against the command
}

void ServoNode::onEffort(const std_msgs::Float64& msg)
{
  record(effort_topic_, msg);
  try
  {
    param("motor_effort").check(msg.data);
  }
  catch (const std::exception& e)
  {
    BACKLASH_LOG_WALL_THROTTLE(WARN, 1.0, "backlash_servo_node: dropped motor_effort (%s); keeping %g N·m", e.what(),
                               effort_);
    return;
  }
  if (sim_.controlMode() != ControlMode::Effort)
  {
    // Not kept either: a torque sent in position mode must not surface later when the mode switches.
    BACKLASH_LOG_WALL_THROTTLE(WARN, 5.0,
                               "backlash_servo_node: motor_effort ignored in position mode (set control_mode: effort)");
    return;
  }
  effort_ = msg.data;
  last_effort_time_ = sim_.state().time;
  effort_timed_out_ = false;
  sim_.setMotorTorque(effort_);
  lockstep_.answered();  // lockstep: the answer for the state just published
}

void ServoNode::applyPositionDrive()
{
  const DriveParams& drive = config_.run.drive;
  const double now = sim_.state().time;
  const double start = profile_ ? profile_->at(now) : command_;  // a profile in progress goes on
  // The configured law (continuous P, saturated or compensated, or a digital drive), fresh from now on: integrators
  // and the sample clock restart.
  sim_.setDrive(makePositionDrive(drive, sim_.params().gain, sim_.params().gear_ratio, start, now));
  if (profile_)
  {
    sim_.setProfile(profile_);
  }
}

void ServoNode::onTrajectory(const trajectory_msgs::JointTrajectory& msg)
{
  record(trajectory_topic_, msg);
  const double now = sim_.state().time;
  try
  {
    if (sim_.controlMode() != ControlMode::Position)
    {
      throw ConfigError("the node is in effort mode (control_mode: effort); a trajectory is a position command");
    }
    const double start = trajectoryStart(msg, clock_.origin(), now);
    const double from = profile_ ? profile_->at(std::max(start, now)) : command_;
    auto profile = trajectoryProfile(msg, config_.load_joint_name, start, from);
    sim_.setProfile(profile);  // throws before changing anything if the law cannot take it (ramps with dry friction)
    profile_ = profile;
    command_ = profile_->finalValue();
    ROS_INFO("backlash_servo_node: command_trajectory: %zu points from t = %.6g s to %.6g s, final %g rad",
             msg.points.size(), start, profile_->endTime(), command_);
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: command_trajectory refused (%s); keeping the current set-point", e.what());
    return;
  }
  lockstep_.answered();  // lockstep: a trajectory answers the state just published, as a command does
  restartMonitor("new command_trajectory");  // judged against the trajectory's final point
}

void ServoNode::onLoadTorque(const std_msgs::Float64& msg)
{
  record(load_torque_topic_, msg);
  ServoParams p = sim_.params();
  const double before = p.load_torque;
  p.load_torque = msg.data;
  try
  {
    p.validate();
    sim_.setParams(p);  // at this step boundary (callbacks run between samples), no jump in θ_c or ω_c
  }
  catch (const std::exception& e)
  {
    BACKLASH_LOG_WALL_THROTTLE(WARN, 1.0, "backlash_servo_node: dropped load_torque (%s); keeping %g N·m", e.what(),
                               sim_.params().load_torque);
    return;
  }
  // The dynamic_reconfigure mirror (one parameter-server call per parameter) is brought up to date at most once per
  // wall second, not per message: a 1 kHz load-torque stream would otherwise cost the node its rate.
  mirror_stale_ = true;
  if (p.load_torque != before)
  {
    restartMonitor("load_torque " + formatNumber(p.load_torque) + " N·m");  // a new equilibrium to judge against
  }
}

bool ServoNode::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  State initial = config_.run.initial;
  initial.time = sim_.state().time;  // time never runs backwards
  try
  {
    sim_.setState(initial);
  }
  catch (const std::exception& e)
  {
    res.success = false;
    res.message = std::string("initial state does not fit the current parameters: ") + e.what();
    ROS_ERROR("backlash_servo_node: reset refused: %s", res.message.c_str());
    return true;
  }
  command_ = config_.run.command;
  // The YAML's profile starts again from now (time never runs backwards).
  profile_ =
      config_.run.profile ? std::make_shared<CommandProfile>(config_.run.profile->delayed(initial.time)) : nullptr;
  if (sim_.controlMode() == ControlMode::Position)
  {
    applyPositionDrive();  // a fresh controller: integrators and sample clock restart with the state
  }
  restartMonitor("reset");
  if (!fault_.empty())
  {
    ROS_INFO("backlash_servo_node: reset clears the simulation error; running again");
    fault_.clear();
    fault_diverged_ = false;
    clock_.reanchor(sim_.state().time);
    publishDiagnostics();
  }
  res.success = true;
  res.message = "reset to the initial state at t = " + std::to_string(initial.time) + " s";
  return true;
}

bool ServoNode::onPause(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  paused_ = true;
  res.success = true;
  res.message = "paused at t = " + std::to_string(sim_.state().time) + " s";
  return true;
}

bool ServoNode::onResume(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  paused_ = false;
  clock_.reanchor(sim_.state().time);
  res.success = true;
  res.message = "running from t = " + std::to_string(sim_.state().time) + " s";
  return true;
}
}  // namespace backlash_servo
