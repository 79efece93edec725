/**
 * @file robot_node.h
 * @brief backlash_servo_node for an arm (~joints given): every joint of the robot description in one simulated
 *        time (RobotSimulator: each joint's plant and drive, gravity and inertia following the pose), one
 *        /joint_states, one /clock. A thin adapter: the physics and the judges are the core's.
 *
 * Topics (in the node's namespace): joint_states (every load joint by its URDF name, every motor by its actuator's
 * name; effort: the motor's torque [N·m], the mesh torque on the load [N·m]), encoder_states (the quantised readings
 * under the same names), impact (with the joint's name), <joint>/limit_cycle (latched) and <joint>/backlash_state per
 * joint, <joint>/command (std_msgs/Float64, rad), command_trajectory (any subset of the joints; the others hold their
 * set-points), /diagnostics (one status per joint). Services ~pause, ~resume.
 * Position mode: each joint's own drive. Effort mode (control_mode: effort): motor_effort (sensor_msgs/JointState,
 * efforts [N·m] by joint or motor name; joints not named keep theirs) sets the motors' torques; <joint>/command is
 * then the set-point each joint is judged against. Lockstep (sync): one answer (motor_effort, or in position mode a
 * command or trajectory) per published state before the arm advances.
 * dynamic_reconfigure per joint at ~<joint> (one group per joint in rqt): its plant and its drive's settings live;
 * what the arm sets (its gravity, its inertia), the node's own settings and what would move the joint's sample grid
 * (rate, law, feedback, compensation) are refused there, saying why.
 */
#pragma once

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <boost/thread/recursive_mutex.hpp>
#include <memory>
#include <string>
#include <vector>

#include "backlash_servo/BacklashServoConfig.h"
#include "backlash_servo/robot/robot_simulator.h"
#include "joint_judge.h"
#include "lockstep.h"
#include "node_config.h"
#include "node_recorder.h"
#include "sim_clock.h"

namespace backlash_servo
{
/// What an arm's node reads: the node's own settings (rates, clock, stop) and the joints.
struct RobotNodeConfig
{
  NodeConfig node;  ///< publish_rate, real_time_factor, publish_clock, stop_after, … (the Node keys)
  std::shared_ptr<const ArmModel> arm;  ///< the robot description's arm (parsed once); null = independent joints
  std::vector<RobotJoint> joints;       ///< each joint's run (robot_config.h)
};

/// From ~joints, the top-level keys, and the robot description: the `robot_description` parameter (the node's
/// namespace, as robot_state_publisher reads it) or the file ~urdf. Throws ConfigError naming the key.
RobotNodeConfig loadRobotNodeConfig(const ros::NodeHandle& nh, const PrivateParams& given);

class RobotNode
{
 public:
  RobotNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, const RobotNodeConfig& config);
  /// Runs the sample loop until shutdown (or stop_after); false when the recording (record_bag) failed.
  bool run();

 private:
  /// One joint's judge and its ROS ends: events in, status out.
  struct Channel : EventSink
  {
    RobotNode* node = nullptr;
    std::size_t index = 0;
    std::unique_ptr<JointJudge> judge;
    double command = 0.0;           // the set-point θ_R judged against in effort mode [rad]
    double last_effort_time = 0.0;  // effort mode: sim time of the joint's last motor_effort [s]
    bool effort_timed_out = false;  // effort mode: its torque was dropped for want of one
    ros::Publisher limit_cycle_pub, state_pub;
    std::string limit_cycle_topic, state_topic, command_topic;
    ros::Subscriber command_sub;
    boost::recursive_mutex reconfigure_mutex;
    std::unique_ptr<dynamic_reconfigure::Server<BacklashServoConfig>> reconfigure;
    BacklashServoConfig last_good;  // the values in force, what rqt shows
    void onEvent(const Event& e) override;
  };

  void onCommand(std::size_t joint, const std_msgs::Float64& msg);
  /// Effort mode: the motors named (by joint or motor name) take their efforts [N·m]; refused whole (ROS_ERROR) if a
  /// name is unknown, the arrays differ in length or an effort is out of range.
  void onEffort(const sensor_msgs::JointState& msg);
  /// The joint whose URDF name or motor name is `name`; -1 when none.
  int motorOrJoint(const std::string& name) const;
  /// The points of every joint named in the message become that joint's profile; refused whole (ROS_ERROR) if any
  /// joint is unknown or its points are bad.
  void onTrajectory(const trajectory_msgs::JointTrajectory& msg);
  /// A live change of joint i's keys (its group ~<joint>): applied at this step boundary, or refused whole (the
  /// reply holds the values in force, ROS_ERROR says why).
  void onReconfigure(std::size_t joint, BacklashServoConfig& c);
  bool onPause(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onResume(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  /// Judges joint i afresh from now on (a new command); `reason` is published at once with verdict undecided.
  void restartMonitor(std::size_t i, const std::string& reason);
  void publishLimitCycle(std::size_t i, double sim_time, bool maximum);
  bool effortMode() const { return config_.node.control_mode == ControlMode::Effort; }
  /// Joint i's set-point [rad]: effort mode the one judged against; else its profile's final value or its command.
  double setPoint(std::size_t i) const;
  /// Joint i's θ_R now [rad] (a profile's value at this instant).
  double reference(std::size_t i) const;
  void publishSample();
  /// encoder_states: joint i's readings at a sample of its digital drive (position mode), kept for flushEncoders.
  void publishEncoders(std::size_t i, const State& s, const Drive& drive);
  /// Publishes the readings kept during a step in time order, one message per instant with every joint sampled then.
  void flushEncoders();
  /// Waits start_delay (and in lockstep for a controller) before sim time starts.
  void awaitStart();
  /// Lockstep: serves callbacks until the answer to the state just published arrives or sync_timeout passes.
  void awaitAnswer();
  /// Effort mode: a joint without motor_effort for effort_timeout s of sim time has its torque dropped to 0.
  void checkEffortTimeouts();
  /// One joint's /diagnostics status: running/paused/fault, sim time, impacts, its load now and its verdict.
  void diagnose(std::size_t i, diagnostic_updater::DiagnosticStatusWrapper& status);
  void publishClock(double t, bool force);
  /// Advances every joint to t [s] and judges each; false after a simulation error (the node pauses, says why).
  bool stepTo(double t);
  void reportStop(double t, const ros::WallTime& run_start);
  ros::Time stamp(double sim_time) const { return clock_.stamp(sim_time); }
  template <class M>
  void emit(const ros::Publisher& pub, const std::string& topic, const M& msg)
  {
    pub.publish(msg);
    record(topic, msg);
  }
  /// Writes a message (an output, or an input as received) to the node's bag, if it records.
  template <class M>
  void record(const std::string& topic, const M& msg)
  {
    if (recorder_)
    {
      recorder_->write(topic, msg);
    }
  }

  RobotNodeConfig config_;
  SimClock clock_;
  std::unique_ptr<RobotSimulator> robot_;
  std::vector<std::unique_ptr<Channel>> channels_;
  std::vector<EventSink*> sinks_;
  std::unique_ptr<NodeRecorder> recorder_;
  ros::Publisher joint_pub_, impact_pub_, encoder_pub_;
  std::string joint_topic_, impact_topic_, encoder_topic_, clock_topic_, trajectory_topic_, effort_topic_;
  ros::Subscriber trajectory_sub_, effort_sub_;
  ros::ServiceServer pause_srv_, resume_srv_;
  // The per-sample messages, kept so that a sample allocates nothing of its own; their names (every load joint in
  // URDF order, then every motor) set once.
  sensor_msgs::JointState joint_msg_, encoder_msg_;
  /// A digital drive's encoder readings at one of its samples [rad]: the load's, the motor's (motor shaft).
  struct Reading
  {
    double time;
    std::size_t joint;
    double load, motor;
  };
  std::vector<Reading> readings_;  // taken during the current step, not yet published
  diagnostic_updater::Updater diagnostics_;
  ros::WallTime last_diagnostics_;
  long sample_index_ = 0;
  Lockstep lockstep_;  // sync: the answer awaited for each published state, the late ones counted
  bool paused_ = false;
  std::string fault_;  // the simulation error holding the arm; empty while healthy
};

}  // namespace backlash_servo
