// backlash_servo_node for an arm: the joints of a robot description in one simulated time.
#include "robot_node.h"

#include <rosgraph_msgs/Clock.h>

#include <algorithm>
#include <ctime>

#include "backlash_servo/LimitCycleStatus.h"
#include "backlash_servo/config/robot_config.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/model/param_table.h"
#include "launch_end.h"
#include "reconfigure_values.h"
#include "status_messages.h"
#include "trajectory_profile.h"

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
}  // namespace

RobotNodeConfig loadRobotNodeConfig(const ros::NodeHandle& nh, const PrivateParams& given)
{
  RobotNodeConfig c;
  c.node = nodeSettingsFrom(withNodeDefaults(given.given), NodeConfig());
  if (c.node.control_mode != ControlMode::Position || c.node.sync)
  {
    throw ConfigError(std::string(c.node.sync ? "sync" : "control_mode") +
                      ": an arm's joints run their own drives (position mode, not in lockstep)");
  }
  c.arm = armModelFrom(robotDescription(nh, given.urdf), "robot_description");
  c.joints = robotJointsFrom(given.given, given.joints, c.arm.get());
  return c;
}

RobotNode::RobotNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, const RobotNodeConfig& config)
    : config_(config), clock_(nh, config_.node, SAMPLE_QUEUE), paused_(config.node.paused)
{
  robot_ = std::make_unique<RobotSimulator>(config_.joints, config_.arm.get(), 1.0 / config_.node.publish_rate);
  if (!config_.node.record_bag.empty())
  {
    recorder_ = std::make_unique<NodeRecorder>(config_.node.record_bag);  // throws naming record_bag
  }
  joint_pub_ = nh.advertise<sensor_msgs::JointState>("joint_states", SAMPLE_QUEUE);
  impact_pub_ = nh.advertise<ImpactEvent>("impact", SAMPLE_QUEUE);
  joint_topic_ = joint_pub_.getTopic();
  impact_topic_ = impact_pub_.getTopic();
  clock_topic_ = clock_.publisher() ? clock_.publisher().getTopic() : std::string();
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    auto ch = std::make_unique<Channel>();
    ch->node = this;
    ch->index = i;
    const std::string& name = robot_->spec(i).name;
    ch->limit_cycle_pub = nh.advertise<LimitCycleStatus>(name + "/limit_cycle", 1000, true);
    ch->limit_cycle_topic = ch->limit_cycle_pub.getTopic();
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
  ROS_INFO("backlash_servo_node: an arm of %zu joints%s, %s, real_time_factor %g, %g Hz", robot_->size(),
           config_.arm ? (" ('" + config_.arm->robotName() + "')").c_str() : "", clock_.modeName(),
           config_.node.real_time_factor, config_.node.publish_rate);
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
  if (e.type == EventType::Maximum || e.type == EventType::Minimum)
  {
    const std::size_t before = monitor->maxima().size();
    monitor->onEvent(e);
    if (e.type != EventType::Maximum || monitor->maxima().size() == before)
    {
      return;
    }
    if (announced == Verdict::Converged && node->fault_.empty() && monitor->leavesConvergence(e.state))
    {
      const std::string why =
          "the converged verdict is withdrawn: the load moved again (maximum at t = " + formatNumber(e.state.time) +
          " s, " + formatNumber(e.state.load_position - monitor->equilibrium()) + " rad beyond where it rested)";
      ROS_WARN("backlash_servo_node: %s: %s", name.c_str(), why.c_str());
      node->restartMonitor(index, why);
      return;
    }
    node->publishLimitCycle(index, e.state.time);
  }
}

void RobotNode::restartMonitor(std::size_t i, const std::string& reason)
{
  const Simulator& sim = robot_->joint(i);
  Channel& ch = *channels_[i];
  const double target = setPoint(i);
  ch.monitor = std::make_unique<ResponseMonitor>(sim.params(), target,
                                                 loopEquilibrium(sim.params(), config_.joints[i].run.drive, target),
                                                 sim.state(), sim.drive().sampled());
  // A profile is judged from its end on (a hunt around an intermediate set-point is not the final verdict).
  ch.judge_from = sim.profile() && sim.profile()->endTime() > sim.state().time ? sim.profile()->endTime() : -1.0;
  ch.announced = Verdict::Undecided;
  ch.reason = reason.empty() ? "" : reason + " at t = " + formatNumber(sim.state().time) + " s: judging afresh";
  publishLimitCycle(i, sim.state().time);
}

double RobotNode::setPoint(std::size_t i) const
{
  const Simulator& sim = robot_->joint(i);
  return sim.profile() ? sim.profile()->finalValue() : sim.command();
}

void RobotNode::publishLimitCycle(std::size_t i, double sim_time)
{
  Channel& ch = *channels_[i];
  const Simulator& sim = robot_->joint(i);
  LimitCycleStatus m;
  m.header.stamp = stamp(sim_time);
  m.sim_time = sim_time;
  RunConfig read = config_.joints[i].run;
  read.params = sim.params();
  fillVerdict(*ch.monitor, cycleResolution(ch.monitor->cycleShape(), loopCount(read)), &m);
  m.steady_error = NAN;
  m.settling_band = NAN;
  m.settling_time = NAN;
  m.steady_rms_error = NAN;
  m.command = setPoint(i);
  m.joint = robot_->spec(i).name;
  if (ch.monitor->status().verdict != Verdict::Undecided && fault_.empty())
  {
    ch.reason.clear();
  }
  m.reason = fault_.empty() ? ch.reason : fault_;
  emit(ch.limit_cycle_pub, ch.limit_cycle_topic, m);
  if (ch.monitor->status().verdict != ch.announced)
  {
    ch.announced = ch.monitor->status().verdict;
    ROS_INFO("backlash_servo_node: %s: %s at t = %.4f s%s", m.joint.c_str(), m.verdict.c_str(), sim_time,
             m.detected
                 ? (" (peak to peak " + formatNumber(m.peak_to_peak) + " rad, period " + formatNumber(m.period) + " s)")
                       .c_str()
                 : "");
  }
}

void RobotNode::onCommand(std::size_t joint, const std_msgs::Float64& msg)
{
  const Channel& ch = *channels_[joint];
  if (recorder_)
  {
    recorder_->write(ch.command_topic, msg);
  }
  try
  {
    param("command").check(msg.data);
    robot_->joint(joint).setCommand(msg.data, &*channels_[joint]);
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: %s refused (%s); keeping the current set-point", ch.command_topic.c_str(),
              e.what());
    return;
  }
  restartMonitor(joint, "new command " + formatNumber(msg.data) + " rad");
}

void RobotNode::onTrajectory(const trajectory_msgs::JointTrajectory& msg)
{
  if (recorder_)
  {
    recorder_->write(trajectory_topic_, msg);
  }
  const double now = robot_->time();
  std::vector<std::pair<std::size_t, std::shared_ptr<CommandProfile>>> profiles;
  try
  {
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
  for (const auto& [i, profile] : profiles)
  {
    restartMonitor(i, "new command_trajectory");
  }
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
    drive.validate(ControlMode::Position);
    if (drive_changed && !sim.retuneDrive(drive, &ch))  // nothing changed when it cannot
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
  sensor_msgs::JointState& js = joint_msg_;
  js.header.stamp = stamp(robot_->time());
  js.name.resize(2 * n);
  js.position.resize(2 * n);
  js.velocity.resize(2 * n);
  js.effort.resize(2 * n);
  for (std::size_t i = 0; i < n; ++i)
  {
    const Simulator& sim = robot_->joint(i);
    const State& s = sim.state();
    js.name[i] = robot_->spec(i).name;
    js.name[n + i] = robot_->spec(i).motor_name;
    js.position[i] = s.load_position;
    js.position[n + i] = s.motor_position;
    js.velocity[i] = s.load_velocity;
    js.velocity[n + i] = s.motor_velocity;
    js.effort[i] = sim.meshTorque();
    js.effort[n + i] = sim.motorTorque();
  }
  emit(joint_pub_, joint_topic_, js);
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
  }
  catch (const std::exception& e)
  {
    fault_ = "simulation stopped at t = " + formatNumber(robot_->time()) + " s: " + e.what();
    ROS_ERROR("backlash_servo_node: %s. Paused: topics and services keep working.", fault_.c_str());
    paused_ = true;
    for (std::size_t i = 0; i < robot_->size(); ++i)
    {
      publishLimitCycle(i, robot_->time());
    }
    return false;
  }
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    const Simulator& sim = robot_->joint(i);
    Channel& ch = *channels_[i];
    if (ch.judge_from >= 0.0 && sim.state().time >= ch.judge_from)
    {
      ch.monitor->restartAt(sim.state());  // the profile has ended: judged afresh against its final value
      ch.announced = Verdict::Undecided;
      ch.judge_from = -1.0;
    }
    ch.monitor->check(sim.state(), sim.drive().winding(), ch.judge_from < 0.0 && sim.atRestForever());
    if (ch.monitor->status().verdict != ch.announced)
    {
      publishLimitCycle(i, sim.state().time);
    }
  }
  return true;
}

void RobotNode::reportStop(double t, const ros::WallTime& run_start)
{
  const double wall = (ros::WallTime::now() - run_start).toSec();
  const double cpu = static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
  for (std::size_t i = 0; i < robot_->size(); ++i)
  {
    const LimitCycleReport& st = channels_[i]->monitor->status();
    ROS_INFO(
        "backlash_servo_node: stop_after %g s reached: %s: verdict %s, error %.6g rad, period %.6g s, %llu impacts",
        config_.node.stop_after, robot_->spec(i).name.c_str(), toString(st.verdict), st.error, st.period,
        static_cast<unsigned long long>(robot_->joint(i).impactCount()));
  }
  ROS_INFO(
      "backlash_servo_node: %ld samples at %g Hz in %.3f s wall: achieved real-time factor %.1f, CPU %.3f s (%.1f %% "
      "of one core)",
      sample_index_, config_.node.publish_rate, wall, t / wall, cpu, 100.0 * cpu / wall);
}

bool RobotNode::run()
{
  const ros::WallTime start = ros::WallTime::now() + ros::WallDuration(config_.node.start_delay);
  while (ros::ok() && ros::WallTime::now() < start)
  {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
  clock_.reanchor(robot_->time());
  const ros::WallTime run_start = ros::WallTime::now();
  publishClock(robot_->time(), true);
  publishSample();
  sample_index_ = 1;
  bool reached_stop = false;
  while (ros::ok())
  {
    ros::spinOnce();
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
    const bool stop = config_.node.stop_after > 0.0 && t >= config_.node.stop_after;
    publishClock(t, stop);
    publishSample();
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
