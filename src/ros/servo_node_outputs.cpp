// What the node publishes: joint and encoder states, backlash_state, impacts, limit_cycle, diagnostics.
#include "servo_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <sensor_msgs/JointState.h>
#include <cmath>
#include <cstdint>
#include "backlash_servo/ImpactEvent.h"
#include "backlash_servo/LimitCycleStatus.h"
#include "status_messages.h"

namespace backlash_servo
{
void ServoNode::publishDiagnostics()
{
  last_diagnostics_ = ros::WallTime::now();
  diagnostics_.force_update();  // on the node's own 1 s wall schedule: sim time may run 0× … 1000× real time
}

void ServoNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& status)
{
  status.summary(fault_.empty() ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::ERROR,
                 fault_.empty() ? (paused_ ? "paused" : "running") : fault_);
  if (!refused_.empty() && fault_.empty())
  {
    status.mergeSummary(diagnostic_msgs::DiagnosticStatus::WARN, refused_);
  }
  status.add("sim_time [s]", formatNumber(sim_.state().time));
  status.add("impacts", std::to_string(sim_.impactCount()));
  // The figures backlash_sim reports, under the same names and units.
  judge_.diagnose(sim_, config_.run, &status);
  // Rates over the last diagnostics interval: impacts per simulated second, simulated seconds per wall second.
  const ros::WallTime now = ros::WallTime::now();
  const double wall = (now - diag_wall_).toSec();
  const double sim = sim_.state().time - diag_sim_;
  if (wall > 0.0 && diag_sim_ >= 0.0)
  {
    status.add("impact rate [1/s]", formatNumber(sim > 0.0 ? (sim_.impactCount() - diag_impacts_) / sim : 0.0));
    status.add("real-time factor achieved", formatNumber(sim / wall));
  }
  diag_wall_ = now;
  diag_sim_ = sim_.state().time;
  diag_impacts_ = sim_.impactCount();
  if (config_.sync)
  {
    status.add("lockstep answers late", std::to_string(lockstep_.late()));
  }
}

void ServoNode::publishEncoders(const State& s, const Drive& drive)
{
  double motor = 0.0, load = 0.0;
  if (drive.readings(&motor, &load))
  {
    publishEncoderReadings(s, motor, load);
  }
}

void ServoNode::publishEncoderReadings(const State& s, double motor, double load)
{
  sensor_msgs::JointState& js = encoder_msg_;
  setJointNames(&js, false);
  js.header.stamp = stamp(s.time);
  js.position.resize(2);
  js.position[0] = motor;  // quantised readings q(θ_m) [rad, motor shaft] and q(θ_c) [rad]
  js.position[1] = load;
  emit(encoder_pub_, encoder_topic_, js);
}

void ServoNode::setJointNames(sensor_msgs::JointState* js, bool compliant) const
{
  const std::size_t n = compliant ? 4 : 2;
  if (js->name.size() != n || js->name[0] != config_.motor_joint_name || js->name[1] != config_.load_joint_name ||
      (compliant && (js->name[2] != config_.gear_joint_name || js->name[3] != config_.shaft_twist_joint_name)))
  {
    js->name = {config_.motor_joint_name, config_.load_joint_name};
    if (compliant)
    {
      js->name.push_back(config_.gear_joint_name);
      js->name.push_back(config_.shaft_twist_joint_name);
    }
  }
}

void ServoNode::publishSample()
{
  const State& s = sim_.state();
  if (sim_.controlMode() == ControlMode::Effort)
  {
    // The encoders are the plant's: an external controller reads them at its own period, the publish period.
    const DriveParams& d = config_.run.drive;
    publishEncoderReadings(s, encoderReading(s.motor_position, d.motor_encoder_resolution),
                           encoderReading(s.load_position, d.load_encoder_resolution));
  }
  const ros::Time now = stamp(s.time);
  sensor_msgs::JointState& js = joint_msg_;
  const ServoParams& p = sim_.params();
  const bool compliant = p.compliant();
  setJointNames(&js, compliant);
  js.header.stamp = now;
  js.position.assign({s.motor_position, s.load_position});
  js.velocity.assign({s.motor_velocity, s.load_velocity});
  js.effort.assign({sim_.motorTorque(), sim_.meshTorque()});
  if (compliant)
  {
    // The output gear θ_o = θ_c + twist (effort: the mesh torque Q on it) and the shaft twist θ_o − θ_c (effort: the
    // shaft's spring–damper torque S; a rigid shaft has no twist and carries 0 here).
    js.position.insert(js.position.end(), {s.load_position + s.shaft_twist, s.shaft_twist});
    js.velocity.insert(js.velocity.end(), {s.load_velocity + s.shaft_twist_rate, s.shaft_twist_rate});
    js.effort.insert(js.effort.end(),
                     {sim_.meshTorque(), p.shaft_stiffness * s.shaft_twist + p.shaft_damping * s.shaft_twist_rate});
  }
  emit(joint_pub_, joint_topic_, js);
  published_ += 2;  // joint_states, backlash_state (/clock counts where it is published)

  const double command = profile_ && sim_.controlMode() == ControlMode::Position ? profile_->at(s.time) : command_;
  emit(state_pub_, state_topic_, backlashStateMessage(sim_, command, now));
}

void ServoNode::onEvent(const Event& e)
{
  if (e.type == EventType::Impact)
  {
    if (e.impact.approach_speed < config_.min_impact_speed)
    {
      return;  // filtered from publishing only; it was simulated
    }
    const ImpactEvent m = impactMessage(e, stamp(e.state.time), config_.load_joint_name);
    emit(impact_pub_, impact_topic_, m);
  }
  else
  {
    // Maxima and minima to the judge (both modes: effort mode is judged against `command` as well).
    std::string withdrawn;
    if (judge_.onEvent(e, &withdrawn))
    {
      publishLimitCycle(e.state.time, true);
    }
    else if (!withdrawn.empty())
    {
      ROS_WARN("backlash_servo_node: %s", withdrawn.c_str());
      restartMonitor(withdrawn);  // published at once: undecided, with the reason
    }
  }
}

void ServoNode::publishLimitCycle(double sim_time, bool maximum, bool diverged)
{
  LimitCycleStatus m = judge_.status(sim_, config_.run, sim_time, fault_.empty(), maximum, diverged);
  m.header.stamp = stamp(sim_time);
  emit(limit_cycle_pub_, limit_cycle_topic_, m);
}
}  // namespace backlash_servo
