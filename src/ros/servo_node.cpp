#include "servo_node.h"

#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>

#include <cstdint>

#include "backlash_servo/BacklashState.h"
#include "backlash_servo/ImpactEvent.h"
#include "backlash_servo/LimitCycleStatus.h"
#include "backlash_servo/config/run_config_loader.h"

namespace backlash_servo
{
namespace
{
/// Outgoing queue of every per-sample topic: as fast as possible (real_time_factor 0) the node publishes thousands of
/// samples per wall second, and roscpp drops the oldest queued messages of a subscriber that falls behind (a bag
/// recorder); 1e5 messages (~20 MB at most) lets recorders catch up without losing a sample.
constexpr uint32_t SAMPLE_QUEUE = 100000;

}  // namespace

ServoNode::ServoNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, const NodeConfig& config)
    : config_(config),
      clock_(nh, config_, SAMPLE_QUEUE),
      sim_(config.run.params, config.run.initial, config.run.command),
      command_(config.run.command),
      profile_(config.run.profile),
      effort_(config.motor_effort),
      judge_(config.load_joint_name, ""),
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
  clock_topic_ = clock_.publisher() ? clock_.publisher().getTopic() : std::string();
  command_topic_ = command_sub_.getTopic();
  trajectory_topic_ = trajectory_sub_.getTopic();
  effort_topic_ = effort_sub_.getTopic();
  load_torque_topic_ = load_torque_sub_.getTopic();

  // Seed the server with the loaded parameters before the callback is set (it is called once at once).
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<BacklashServoConfig>>(reconfigure_mutex_, pnh);
  last_good_ = currentConfig();
  reconfigure_->updateConfig(last_good_);
  reconfigure_->setCallback([this](BacklashServoConfig& c, uint32_t level) { onReconfigure(c, level); });

  clock_.start();
  ROS_INFO("backlash_servo_node: %s, real_time_factor %g, %g Hz, zeta %.3g, w_n %.3g rad/s, backlash %g rad, e %g",
           clock_.modeName(), config_.real_time_factor, config_.publish_rate, sim_.params().dampingRatio(),
           sim_.params().naturalFrequency(), sim_.params().backlash, sim_.params().restitution);
  for (const std::string& w : inputWarnings(config_.run))
  {
    ROS_WARN("backlash_servo_node: %s", w.c_str());
  }
}

}  // namespace backlash_servo
