// backlash_servo_node for an arm: the joints of a robot description in one simulated time.
#include "robot_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <rosgraph_msgs/Clock.h>

#include <algorithm>
#include <ctime>

#include "backlash_servo/BacklashState.h"
#include "backlash_servo/LimitCycleStatus.h"
#include "backlash_servo/config/robot_config.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/model/param_table.h"
#include "launch_end.h"
#include "reconfigure_values.h"
#include "status_messages.h"
#include "trajectory_profile.h"
#include "wall_throttle.h"

namespace backlash_servo
{
namespace
{
constexpr uint32_t SAMPLE_QUEUE = 100000;

/// The robot description: the `robot_description` parameter, else the file ~urdf (which is then read).
std::string robotDescription(const ros::NodeHandle& nh, const std::string& urdf_file)
{
  std::string text;
  if (nh.getParam("robot_description", text))
  {
    if (!urdf_file.empty())
    {
      ROS_INFO("backlash_servo_node: the robot description is the parameter %s (~urdf '%s' is not read)",
               nh.resolveName("robot_description").c_str(), urdf_file.c_str());
    }
    return text;
  }
  if (urdf_file.empty())
  {
    return "";
  }
  return readRegularFile("~urdf", urdf_file, MAX_URDF_BYTES);
}
/// A geared joint of the arm (a transmission in the URDF) left out of `joints:` is most often one written `NAME: {}`:
/// the parameter server drops empty mappings, so the node never sees it. Said, with the remedy.
void warnUnsimulatedTransmissions(const RobotNodeConfig& c)
{
  if (!c.arm)
  {
    return;
  }
  std::string left;
  for (const ArmJoint& j : c.arm->joints())
  {
    const bool simulated =
        std::any_of(c.joints.begin(), c.joints.end(), [&j](const RobotJoint& r) { return r.name == j.name; });
    if (j.reduction != 0.0 && !simulated)
    {
      left += (left.empty() ? "" : ", ") + j.name;
    }
  }
  if (!left.empty())
  {
    ROS_WARN(
        "backlash_servo_node: the robot description's geared joints %s are not simulated (held at 0 rad in the pose): "
        "a joint written as '%s: {}' in ~joints is dropped by the parameter server — give it a key, e.g. its command",
        left.c_str(), left.substr(0, left.find(',')).c_str());
  }
}
}  // namespace

RobotNodeConfig loadRobotNodeConfig(const ros::NodeHandle& nh, const PrivateParams& given)
{
  RobotNodeConfig c;
  c.node = nodeSettingsFrom(withNodeDefaults(given.given), NodeConfig());
  c.arm = armModelFrom(robotDescription(nh, given.urdf), "robot_description");
  c.joints = robotJointsFrom(given.given, given.joints, c.arm.get());
  warnUnsimulatedTransmissions(c);
  return c;
}

RobotNode::RobotNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, const RobotNodeConfig& config)
    : config_(config), clock_(nh, config_.node, SAMPLE_QUEUE), diagnostics_(nh, pnh), paused_(config.node.paused)
{
  robot_ = std::make_unique<RobotSimulator>(config_.joints, config_.arm.get(), 1.0 / config_.node.publish_rate);
  for (std::size_t i = 0; effortMode() && i < robot_->size(); ++i)
  {
    robot_->joint(i).setMotorTorque(config_.node.motor_effort);
  }
  if (!config_.node.record_bag.empty())
  {
    recorder_ = std::make_unique<NodeRecorder>(config_.node.record_bag);  // throws naming record_bag
  }
  joint_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", SAMPLE_QUEUE);
  impact_pub_ = nh.advertise<ImpactEvent>("impact", SAMPLE_QUEUE);
  encoder_pub_ = nh.advertise<sensor_msgs::JointState>("encoder_states", SAMPLE_QUEUE);
  joint_topic_ = joint_pub_.getTopic();
  impact_topic_ = impact_pub_.getTopic();
  encoder_topic_ = encoder_pub_.getTopic();
  diagnostics_.setHardwareID("backlash_servo");
  for (const bool motors : {false, true})
  {
    for (std::size_t i = 0; i < robot_->size(); ++i)
    {
      joint_msg_.name.push_back(motors ? robot_->spec(i).motor_name : robot_->spec(i).name);
    }
  }
  encoder_msg_.name = joint_msg_.name;
  clock_topic_ = clock_.publisher() ? clock_.publisher().getTopic() : std::string();
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    auto ch = std::make_unique<Channel>();
    ch->node = this;
    ch->index = i;
    const std::string& name = robot_->spec(i).name;
    ch->judge = std::make_unique<JointJudge>(name, name + ": ");
    ch->command = config_.joints[i].run.command;
    ch->limit_cycle_pub = nh.advertise<LimitCycleStatus>(name + "/limit_cycle", 1000, true);
    ch->limit_cycle_topic = ch->limit_cycle_pub.getTopic();
    ch->state_pub = nh.advertise<BacklashState>(name + "/backlash_state", SAMPLE_QUEUE);
    ch->state_topic = ch->state_pub.getTopic();
    if (!effortMode())
    {
      robot_->joint(i).setSampleObserver([this, i](const State& s, const Drive& d) { publishEncoders(i, s, d); });
    }
    diagnostics_.add(name, [this, i](diagnostic_updater::DiagnosticStatusWrapper& st) { diagnose(i, st); });
    ch->command_sub = nh.subscribe<std_msgs::Float64>(
        name + "/command", 100, [this, i](const std_msgs::Float64::ConstPtr& m) { onCommand(i, *m); });
    ch->command_topic = ch->command_sub.getTopic();
    sinks_.push_back(ch.get());
    channels_.push_back(std::move(ch));
  }
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    // One group per joint (rqt: ~<joint>), seeded with the joint's values before the callback is set.
    Channel& ch = *channels_[i];
    ch.reconfigure = std::make_unique<dynamic_reconfigure::Server<BacklashServoConfig>>(
        ch.reconfigure_mutex, ros::NodeHandle(pnh, robot_->spec(i).name));
    ch.last_good = reconfigureConfig(robot_->joint(i).params(), config_.joints[i].run.drive, config_.node);
    ch.reconfigure->updateConfig(ch.last_good);
    ch.reconfigure->setCallback([this, i](BacklashServoConfig& c, uint32_t) { onReconfigure(i, c); });
  }
  trajectory_sub_ = nh.subscribe("command_trajectory", 10, &RobotNode::onTrajectory, this);
  trajectory_topic_ = trajectory_sub_.getTopic();
  effort_sub_ = nh.subscribe("motor_effort", 100, &RobotNode::onEffort, this);
  effort_topic_ = effort_sub_.getTopic();
  pause_srv_ = pnh.advertiseService("pause", &RobotNode::onPause, this);
  resume_srv_ = pnh.advertiseService("resume", &RobotNode::onResume, this);
  clock_.start();
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    restartMonitor(i, "");
    const ServoParams& p = robot_->joint(i).params();
    ROS_INFO(
        "backlash_servo_node: joint %s (motor %s): gear ratio %g, backlash %g rad, load torque %g N·m%s, load "
        "inertia %g kg·m²%s",
        robot_->spec(i).name.c_str(), robot_->spec(i).motor_name.c_str(), p.gear_ratio, p.backlash, p.load_torque,
        robot_->spec(i).arm_gravity ? " (the arm's gravity)" : "", p.load_inertia,
        robot_->spec(i).arm_inertia ? " (the arm's, at the pose)" : "");
  }
  ROS_INFO("backlash_servo_node: an arm of %zu joints%s, %s mode%s, %s, real_time_factor %g, %g Hz", robot_->size(),
           config_.arm ? (" ('" + config_.arm->robotName() + "')").c_str() : "", effortMode() ? "effort" : "position",
           config_.node.sync ? " in lockstep" : "", clock_.modeName(), config_.node.real_time_factor,
           config_.node.publish_rate);
}

void RobotNode::Channel::onEvent(const Event& e)
{
  const std::string& name = node->robot_->spec(index).name;
  if (e.type == EventType::Impact)
  {
    if (e.impact.approach_speed >= node->config_.node.min_impact_speed)
    {
      node->emit(node->impact_pub_, node->impact_topic_, impactMessage(e, node->stamp(e.state.time), name));
    }
    return;
  }
  std::string withdrawn;
  if (judge->onEvent(e, &withdrawn))
  {
    node->publishLimitCycle(index, e.state.time, true);
  }
  else if (!withdrawn.empty() && node->fault_.empty())
  {
    ROS_WARN("backlash_servo_node: %s: %s", name.c_str(), withdrawn.c_str());
    node->restartMonitor(index, withdrawn);
  }
}

void RobotNode::restartMonitor(std::size_t i, const std::string& reason)
{
  const Simulator& sim = robot_->joint(i);
  channels_[i]->judge->restart(sim, config_.joints[i].run, setPoint(i), sim.profile(), 1.0 / config_.node.publish_rate,
                               reason);
  publishLimitCycle(i, sim.state().time, false);
}

double RobotNode::setPoint(std::size_t i) const
{
  const Simulator& sim = robot_->joint(i);
  if (effortMode())
  {
    return channels_[i]->command;
  }
  return sim.profile() ? sim.profile()->finalValue() : sim.command();
}

double RobotNode::reference(std::size_t i) const
{
  const Simulator& sim = robot_->joint(i);
  return !effortMode() && sim.profile() ? sim.profile()->at(sim.state().time) : setPoint(i);
}

void RobotNode::publishLimitCycle(std::size_t i, double sim_time, bool maximum)
{
  Channel& ch = *channels_[i];
  LimitCycleStatus m = ch.judge->status(robot_->joint(i), config_.joints[i].run, sim_time, fault_.empty(), maximum);
  m.header.stamp = stamp(sim_time);
  emit(ch.limit_cycle_pub, ch.limit_cycle_topic, m);
}

void RobotNode::onCommand(std::size_t joint, const std_msgs::Float64& msg)
{
  const Channel& ch = *channels_[joint];
  record(ch.command_topic, msg);
  try
  {
    param("command").check(msg.data);
    if (!effortMode())
    {
      robot_->joint(joint).setCommand(msg.data, channels_[joint].get());
      lockstep_.answered();  // lockstep: the answer for the state just published
    }
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: %s refused (%s); keeping the current set-point", ch.command_topic.c_str(),
              e.what());
    return;
  }
  channels_[joint]->command = msg.data;  // effort mode: the set-point judged against
  restartMonitor(joint, "new command " + formatNumber(msg.data) + " rad");
}

void RobotNode::onTrajectory(const trajectory_msgs::JointTrajectory& msg)
{
  record(trajectory_topic_, msg);
  const double now = robot_->time();
  std::vector<std::pair<std::size_t, std::shared_ptr<CommandProfile>>> profiles;
  try
  {
    if (effortMode())
    {
      throw ConfigError("the node is in effort mode (control_mode: effort); a trajectory is a position command");
    }
    const double start = trajectoryStart(msg, clock_.origin(), now);
    for (const std::string& name : msg.joint_names)
    {
      const int i = robot_->indexOf(name);
      if (i < 0)
      {
        throw ConfigError("joint_names: '" + name + "' is not one of this arm's joints");
      }
      const Simulator& sim = robot_->joint(static_cast<std::size_t>(i));
      const double from = sim.profile() ? sim.profile()->at(std::max(start, now)) : sim.command();
      profiles.emplace_back(static_cast<std::size_t>(i), trajectoryProfile(msg, name, start, from));
    }
    for (const auto& [i, profile] : profiles)
    {
      robot_->joint(i).setProfile(profile, channels_[i].get());
    }
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: command_trajectory refused (%s); keeping every set-point", e.what());
    return;
  }
  lockstep_.answered();  // lockstep: a trajectory answers the state just published
  for (const auto& [i, profile] : profiles)
  {
    restartMonitor(i, "new command_trajectory");
  }
}

void RobotNode::onEffort(const sensor_msgs::JointState& msg)
{
  record(effort_topic_, msg);
  if (!effortMode())
  {
    // Not kept either: a torque sent in position mode must not surface later.
    BACKLASH_LOG_WALL_THROTTLE(WARN, 5.0,
                               "backlash_servo_node: motor_effort ignored in position mode (set control_mode: effort)");
    return;
  }
  std::vector<std::pair<std::size_t, double>> efforts;
  try
  {
    if (msg.effort.size() != msg.name.size())
    {
      throw ConfigError("effort: " + std::to_string(msg.effort.size()) + " values for " +
                        std::to_string(msg.name.size()) + " names");
    }
    for (std::size_t k = 0; k < msg.name.size(); ++k)
    {
      const int i = motorOrJoint(msg.name[k]);
      if (i < 0)
      {
        throw ConfigError("name: '" + msg.name[k] + "' is neither a joint nor a motor of this arm");
      }
      try
      {
        param("motor_effort").check(msg.effort[k]);
      }
      catch (const std::exception& e)
      {
        throw ConfigError(msg.name[k] + ": " + e.what());
      }
      efforts.emplace_back(static_cast<std::size_t>(i), msg.effort[k]);
    }
  }
  catch (const std::exception& e)
  {
    BACKLASH_LOG_WALL_THROTTLE(ERROR, 1.0, "backlash_servo_node: motor_effort refused (%s); keeping every torque",
                               e.what());
    return;
  }
  for (const auto& [i, effort] : efforts)
  {
    Channel& ch = *channels_[i];
    robot_->joint(i).setMotorTorque(effort, &ch);
    ch.last_effort_time = robot_->time();
    ch.effort_timed_out = false;
  }
  lockstep_.answered();  // lockstep: the answer for the state just published
}

int RobotNode::motorOrJoint(const std::string& name) const
{
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    if (robot_->spec(i).name == name || robot_->spec(i).motor_name == name)
    {
      return static_cast<int>(i);
    }
  }
  return -1;
}

void RobotNode::onReconfigure(std::size_t joint, BacklashServoConfig& c)
{
  Channel& ch = *channels_[joint];
  Simulator& sim = robot_->joint(joint);
  const RobotJoint& spec = robot_->spec(joint);
  const KeyValues kv = reconfigureValues(c);
  const KeyValues before = reconfigureValues(ch.last_good);
  std::string changed;
  bool drive_changed = false;
  ServoParams p = sim.params();
  DriveParams drive = config_.joints[joint].run.drive;
  try
  {
    for (const auto& [key, text] : kv.keys())
    {
      if (before.text(key, "") == text)
      {
        continue;
      }
      const ParamSection section = findParam(key)->section;
      if (section == ParamSection::Node)
      {
        throw ConfigError(key + ": the arm's setting (the node's ~" + key + "), not a joint's");
      }
      if ((key == "load_torque" && spec.arm_gravity) || (key == "load_inertia" && spec.arm_inertia))
      {
        throw ConfigError(key + ": the arm sets it at every sample from the pose (give " + key +
                          " in the joint's keys to hold a constant)");
      }
      if (key == "controller_rate" || key == "control_law" || key == "feedback" || key == "compensation")
      {
        throw ConfigError(key + ": the arm's loads follow the joint's controller samples; a new " + key +
                          " restarts them (restart the node)");
      }
      changed += (changed.empty() ? "" : ", ") + key;
      drive_changed = drive_changed || section == ParamSection::Drive;
    }
    updateServoKeys(kv, &p);
    p.load_torque = sim.params().load_torque;  // the arm's, or the constant no change touched
    p.load_inertia = sim.params().load_inertia;
    p.validate();
    readDriveKeys(kv, true, &drive);
    drive.validate(config_.node.control_mode);
    // (Effort mode: the settings are stored; the encoders apply to encoder_states at once.)
    if (drive_changed && !effortMode() && !sim.retuneDrive(drive, &ch))  // nothing changed when it cannot
    {
      throw ConfigError("the drive's new settings need a fresh controller (restart the node)");
    }
    sim.setParams(p, &ch);  // validated above: applied
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: %s: reconfigure refused: %s; keeping the previous values", spec.name.c_str(),
              e.what());
    c = ch.last_good;
    return;
  }
  config_.joints[joint].run.drive = drive;
  ch.last_good = c;
  if (!changed.empty())
  {
    restartMonitor(joint, "live change of " + changed);
  }
}

bool RobotNode::onPause(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  paused_ = true;
  res.success = true;
  res.message = "paused at t = " + formatNumber(robot_->time()) + " s";
  return true;
}

bool RobotNode::onResume(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res)
{
  res.success = fault_.empty();
  res.message = fault_.empty() ? "resumed at t = " + formatNumber(robot_->time()) + " s" : "not resumed: " + fault_;
  paused_ = paused_ && !fault_.empty();
  clock_.reanchor(robot_->time());
  return true;
}

void RobotNode::publishSample()
{
  const std::size_t n = robot_->size();
  const ros::Time now = stamp(robot_->time());
  if (effortMode())
  {
    // The plant's encoders, read at the external controller's period (the publish period), before joint_states.
    sensor_msgs::JointState& enc = encoder_msg_;
    enc.header.stamp = now;
    enc.position.resize(2 * n);
    for (std::size_t i = 0; i < n; ++i)
    {
      const State& s = robot_->joint(i).state();
      const DriveParams& d = config_.joints[i].run.drive;
      enc.position[i] = encoderReading(s.load_position, d.load_encoder_resolution);
      enc.position[n + i] = encoderReading(s.motor_position, d.motor_encoder_resolution);
    }
    emit(encoder_pub_, encoder_topic_, enc);
  }
  sensor_msgs::JointState& js = joint_msg_;
  js.header.stamp = now;
  js.position.resize(2 * n);
  js.velocity.resize(2 * n);
  js.effort.resize(2 * n);
  for (std::size_t i = 0; i < n; ++i)
  {
    const Simulator& sim = robot_->joint(i);
    const State& s = sim.state();
    js.position[i] = s.load_position;
    js.position[n + i] = s.motor_position;
    js.velocity[i] = s.load_velocity;
    js.velocity[n + i] = s.motor_velocity;
    js.effort[i] = sim.meshTorque();
    js.effort[n + i] = sim.motorTorque();
  }
  emit(joint_pub_, joint_topic_, js);
  for (std::size_t i = 0; i < n; ++i)
  {
    const Channel& ch = *channels_[i];
    emit(ch.state_pub, ch.state_topic, backlashStateMessage(robot_->joint(i), reference(i), now));
  }
}

void RobotNode::publishEncoders(std::size_t i, const State& s, const Drive& drive)
{
  double motor = 0.0, load = 0.0;
  if (drive.readings(&motor, &load))
  {
    readings_.push_back({s.time, i, load, motor});  // published with the others of its instant (flushEncoders)
  }
}

void RobotNode::flushEncoders()
{
  std::stable_sort(readings_.begin(), readings_.end(),
                   [](const Reading& a, const Reading& b) { return a.time < b.time; });
  for (std::size_t k = 0; k < readings_.size();)
  {
    std::size_t end = k;
    while (end < readings_.size() && readings_[end].time == readings_[k].time)
    {
      ++end;
    }
    sensor_msgs::JointState js;  // the joints sampled at this instant: their loads, then their motors
    js.header.stamp = stamp(readings_[k].time);
    for (std::size_t r = k; r < end; ++r)
    {
      js.name.push_back(robot_->spec(readings_[r].joint).name);
      js.position.push_back(readings_[r].load);  // quantised q(θ_c) [rad]
    }
    for (std::size_t r = k; r < end; ++r)
    {
      js.name.push_back(robot_->spec(readings_[r].joint).motor_name);
      js.position.push_back(readings_[r].motor);  // quantised q(θ_m) [rad, motor shaft]
    }
    emit(encoder_pub_, encoder_topic_, js);
    k = end;
  }
  readings_.clear();
}

void RobotNode::publishClock(double t, bool force)
{
  if (clock_.clockDue(t, force))
  {
    rosgraph_msgs::Clock clock;
    clock.clock = stamp(t);
    emit(clock_.publisher(), clock_topic_, clock);
  }
}

bool RobotNode::stepTo(double t)
{
  try
  {
    robot_->advanceTo(t, sinks_);
    flushEncoders();
  }
  catch (const std::exception& e)
  {
    flushEncoders();  // what the drives read before the fault
    fault_ = "simulation stopped at t = " + formatNumber(robot_->time()) + " s: " + e.what();
    ROS_ERROR("backlash_servo_node: %s. Paused: topics and services keep working.", fault_.c_str());
    paused_ = true;
    for (std::size_t i = 0; i < robot_->size(); ++i)
    {
      channels_[i]->judge->fault(robot_->joint(i), e.what());
      publishLimitCycle(i, robot_->time(), false);
    }
    diagnostics_.force_update();
    return false;
  }
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    if (channels_[i]->judge->sample(robot_->joint(i), reference(i)))
    {
      publishLimitCycle(i, robot_->time(), false);
    }
  }
  return true;
}

void RobotNode::checkEffortTimeouts()
{
  const double timeout = config_.node.effort_timeout;
  for (std::size_t i = 0; effortMode() && timeout > 0.0 && i < robot_->size(); ++i)
  {
    Channel& ch = *channels_[i];
    Simulator& sim = robot_->joint(i);
    if (ch.effort_timed_out || robot_->time() - ch.last_effort_time < timeout)
    {
      continue;
    }
    ch.effort_timed_out = true;
    ROS_WARN(
        "backlash_servo_node: %s: no motor_effort for %g s of sim time (effort_timeout): motor torque set to 0 N·m "
        "(was %g N·m) until the next message",
        robot_->spec(i).name.c_str(), robot_->time() - ch.last_effort_time, sim.motorTorque());
    sim.setMotorTorque(0.0, &ch);
  }
}

void RobotNode::diagnose(std::size_t i, diagnostic_updater::DiagnosticStatusWrapper& status)
{
  const Simulator& sim = robot_->joint(i);
  status.summary(fault_.empty() ? diagnostic_msgs::DiagnosticStatus::OK : diagnostic_msgs::DiagnosticStatus::ERROR,
                 fault_.empty() ? (paused_ ? "paused" : "running") : fault_);
  status.add("sim_time [s]", formatNumber(sim.state().time));
  status.add("impacts", std::to_string(sim.impactCount()));
  status.add("load_torque [N·m]", formatNumber(sim.params().load_torque));
  status.add("load_inertia [kg·m²]", formatNumber(sim.params().load_inertia));
  channels_[i]->judge->diagnose(sim, config_.joints[i].run, &status);
  if (config_.node.sync)
  {
    status.add("lockstep answers late", std::to_string(lockstep_.late()));
  }
}

void RobotNode::awaitStart()
{
  serveCallbacksFor(config_.node.start_delay);  // recorders and monitors subscribe before sim time starts
  if (!config_.node.sync)
  {
    return;
  }
  // A subscriber of joint_states or encoder_states and a publisher of the answer.
  const auto connected = [this] {
    bool answering = effortMode() ? effort_sub_.getNumPublishers() > 0 : trajectory_sub_.getNumPublishers() > 0;
    for (const auto& ch : channels_)
    {
      answering = answering || (!effortMode() && ch->command_sub.getNumPublishers() > 0);
    }
    return answering && (joint_pub_.getNumSubscribers() > 0 || encoder_pub_.getNumSubscribers() > 0);
  };
  lockstep_.waitForController(connected, effortMode() ? effort_topic_ : trajectory_topic_ + " or <joint>/command");
}

void RobotNode::awaitAnswer()
{
  if (config_.node.sync)
  {
    lockstep_.awaitAnswer([this] { return paused_; }, effortMode() ? "motor_effort" : "command", robot_->time(),
                          config_.node.sync_timeout);
  }
}

void RobotNode::reportStop(double t, const ros::WallTime& run_start)
{
  const double wall = (ros::WallTime::now() - run_start).toSec();
  const double cpu = static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    const LimitCycleReport& st = channels_[i]->judge->monitor().status();
    ROS_INFO(
        "backlash_servo_node: stop_after %g s reached: %s: verdict %s, error %.6g rad, period %.6g s, %llu impacts",
        config_.node.stop_after, robot_->spec(i).name.c_str(), toString(st.verdict), st.error, st.period,
        static_cast<unsigned long long>(robot_->joint(i).impactCount()));
  }
  if (config_.node.sync)
  {
    ROS_INFO("backlash_servo_node: lockstep: %ld steps, %ld answered late (after sync_timeout)", sample_index_,
             lockstep_.late());
  }
  ROS_INFO(
      "backlash_servo_node: %ld samples at %g Hz in %.3f s wall: achieved real-time factor %.1f, CPU %.3f s (%.1f %% "
      "of one core)",
      sample_index_, config_.node.publish_rate, wall, t / wall, cpu, 100.0 * cpu / wall);
}

bool RobotNode::run()
{
  awaitStart();
  clock_.reanchor(robot_->time());
  const ros::WallTime run_start = ros::WallTime::now();
  publishClock(robot_->time(), true);
  publishSample();
  sample_index_ = 1;
  awaitAnswer();
  bool reached_stop = false;
  while (ros::ok())
  {
    ros::spinOnce();  // commands, services and reconfigure act here, at a step boundary
    if ((ros::WallTime::now() - last_diagnostics_).toSec() >= 1.0)
    {
      last_diagnostics_ = ros::WallTime::now();
      diagnostics_.force_update();  // on the node's own 1 s wall schedule: sim time may run at any rate
    }
    if (paused_)
    {
      if (clock_.skipped() >= 0.0)
      {
        publishClock(clock_.skipped(), true);  // a paused graph sees the time the node stands at
      }
      ros::WallDuration(0.005).sleep();
      clock_.reanchor(robot_->time());
      continue;
    }
    const double t = static_cast<double>(sample_index_) / config_.node.publish_rate;
    if (!clock_.due(t) || !stepTo(t))
    {
      continue;
    }
    ++sample_index_;
    checkEffortTimeouts();
    const bool stop = config_.node.stop_after > 0.0 && t >= config_.node.stop_after;
    publishClock(t, stop);
    publishSample();
    awaitAnswer();  // the last state too: every published state has its answer in the bag
    if (stop)
    {
      reportStop(t, run_start);
      reached_stop = true;
      break;
    }
  }
  const bool recorded = recorder_ == nullptr || recorder_->close();
  if (reached_stop && config_.node.stop_launch)
  {
    endParentLaunchAndWait();
  }
  ros::shutdown();
  return recorded;
}

}  // namespace backlash_servo
