// What the node publishes: joint and encoder states, backlash_state, impacts, limit_cycle, diagnostics.
#include "servo_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <sensor_msgs/JointState.h>
#include <cmath>
#include <cstdint>
#include "backlash_servo/BacklashState.h"
#include "backlash_servo/ImpactEvent.h"
#include "backlash_servo/LimitCycleStatus.h"
#include "status_messages.h"

namespace backlash_servo
{
namespace
{
uint8_t contactCode(Contact c)
{
  switch (c)
  {
    case Contact::Forward:
      return BacklashState::FORWARD;
    case Contact::Backward:
      return BacklashState::BACKWARD;
    default:
      return BacklashState::APART;
  }
}
}  // namespace

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
  const LimitCycleReport& verdict = monitor_->status();
  status.add("verdict", toString(verdict.verdict));
  status.add("equilibrium [rad]", formatNumber(monitor_->equilibrium()));
  if (verdict.verdict == Verdict::LimitCycle || verdict.verdict == Verdict::Irregular)
  {
    status.add("limit_cycle_error [rad]", formatNumber(verdict.error));
    status.add("period [s]", formatNumber(verdict.period));
    status.add("maxima_per_period", std::to_string(verdict.multiplicity));
    const CycleShape cycle = monitor_->cycleShape();
    status.add("peak_to_peak [rad]", formatNumber(cycle.peak_to_peak));
    status.add("cycle_centre [rad]", formatNumber(cycle.centre));
    const CycleResolution resolution = resolutionNow(cycle);
    status.add("peak_to_peak_counts", formatNumber(resolution.counts));
    status.add("peak_to_peak_arcmin", formatNumber(resolution.arcmin));
    status.add("below_encoder_resolution", resolution.below_count ? "true" : "false");
  }
  if (verdict.verdict == Verdict::Converged)
  {
    const SteadyAnswer& steady = steadyNow();
    status.add("steady_error [rad]", std::isnan(steady.error) ? "n/a: " + steady.note : formatNumber(steady.error));
    status.add("steady_basis", steadyBasisName(steady.basis));
  }
  const TrackingFigures tracking = trackingNow();
  status.add("settling_band [rad]", formatNumber(tracking.band));
  status.add("settling_time [s]",
             std::isnan(tracking.settling_time) ? "- (outside the band)" : formatNumber(tracking.settling_time));
  status.add("steady_rms_error [rad]", formatNumber(tracking.steady_rms_error));
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
    status.add("lockstep answers late", std::to_string(sync_misses_));
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

  BacklashState b;
  b.header.stamp = now;
  b.sim_time = s.time;
  b.contact = contactCode(s.contact);
  b.gap = sim_.gap();
  b.mesh_torque = sim_.meshTorque();
  b.motor_torque = sim_.motorTorque();
  b.command = profile_ && sim_.controlMode() == ControlMode::Position ? profile_->at(s.time) : command_;
  b.control_mode = sim_.controlMode() == ControlMode::Effort ? BacklashState::EFFORT : BacklashState::POSITION;
  const EnergyLedger& e = sim_.energy();
  b.energy_input = e.input;
  b.energy_motor_friction = e.motor_friction;
  b.energy_load_friction = e.load_friction;
  b.energy_impact_loss = e.impact_loss;
  b.energy_motor_dry_friction = e.motor_dry_friction;
  b.energy_load_dry_friction = e.load_dry_friction;
  b.energy_load_work = e.load_work;
  if (!sim_.energyValid())
  {
    // A ramp of the continuous law ran in its moving frame: the ledger is the frame's (NaN: unknown; ~reset restores).
    b.energy_input = b.energy_motor_friction = b.energy_load_friction = b.energy_impact_loss =
        b.energy_motor_dry_friction = b.energy_load_dry_friction = b.energy_load_work = NAN;
  }
  b.energy_kinetic = sim_.kineticEnergy();
  b.impacts = sim_.impactCount();
  emit(state_pub_, state_topic_, b);
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
  else if (e.type == EventType::Maximum)  // both modes: effort mode is judged against `command` as well
  {
    const std::size_t before = monitor_->maxima().size();
    monitor_->onEvent(e);
    if (monitor_->maxima().size() == before)
    {
      return;  // not above the command
    }
    if (leftConvergence(e.state))
    {
      const std::string why = "the converged verdict of t = " + formatNumber(converged_at_) +
                              " s is withdrawn: the load moved again (maximum at t = " + formatNumber(e.state.time) +
                              " s, " + formatNumber(e.state.load_position - monitor_->equilibrium()) +
                              " rad beyond where it rested)";
      ROS_WARN("backlash_servo_node: %s", why.c_str());
      restartMonitor(why);  // published at once: undecided, with the reason
      return;
    }
    publishLimitCycle(e.state.time, true);
  }
  else if (e.type == EventType::Minimum)
  {
    monitor_->onEvent(e);  // the cycle's lowest points (peak to peak, centre)
  }
}

bool ServoNode::leftConvergence(const State& at_maximum) const
{
  // A maximum above the quiet band after a converged verdict: the load moved again (an external controller's
  // integrator, a breakaway, a push) — the verdict no longer describes the joint.
  return announced_ == Verdict::Converged && fault_.empty() && monitor_->leavesConvergence(at_maximum);
}

TrackingFigures ServoNode::trackingNow() const
{
  if (!tracking_)
  {
    return TrackingFigures();
  }
  const double dt = 1.0 / config_.publish_rate;
  return tracking_->figures(sim_.state().time, dt,
                            cycleLeavesBand(monitor_->status(), monitor_->cycleShape(), command_, tracking_->band()));
}

CycleResolution ServoNode::resolutionNow(const CycleShape& cycle) const
{
  RunConfig read = config_.run;
  read.params = sim_.params();
  return cycleResolution(cycle, loopCount(read));
}

const SteadyAnswer& ServoNode::steadyNow()
{
  if (monitor_->status().verdict != Verdict::Converged)
  {
    steady_ = SteadyAnswer();
    return steady_;
  }
  const bool effort = sim_.controlMode() == ControlMode::Effort;
  if (steady_.basis == SteadyBasis::None || (effort && steady_.basis == SteadyBasis::Unsettled))
  {
    if (!effort || sim_.atRestForever())  // (held for ever: steadyAnswer's first answer, whoever drives)
    {
      steady_ = steadyAnswer(sim_, config_.run.drive, command_, monitor_->equilibrium(), monitor_->scale());
    }
    else
    {
      steady_.basis = SteadyBasis::Unsettled;
      steady_.note = "effort mode: the external controller's law is unknown";
    }
  }
  return steady_;
}

void ServoNode::publishLimitCycle(double sim_time, bool maximum, bool diverged)
{
  const auto& st = monitor_->status();
  LimitCycleStatus m;
  m.header.stamp = stamp(sim_time);
  m.sim_time = sim_time;
  fillVerdict(*monitor_, resolutionNow(monitor_->cycleShape()), &m);
  if (diverged)
  {
    m.verdict = toString(Verdict::Diverged);
  }
  m.joint = config_.load_joint_name;
  const SteadyAnswer& steady = steadyNow();
  m.steady_error = steady.error;
  m.steady_basis = steady.basis == SteadyBasis::None ? "" : steadyBasisName(steady.basis);
  const TrackingFigures tracking = trackingNow();
  m.settling_band = tracking.band;
  m.settling_time = tracking.settling_time;
  m.steady_rms_error = tracking.steady_rms_error;
  m.command = command_;
  if (st.verdict != Verdict::Undecided && fault_.empty())
  {
    verdict_reason_.clear();  // a verdict reached: nothing pending to explain
  }
  // A convergence is never withdrawn silently (the load moved again: an external controller's integrator, a joint
  // breaking away): the message says which verdict it replaces and since when.
  if (announced_ == Verdict::Converged && st.verdict != Verdict::Converged && fault_.empty())
  {
    verdict_reason_ = "the converged verdict of t = " + formatNumber(converged_at_) +
                      " s is withdrawn: the load moved again (maximum at t = " +
                      formatNumber(monitor_->maxima().empty() ? sim_time : monitor_->maxima().back().time) + " s)";
    ROS_WARN("backlash_servo_node: %s", verdict_reason_.c_str());
  }
  m.reason = verdict_reason_;
  emit(limit_cycle_pub_, limit_cycle_topic_, m);
  if (maximum)
  {
    ROS_INFO("maximum #%u at t = %.4f s: load %.6f rad (error %+.6f rad); verdict: %s", m.maxima_observed,
             m.last_maximum_time, m.last_maximum_position, m.last_maximum_position - command_, m.verdict.c_str());
  }
  if (st.verdict != announced_)
  {
    announced_ = st.verdict;
    if (m.detected)
    {
      ROS_INFO("%s detected: error %.6f rad, period %.4f s; load %.6f rad peak to peak about %.6f rad",
               st.verdict == Verdict::LimitCycle ? "LIMIT CYCLE" : "IRREGULAR OSCILLATION", st.error, st.period,
               m.peak_to_peak, m.cycle_centre);
    }
    else if (st.verdict == Verdict::Converged)
    {
      converged_at_ = sim_time;
      ROS_INFO("converged to the command at t = %.4f s: no limit cycle", sim_time);
    }
  }
}
}  // namespace backlash_servo
