#include "servo_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <dynamic_reconfigure/config_tools.h>
#include <ros/callback_queue.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <ctime>

#include "backlash_servo/BacklashState.h"
#include "backlash_servo/ImpactEvent.h"
#include "backlash_servo/LimitCycleStatus.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"
#include "launch_end.h"
#include "wall_throttle.h"

namespace backlash_servo
{
namespace
{
/// Outgoing queue of every per-sample topic: as fast as possible (real_time_factor 0) the node publishes thousands of
/// samples per wall second, and roscpp drops the oldest queued messages of a subscriber that falls behind (a bag
/// recorder); 1e5 messages (~20 MB at most) lets recorders catch up without losing a sample.
constexpr uint32_t SAMPLE_QUEUE = 100000;

/// The generated config → key values, by the names of the parameter table.
KeyValues keyValuesOf(const BacklashServoConfig& c)
{
  KeyValues kv;
  kv.nameKeysAsFlags(false);
  for (const auto& d : BacklashServoConfig::__getParamDescriptions__())
  {
    boost::any value;
    d->getValue(c, value);
    const ParamSpec* spec = findParam(d->name);
    if (spec == nullptr)
    {
      continue;  // a .cfg entry the table does not know: the consistency test fails for it
    }
    if (d->type == "double")
    {
      kv.setNumber(d->name, boost::any_cast<double>(value));
    }
    else if (d->type == "int")
    {
      const int i = boost::any_cast<int>(value);
      kv.set(d->name, i >= 0 && i < static_cast<int>(spec->choices.size()) ? spec->choices[i] : std::to_string(i));
    }
    else if (d->type == "bool")
    {
      kv.setBoolean(d->name, boost::any_cast<bool>(value));
    }
    else
    {
      kv.set(d->name, boost::any_cast<std::string>(value));
    }
  }
  return kv;
}

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

ServoNode::ServoNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, const NodeConfig& config)
    : config_(config),
      clock_mode_(config.publish_clock ? ClockMode::Publisher
                                       : (ros::Time::isSimTime() ? ClockMode::External : ClockMode::RealTime)),
      sim_(config.run.params, config.run.initial, config.run.command),
      command_(config.run.command),
      profile_(config.run.profile),
      effort_(config.motor_effort),
      paused_(config.paused),
      diagnostics_(nh, pnh)
{
  if (config_.control_mode == ControlMode::Effort)
  {
    sim_.setMotorTorque(effort_);
  }
  else
  {
    applyPositionDrive();
  }
  restartMonitor();
  if (!config_.record_bag.empty())
  {
    recorder_ = std::make_unique<NodeRecorder>(config_.record_bag);  // throws naming record_bag
  }
  joint_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", SAMPLE_QUEUE);
  impact_pub_ = nh.advertise<ImpactEvent>("impact", SAMPLE_QUEUE);
  state_pub_ = nh.advertise<BacklashState>("backlash_state", SAMPLE_QUEUE);
  limit_cycle_pub_ = nh.advertise<LimitCycleStatus>("limit_cycle", 1000, true);
  encoder_pub_ = nh.advertise<sensor_msgs::JointState>("encoder_states", SAMPLE_QUEUE);
  sim_.setSampleObserver([this](const State& s, const Drive& drive) { publishEncoders(s, drive); });
  if (clock_mode_ == ClockMode::Publisher)
  {
    clock_pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", SAMPLE_QUEUE);
    if (!ros::Time::isSimTime())
    {
      ROS_WARN(
          "backlash_servo_node: publish_clock is true but /use_sim_time is false: other nodes will not follow "
          "the simulator's clock (launch with publish_clock:=true, or set use_sim_time:=true)");
    }
  }
  diagnostics_.setHardwareID("backlash_servo");
  diagnostics_.add("simulation", this, &ServoNode::diagnose);
  sim_.setEventBudget(static_cast<std::uint64_t>(config_.run.max_events));
  command_sub_ = nh.subscribe("command", 100, &ServoNode::onCommand, this);
  trajectory_sub_ = nh.subscribe("command_trajectory", 10, &ServoNode::onTrajectory, this);
  effort_sub_ = nh.subscribe("motor_effort", 100, &ServoNode::onEffort, this);
  load_torque_sub_ = nh.subscribe("load_torque", 100, &ServoNode::onLoadTorque, this);
  reset_srv_ = pnh.advertiseService("reset", &ServoNode::onReset, this);
  pause_srv_ = pnh.advertiseService("pause", &ServoNode::onPause, this);
  resume_srv_ = pnh.advertiseService("resume", &ServoNode::onResume, this);
  // Resolved (absolute) names, as a recorder process would write them; kept so that a sample allocates nothing.
  joint_topic_ = joint_pub_.getTopic();
  impact_topic_ = impact_pub_.getTopic();
  state_topic_ = state_pub_.getTopic();
  limit_cycle_topic_ = limit_cycle_pub_.getTopic();
  encoder_topic_ = encoder_pub_.getTopic();
  clock_topic_ = clock_pub_ ? clock_pub_.getTopic() : std::string();
  command_topic_ = command_sub_.getTopic();
  trajectory_topic_ = trajectory_sub_.getTopic();
  effort_topic_ = effort_sub_.getTopic();
  load_torque_topic_ = load_torque_sub_.getTopic();

  // Seed the server with the loaded parameters before the callback is set (it is called once at once).
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<BacklashServoConfig>>(reconfigure_mutex_, pnh);
  last_good_ = currentConfig();
  reconfigure_->updateConfig(last_good_);
  reconfigure_->setCallback([this](BacklashServoConfig& c, uint32_t level) { onReconfigure(c, level); });

  if (clock_mode_ == ClockMode::External)
  {
    ros::Time::waitForValid();
    origin_ = ros::Time::now();
  }
  else if (clock_mode_ == ClockMode::Publisher)
  {
    origin_ = ros::Time(config_.start_time);  // sim time 0 is ROS time start_time (default 0, as in Gazebo)
  }
  else
  {
    origin_ = ros::Time::now();
  }
  const char* modes[] = {"real time", "publishing /clock", "following /clock"};
  ROS_INFO("backlash_servo_node: %s, real_time_factor %g, %g Hz, zeta %.3g, w_n %.3g rad/s, backlash %g rad, e %g",
           modes[static_cast<int>(clock_mode_)], config_.real_time_factor, config_.publish_rate,
           sim_.params().dampingRatio(), sim_.params().naturalFrequency(), sim_.params().backlash,
           sim_.params().restitution);
  for (const std::string& w : inputWarnings(config_.run))
  {
    ROS_WARN("backlash_servo_node: %s", w.c_str());
  }
}

BacklashServoConfig ServoNode::currentConfig() const
{
  // Every live key of the table, by name: the generated config is filled through its own message form.
  dynamic_reconfigure::Config msg;
  const ServoParams& p = sim_.params();
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
    {
      const auto it = std::find(spec->choices.begin(), spec->choices.end(), p.*(*text));
      dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, static_cast<int>(it - spec->choices.begin()));
      continue;
    }
    dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, p.*std::get<double ServoParams::*>(spec->field));
  }
  const KeyValues drive = driveKeyValues(config_.run.drive);
  for (const ParamSpec* spec : paramsIn(ParamSection::Drive))
  {
    if (spec->type == ParamType::Choice)
    {
      const std::string value = drive.text(spec->key, spec->fallback);
      const auto it = std::find(spec->choices.begin(), spec->choices.end(), value);
      dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, static_cast<int>(it - spec->choices.begin()));
    }
    else
    {
      dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, drive.number(spec->key));
    }
  }
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "control_mode",
                                                    config_.control_mode == ControlMode::Effort ? 1 : 0);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "publish_rate", config_.publish_rate);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "real_time_factor", config_.real_time_factor);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "min_impact_speed", config_.min_impact_speed);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "sync_timeout", config_.sync_timeout);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "effort_timeout", config_.effort_timeout);
  BacklashServoConfig c = BacklashServoConfig::__getDefault__();
  c.__fromMessage__(msg);
  return c;
}

void ServoNode::reanchorWallClock()
{
  wall_anchor_ = ros::WallTime::now();
  sim_anchor_ = sim_.state().time;
}

void ServoNode::restartMonitor(const std::string& reason)
{
  const bool running = monitor_ != nullptr;
  judge_from_ = profile_ && sim_.controlMode() == ControlMode::Position ? profile_->endTime() : -1.0;
  // Effort mode is fed by an external, usually digital, controller: its cycles may be quasi-periodic bands too.
  // Effort mode: the external controller's law is unknown; its rest is judged against `command` itself.
  const double equilibrium = sim_.controlMode() == ControlMode::Effort
                                 ? command_
                                 : loopEquilibrium(sim_.params(), config_.run.drive, command_);
  monitor_ = std::make_unique<ResponseMonitor>(sim_.params(), command_, equilibrium, sim_.state(),
                                               sim_.drive().sampled() || sim_.controlMode() == ControlMode::Effort);
  // The tracking figures start afresh with the judgement: the reference's last move is this step or the profile.
  RunConfig tracked = config_.run;
  tracked.params = sim_.params();
  tracked.initial = sim_.state();
  tracked.command = command_;
  tracked.profile = sim_.controlMode() == ControlMode::Position ? profile_ : nullptr;
  tracking_ = std::make_unique<TrackingMetrics>(trackingOf(tracked, 1.0 / config_.publish_rate, INFINITY));
  announced_ = Verdict::Undecided;
  steady_ = SteadyAnswer();
  if (running && !reason.empty())
  {
    verdict_reason_ = reason + " at t = " + formatNumber(sim_.state().time) + " s: judging afresh";
    publishLimitCycle(sim_.state().time, false);  // no stale verdict: undecided, with the reason, until the new one
  }
}

void ServoNode::awaitStart()
{
  // Give recorders and monitors time to subscribe before sim time starts (callbacks are served meanwhile).
  const ros::WallTime start = ros::WallTime::now() + ros::WallDuration(config_.start_delay);
  while (ros::ok() && ros::WallTime::now() < start)
  {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  if (config_.sync)
  {
    // Lockstep needs its controller connected before the first state goes out (a state nobody answers would stall
    // the run until sync_timeout): a subscriber of joint_states or encoder_states and a publisher of the answer
    // topic, plus a second for the controller's own subscription to finish connecting.
    const ros::Subscriber& answer = config_.control_mode == ControlMode::Effort ? effort_sub_ : command_sub_;
    ros::WallTime said = ros::WallTime::now();
    ROS_INFO(
        "backlash_servo_node: lockstep: waiting for a controller (subscribing joint_states or encoder_states, "
        "publishing %s)",
        answer.getTopic().c_str());
    while (ros::ok() && ((joint_pub_.getNumSubscribers() == 0 && encoder_pub_.getNumSubscribers() == 0) ||
                         answer.getNumPublishers() == 0))
    {
      ros::spinOnce();
      ros::WallDuration(0.01).sleep();
      if ((ros::WallTime::now() - said).toSec() > 10.0)
      {
        ROS_INFO("backlash_servo_node: lockstep: still waiting for a controller");
        said = ros::WallTime::now();
      }
    }
    ros::WallDuration(1.0).sleep();
    ros::spinOnce();
  }
}

bool ServoNode::due(double t)
{
  if (clock_mode_ == ClockMode::External)
  {
    if (ros::Time::now() < stamp(t))
    {
      ros::WallDuration(0.0005).sleep();
      return false;
    }
  }
  else if (config_.real_time_factor > 0.0)
  {
    // Long waits are cut into 5 ms slices so callbacks stay responsive; the last slice ends exactly on time and
    // falls through (one wake-up and one spinOnce per sample at high rates).
    const double wait =
        (wall_anchor_.toSec() + (t - sim_anchor_) / config_.real_time_factor) - ros::WallTime::now().toSec();
    if (wait > 0.005)
    {
      ros::WallDuration(0.005).sleep();
      return false;
    }
    if (wait > 0.0)
    {
      ros::WallDuration(wait).sleep();
    }
  }
  return true;
}

bool ServoNode::stepTo(double t)
{
  try
  {
    sim_.advanceTo(t, this);
  }
  catch (const MotionDiverged& e)
  {
    enterFault(e.what(), true);
    return false;
  }
  catch (const std::exception& e)
  {
    enterFault(e.what());
    return false;
  }
  ++sample_index_;
  // Rest and quiet rules, as backlash_sim applies them; in effort mode against `command` too (the external
  // controller's integrator is not visible: its stick–slip phases count as rest only once quiet for long).
  if (judge_from_ >= 0.0 && sim_.state().time >= judge_from_)
  {
    monitor_->restartAt(sim_.state());  // the profile has ended: judged afresh against its final value
    announced_ = Verdict::Undecided;
    judge_from_ = -1.0;
  }
  monitor_->check(sim_.state(), sim_.drive().winding(), judge_from_ < 0.0 && sim_.atRestForever());
  {
    const State& s = sim_.state();
    const double reference = profile_ && sim_.controlMode() == ControlMode::Position ? profile_->at(s.time) : command_;
    tracking_->add(s.time, reference, s.load_position, sim_.motorTorque());
  }
  if (monitor_->status().verdict != announced_)
  {
    publishLimitCycle(t, false);
  }
  return true;
}

void ServoNode::reportStop(double t, const ros::WallTime& run_start)
{
  if (config_.sync)
  {
    ROS_INFO("backlash_servo_node: lockstep: %ld steps, %ld answered late (after sync_timeout)", sample_index_,
             sync_misses_);
  }
  const double wall = (ros::WallTime::now() - run_start).toSec();
  const double cpu = static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
  ROS_INFO("backlash_servo_node: stop_after %g s reached: verdict %s, error %.6g rad, period %.6g s, %llu impacts",
           config_.stop_after, toString(monitor_->status().verdict), monitor_->status().error,
           monitor_->status().period, static_cast<unsigned long long>(sim_.impactCount()));
  ROS_INFO(
      "backlash_servo_node: %ld samples at %g Hz in %.3f s wall: achieved real-time factor %.1f, "
      "CPU %.3f s (%.1f %% of one core)",
      sample_index_, config_.publish_rate, wall, t / wall, cpu, 100.0 * cpu / wall);
  drainBeforeExit(wall);
}

void ServoNode::endLaunch(bool reached_stop)
{
  // Every input served so far is in the bag (the drain above serves the last ones).
  if (reached_stop && config_.stop_launch && endParentLaunch())
  {
    // roslaunch stops every node of the launch, this one with SIGINT (SIGTERM after 15 s): exit then, so that the
    // end is roslaunch's ordinary shutdown and not a required node's death.
    const ros::WallTime asked = ros::WallTime::now();
    while (ros::ok() && (ros::WallTime::now() - asked).toSec() < 20.0)
    {
      ros::WallDuration(0.01).sleep();
    }
  }
}

bool ServoNode::run()
{
  awaitStart();
  reanchorWallClock();
  const ros::WallTime run_start = ros::WallTime::now();
  if (clock_mode_ == ClockMode::Publisher)
  {
    rosgraph_msgs::Clock clock;
    clock.clock = stamp(0.0);
    emit(clock_pub_, clock_topic_, clock);
  }
  publishSample();
  sample_index_ = 1;
  awaitAnswer();
  bool reached_stop = false;
  while (ros::ok())
  {
    ros::spinOnce();  // commands, services and reconfigure act here, at a step boundary
    if ((ros::WallTime::now() - last_diagnostics_).toSec() >= 1.0)
    {
      publishDiagnostics();
      refreshReconfigureMirror();
    }
    if (paused_ || !fault_.empty())
    {
      ros::WallDuration(0.005).sleep();
      reanchorWallClock();
      continue;
    }
    const double t = sample_base_ + static_cast<double>(sample_index_) / config_.publish_rate;
    if (!due(t))
    {
      continue;
    }
    if (!stepTo(t))
    {
      continue;
    }
    checkEffortTimeout();
    if (clock_mode_ == ClockMode::Publisher)
    {
      rosgraph_msgs::Clock clock;
      clock.clock = stamp(t);
      emit(clock_pub_, clock_topic_, clock);
    }
    publishSample();
    if (!(config_.stop_after > 0.0 && t >= config_.stop_after))
    {
      awaitAnswer();
    }
    if (config_.stop_after > 0.0 && t >= config_.stop_after)
    {
      reportStop(t, run_start);
      reached_stop = true;
      break;
    }
  }
  // Every input served so far is in the bag (the drain above serves the last ones).
  const bool recorded = recorder_ == nullptr || recorder_->close();
  endLaunch(reached_stop);
  ros::shutdown();
  return recorded;
}

void ServoNode::enterFault(const std::string& what, bool diverged)
{
  // A runaway motion's state is unusable: new parameters cannot go on from it, only ~reset can (said so).
  fault_ = diverged ? what + " (the motion ran away: ~reset starts again from the initial state)" : what;
  fault_diverged_ = diverged;
  // /limit_cycle no longer shows the verdict of a motion that has ended: diverged (an unstable loop ran away) or
  // undecided with the fault as its reason.
  monitor_->restartAt(sim_.state());
  announced_ = Verdict::Undecided;
  verdict_reason_ = "simulation stopped at t = " + formatNumber(sim_.state().time) + " s: " + what;
  publishLimitCycle(sim_.state().time, false, diverged);
  const ServoParams& p = sim_.params();
  ROS_ERROR(
      "backlash_servo_node: simulation error at t = %.9g s: %s; parameters: motor_inertia %g, load_inertia %g, "
      "motor_friction %g, load_friction %g, gain %g, gear_ratio %g, backlash %g, restitution %g, command %g rad. "
      "Paused: topics, services and reconfigure keep working; ~reset or a valid parameter set resumes.",
      sim_.state().time, what.c_str(), p.motor_inertia, p.load_inertia, p.motor_friction, p.load_friction, p.gain,
      p.gear_ratio, p.backlash, p.restitution, command_);
  publishDiagnostics();
}

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
  published_ += 2 + (clock_mode_ == ClockMode::Publisher ? 1 : 0);  // joint_states, backlash_state, /clock

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
    ImpactEvent m;
    m.header.stamp = stamp(e.state.time);
    m.sim_time = e.state.time;
    m.wall = e.impact.wall == Contact::Backward ? ImpactEvent::BACKWARD : ImpactEvent::FORWARD;
    m.motor_velocity_before = e.impact.motor_velocity_before;
    m.motor_velocity_after = e.impact.motor_velocity_after;
    m.load_velocity_before = e.impact.load_velocity_before;
    m.load_velocity_after = e.impact.load_velocity_after;
    m.approach_speed = e.impact.approach_speed;
    m.impulse = e.impact.impulse;
    m.energy_loss = e.impact.energy_loss;
    m.stuck = e.impact.stuck;
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
    publishLimitCycle(e.state.time, true);
  }
  else if (e.type == EventType::Minimum)
  {
    monitor_->onEvent(e);  // the cycle's lowest points (peak to peak, centre)
  }
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
  m.verdict = diverged ? toString(Verdict::Diverged) : toString(st.verdict);
  m.detected = monitor_->oscillating();
  m.error = m.detected ? st.error : 0.0;
  m.period = m.detected ? st.period : 0.0;
  m.maxima_per_period = m.detected ? static_cast<uint32_t>(st.multiplicity) : 0;
  const CycleShape cycle = monitor_->cycleShape();
  m.peak_to_peak = m.detected ? cycle.peak_to_peak : 0.0;
  m.cycle_centre = m.detected ? cycle.centre : 0.0;
  const CycleResolution resolution = resolutionNow(cycle);
  m.peak_to_peak_counts = m.detected ? resolution.counts : NAN;
  m.peak_to_peak_arcmin = m.detected ? resolution.arcmin : NAN;
  m.below_encoder_resolution = m.detected && resolution.below_count;
  m.equilibrium = monitor_->equilibrium();
  const SteadyAnswer& steady = steadyNow();
  m.steady_error = steady.error;
  m.steady_basis = steady.basis == SteadyBasis::None ? "" : steadyBasisName(steady.basis);
  const TrackingFigures tracking = trackingNow();
  m.settling_band = tracking.band;
  m.settling_time = tracking.settling_time;
  m.steady_rms_error = tracking.steady_rms_error;
  m.maxima_observed = static_cast<uint32_t>(monitor_->maxima().size());
  if (!monitor_->maxima().empty())
  {
    const Maximum& last = monitor_->maxima().back();
    m.last_maximum_time = last.time;
    m.last_maximum_position = last.position;
    m.last_maximum_velocity = last.velocity;
  }
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
    answered_ = answered_ || awaiting_;  // lockstep: the answer for the state just published
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
  answered_ = answered_ || awaiting_;  // lockstep: the answer for the state just published
}

void ServoNode::drainBeforeExit(double wall)
{
  // roscpp keeps unsent messages in each subscriber's outgoing queue and loses them when the process exits; a
  // recorder that fell behind a fast run (real_time_factor 0) would miss the end of it. Wait as long as a recorder
  // needs at 20 000 messages per second for what was published faster than that (at most 30 s).
  // (The node's own bag needs no wait: it is complete when closed.)
  const bool subscribed = joint_pub_.getNumSubscribers() + state_pub_.getNumSubscribers() +
                              impact_pub_.getNumSubscribers() + encoder_pub_.getNumSubscribers() >
                          0;
  const double rate = static_cast<double>(published_) / std::max(wall, 1e-3);
  const double drain =
      subscribed && rate > 20000.0 ? std::min(30.0, static_cast<double>(published_) / 20000.0 - wall) : 0.0;
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(std::max(drain, 0.2));
  if (drain > 0.5)
  {
    ROS_INFO("backlash_servo_node: %.1f s for subscribers (recorders) to receive the %ld messages still queued", drain,
             published_);
  }
  while (ros::ok() && ros::WallTime::now() < end)
  {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
}

void ServoNode::awaitAnswer()
{
  if (!config_.sync)
  {
    return;
  }
  answered_ = false;
  awaiting_ = true;
  const ros::WallTime start = ros::WallTime::now();
  bool warned = false;
  while (ros::ok() && !answered_)
  {
    ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.001));
    if (paused_ || !fault_.empty())
    {
      continue;  // a paused or faulted node waits with its controller
    }
    if (config_.sync_timeout > 0.0 && (ros::WallTime::now() - start).toSec() >= config_.sync_timeout)
    {
      ++sync_misses_;
      if (!warned)
      {
        ROS_WARN(
            "backlash_servo_node: lockstep: no %s for t = %.6f s within sync_timeout %g s; advancing on the "
            "last input (this run is no longer reproducible)",
            sim_.controlMode() == ControlMode::Effort ? "motor_effort" : "command", sim_.state().time,
            config_.sync_timeout);
        warned = true;
      }
      break;
    }
  }
  awaiting_ = false;
}

void ServoNode::checkEffortTimeout()
{
  if (sim_.controlMode() != ControlMode::Effort || config_.effort_timeout <= 0.0 || effort_timed_out_ ||
      sim_.state().time - last_effort_time_ < config_.effort_timeout)
  {
    return;
  }
  effort_timed_out_ = true;
  ROS_WARN(
      "backlash_servo_node: no motor_effort for %g s of sim time (effort_timeout): motor torque set to 0 N·m "
      "(was %g N·m) until the next message",
      sim_.state().time - last_effort_time_, effort_);
  effort_ = 0.0;
  sim_.setMotorTorque(0.0);
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
    const auto joint = std::find(msg.joint_names.begin(), msg.joint_names.end(), config_.load_joint_name);
    if (joint == msg.joint_names.end())
    {
      throw ConfigError("no joint named '" + config_.load_joint_name + "' in joint_names");
    }
    const std::size_t j = static_cast<std::size_t>(joint - msg.joint_names.begin());
    if (msg.points.empty())
    {
      throw ConfigError("no points");
    }
    // Start: the header's stamp in sim time, or now for a zero stamp (the ROS convention).
    const double start = msg.header.stamp.isZero() ? now : (msg.header.stamp - origin_).toSec();
    if (!(start >= 0.0))
    {
      throw ConfigError("header.stamp lies before the simulation's time 0");
    }
    const double from = profile_ ? profile_->at(std::max(start, now)) : command_;
    std::vector<ProfileSegment> segments;
    double previous = 0.0;
    for (std::size_t i = 0; i < msg.points.size(); ++i)
    {
      const trajectory_msgs::JointTrajectoryPoint& point = msg.points[i];
      const std::string where = "point " + std::to_string(i + 1);
      if (point.positions.size() != msg.joint_names.size())
      {
        throw ConfigError(where + ": " + std::to_string(point.positions.size()) + " positions for " +
                          std::to_string(msg.joint_names.size()) + " joint names");
      }
      param("command").check(point.positions[j]);  // finite and inside the validated envelope
      const double t = point.time_from_start.toSec();
      if (!(t >= previous))
      {
        throw ConfigError(where + ": time_from_start " + std::to_string(t) + " s is before the previous point's");
      }
      ProfileSegment s;
      s.time = start + previous;
      s.target = point.positions[j];
      s.kind = t > previous ? ProfileSegment::Kind::Ramp : ProfileSegment::Kind::Step;
      s.duration = t - previous;  // linear interpolation from the previous point (the first: from the set-point)
      segments.push_back(s);
      previous = t;
    }
    auto profile = std::make_shared<CommandProfile>(from, segments);
    sim_.setProfile(profile);  // throws before changing anything if the law cannot take it (ramps with dry friction)
    profile_ = profile;
    command_ = profile_->finalValue();
    ROS_INFO("backlash_servo_node: command_trajectory: %zu points from t = %.6g s to %.6g s, final %g rad",
             msg.points.size(), start, start + previous, command_);
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: command_trajectory refused (%s); keeping the current set-point", e.what());
    return;
  }
  answered_ = answered_ || awaiting_;  // lockstep: a trajectory answers the state just published, as a command does
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

void ServoNode::refreshReconfigureMirror()
{
  if (mirror_stale_)
  {
    mirror_stale_ = false;
    last_good_ = currentConfig();
    reconfigure_->updateConfig(last_good_);
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
    reanchorWallClock();
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
  reanchorWallClock();
  res.success = true;
  res.message = "running from t = " + std::to_string(sim_.state().time) + " s";
  return true;
}

void ServoNode::onReconfigure(BacklashServoConfig& c, uint32_t)
{
  if (mirror_stale_ && c.load_torque == last_good_.load_torque)
  {
    // Not touched by this reconfigure: the value the load_torque topic set since the mirror's last refresh stays.
    c.load_torque = sim_.params().load_torque;
  }
  mirror_stale_ = false;
  const KeyValues kv = keyValuesOf(c);
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
  const KeyValues before = keyValuesOf(last_good_);
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
  reanchorWallClock();
  last_good_ = c;
  if (!fault_.empty() && !fault_diverged_)
  {
    ROS_INFO("backlash_servo_node: valid parameters clear the simulation error; running again");
    fault_.clear();
    publishDiagnostics();
  }
}

}  // namespace backlash_servo
