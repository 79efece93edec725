// Live parameters: dynamic_reconfigure in and out, and a monitor restarted when they change what it judges.
#include "servo_node.h"

#include <dynamic_reconfigure/config_tools.h>
#include <algorithm>
#include <cmath>
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"
#include "reconfigure_values.h"

namespace backlash_servo
{
BacklashServoConfig ServoNode::currentConfig() const
{
  return reconfigureConfig(sim_.params(), config_.run.drive, config_);
}

void ServoNode::restartMonitor(const std::string& reason)
{
  judge_.restart(sim_, config_.run, command_, profile_, 1.0 / config_.publish_rate, reason);
  if (!reason.empty())
  {
    publishLimitCycle(sim_.state().time, false);  // no stale verdict: undecided, with the reason, until the new one
  }
}

void ServoNode::refreshReconfigureMirror()
{
  if (mirror_stale_)
  {
    mirror_stale_ = false;
    last_good_ = currentConfig();
    reconfigure_->updateConfig(last_good_);
  }
}

void ServoNode::onReconfigure(BacklashServoConfig& c, uint32_t)
{
  if (mirror_stale_ && c.load_torque == last_good_.load_torque)
  {
    // Not touched by this reconfigure: the value the load_torque topic set since the mirror's last refresh stays.
    c.load_torque = sim_.params().load_torque;
  }
  mirror_stale_ = false;
  const KeyValues kv = reconfigureValues(c);
  NodeConfig next;
  ServoParams p = sim_.params();
  try
  {
    updateServoKeys(kv, &p);
    p.validate();
    next = nodeSettingsFrom(kv, config_);
    readDriveKeys(kv, true, &next.run.drive);
    next.run.drive.validate(next.control_mode);
    sim_.setParams(p);  // at this step boundary, no jump in θ_c or ω_c (docs/ros_node.md: a shrinking backlash)
  }
  catch (const std::exception& e)
  {
    // The reply holds the values in force (what rqt shows); /diagnostics says what was refused until the next
    // accepted change.
    refused_ = std::string("reconfigure refused: ") + e.what();
    ROS_ERROR("backlash_servo_node: %s; keeping the previous values", refused_.c_str());
    c = last_good_;
    publishDiagnostics();
    return;
  }
  refused_.clear();
  // A live change of anything the joint's motion depends on (plant or drive, not the node's own settings) restarts
  // the judgement: the maxima before it belong to another joint. (Values compared as the exact text of each key.)
  const KeyValues before = reconfigureValues(last_good_);
  std::string changed;
  bool drive_changed = false;
  for (const auto& [key, text] : kv.keys())
  {
    const ParamSection section = findParam(key)->section;
    if (section != ParamSection::Node && before.text(key, "") != text)
    {
      changed += (changed.empty() ? "" : ", ") + key;
      drive_changed = drive_changed || section == ParamSection::Drive;
    }
  }
  if (next.control_mode != config_.control_mode)
  {
    if (next.control_mode == ControlMode::Effort)
    {
      effort_ = 0.0;  // no stale torque: 0 N·m until the first motor_effort in this mode
      last_effort_time_ = sim_.state().time;
      effort_timed_out_ = false;
      profile_.reset();  // back in position mode the law holds the profile's final value
      sim_.setMotorTorque(effort_);
    }
    else
    {
      config_.run.drive = next.run.drive;
      applyPositionDrive();
    }
    restartMonitor("control_mode changed");
  }
  else
  {
    if (drive_changed && next.control_mode == ControlMode::Position &&
        !sim_.retuneDrive(next.run.drive))  // gains, limit, rate, delay, encoders, compensator settings: no bump
    {
      config_.run.drive = next.run.drive;
      applyPositionDrive();  // a new law, feedback, compensator or continuous ↔ digital: a fresh controller
    }
    if (!changed.empty())
    {
      restartMonitor("live change of " + changed);
    }
  }
  if (next.publish_rate != config_.publish_rate)
  {
    sample_base_ = sim_.state().time;
    sample_index_ = 1;
  }
  config_ = next;
  clock_.reanchor(sim_.state().time);
  last_good_ = c;
  if (!fault_.empty() && !fault_diverged_)
  {
    ROS_INFO("backlash_servo_node: valid parameters clear the simulation error; running again");
    fault_.clear();
    publishDiagnostics();
  }
}
}  // namespace backlash_servo
