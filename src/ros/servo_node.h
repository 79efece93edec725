/**
 * @file servo_node.h
 * @brief backlash_servo_node: the simulated servo joint in a live ROS graph. A thin adapter around Simulator —
 *        all physics (event location, impacts, verdict) stays in the core.
 *
 * Time: the simulator advances sample by sample (publish_rate, in sim time); impacts and maxima between samples are
 * located exactly by the core and published with their exact stamps. The sample loop is paced by the wall clock
 * (real_time_factor), runs free (publish_clock with real_time_factor 0), or follows an external /clock.
 *
 * The class's parts, one file each: construction (servo_node.cpp), the sample loop and its clock
 * (servo_node_clock.cpp), its inputs (servo_node_inputs.cpp), its outputs (servo_node_outputs.cpp) and live
 * parameters (servo_node_parameters.cpp).
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
#include <cstdint>
#include <memory>

#include "backlash_servo/BacklashServoConfig.h"
#include "backlash_servo/simulation/simulator.h"
#include "joint_judge.h"
#include "lockstep.h"
#include "node_config.h"
#include "node_recorder.h"
#include "sim_clock.h"

namespace backlash_servo
{
class ServoNode : public EventSink
{
 public:
  ServoNode(ros::NodeHandle& nh, ros::NodeHandle& pnh, const NodeConfig& config);
  /// Runs the sample loop until shutdown (or stop_after); false when the recording (record_bag) failed (a message, the
  /// close or the rename).
  bool run();

  /// Core events (called during Simulator::advanceTo): impacts and maxima are published here.
  void onEvent(const Event& event) override;

 private:
  // The sample loop's stages (run()).
  /// Waits start_delay (and in lockstep for a controller) before sim time starts.
  void awaitStart();
  /// /clock at sim time t [s] when the node is the clock: every sample in lockstep, when `force`d, or when the
  /// samples come no faster than clock_publish_rate of wall time; else at most at that rate (the rest skipped).
  void publishClock(double t, bool force);
  /// Advances to t [s] and judges the state (verdict, tracking); false after a fault (the node pauses).
  bool stepTo(double t);
  /// The figures at stop_after: verdict, lockstep misses, achieved real-time factor and CPU.
  void reportStop(double t, const ros::WallTime& run_start);
  /// With stop_launch: ends the parent launch and waits for roslaunch's SIGINT.
  void endLaunch(bool reached_stop);

  void onCommand(const std_msgs::Float64& msg);
  /// command_trajectory: the load joint's points → a profile of ramps (steps where time_from_start repeats),
  /// starting from the set-point in force (the continuous law: not with dry friction). Bad messages: ROS_ERROR,
  /// dropped.
  void onTrajectory(const trajectory_msgs::JointTrajectory& msg);
  void onEffort(const std_msgs::Float64& msg);
  /// External load torque T_ext [N·m] from now on (a disturbance input); validated, reflected in reconfigure.
  void onLoadTorque(const std_msgs::Float64& msg);
  /// Position mode with the configured law: the continuous P law, or the YAML's digital drive (fresh state).
  void applyPositionDrive();
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onPause(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onResume(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  void onReconfigure(BacklashServoConfig& config, uint32_t level);

  /// Waits (serving callbacks) until the sample at sim time t may be computed; false on shutdown.
  bool waitFor(double t);
  void publishSample();
  /// Lockstep: after a state is published, serves callbacks until its answer (motor_effort in effort mode, command
  /// in position mode) arrives or sync_timeout passes. No-op unless sync.
  void awaitAnswer();
  /// Effort mode: drops the torque to 0 (once, with a warning) after effort_timeout s of sim time without a message.
  void checkEffortTimeout();
  /// At stop_after: lets subscribers (bag recorders) receive what is still queued before the process exits.
  void drainBeforeExit(double wall);
  /// encoder_states: what a digital drive's controller read at its sample (quantised motor and load angles).
  void publishEncoders(const State& s, const Drive& drive);
  /// encoder_states at the state's instant: motor reading on the motor shaft and load reading [rad].
  void publishEncoderReadings(const State& s, double motor, double load);
  /// joint_states / encoder_states carry the configured motor and load joint names, and joint_states of a compliant
  /// joint also the gear and shaft-twist names (set only when they differ).
  void setJointNames(sensor_msgs::JointState* js, bool compliant) const;
  /// /diagnostics through diagnostic_updater, every second of wall time (publishDiagnostics forces an update).
  void publishDiagnostics();
  /// The "simulation" task: OK while running, ERROR with the fault while a core error holds the simulation; values
  /// sim time, impacts, verdict, cycle error/period, impact rate, real-time factor achieved, late lockstep answers.
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);
  /// A core error at sim time t: logged with the parameters, the simulation paused until ~reset or good parameters.
  /// Pauses on a simulation error; diverged: the motion ran away (published as the verdict `diverged`).
  void enterFault(const std::string& what, bool diverged = false);
  /// Publishes the monitor's status on limit_cycle (latched) and logs it; `maximum`: a new maximum caused it.
  void publishLimitCycle(double sim_time, bool maximum, bool diverged = false);
  /// A fresh monitor from the current state and command (after a command step, a reset, a mode switch).
  /// Judges afresh from now on (a new command, trajectory, reset, mode or a live change of a plant or drive
  /// parameter); `reason` says what restarted it and /limit_cycle is published at once with verdict undecided.
  void restartMonitor(const std::string& reason = "");
  ros::Time stamp(double sim_time) const { return clock_.stamp(sim_time); }
  /// Publishes an output and writes it to the node's bag (record_bag) under its resolved topic name.
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
  BacklashServoConfig currentConfig() const;

  NodeConfig config_;
  SimClock clock_;  // when samples are due, /clock
  Simulator sim_;
  double command_;                                 // θ_R [rad] (a profile's final value), kept also in effort mode
  std::shared_ptr<const CommandProfile> profile_;  // θ_R(t) in sim time (YAML `profile`, command_trajectory) or null
  double effort_;                                  // effort-mode torque [N·m]
  JointJudge judge_;             // the verdict, as backlash_sim's judge gives it, with tracking and steady figures
  bool fault_diverged_ = false;  // the fault is a runaway motion: only ~reset resumes

  std::unique_ptr<NodeRecorder> recorder_;  // the node's own bag (record_bag), or null
  ros::Publisher joint_pub_, impact_pub_, state_pub_, limit_cycle_pub_, encoder_pub_;
  std::string joint_topic_, impact_topic_, state_topic_, limit_cycle_topic_, encoder_topic_, clock_topic_;
  std::string command_topic_, trajectory_topic_, effort_topic_, load_torque_topic_;
  // The per-sample messages, kept so that a sample allocates nothing of its own (names and arrays are reused).
  sensor_msgs::JointState joint_msg_, encoder_msg_;
  ros::Subscriber command_sub_, effort_sub_, load_torque_sub_, trajectory_sub_;
  ros::ServiceServer reset_srv_, pause_srv_, resume_srv_;
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<BacklashServoConfig>> reconfigure_;
  BacklashServoConfig last_good_;
  std::string refused_;        ///< the last refused reconfigure (key, value, reason) until the next accepted one
  bool mirror_stale_ = false;  ///< a topic changed a live value that last_good_ and dynamic_reconfigure do not show
  /// Brings last_good_ and the dynamic_reconfigure parameters up to date (called once per wall second).
  void refreshReconfigureMirror();

  double sample_base_ = 0.0;  // sim time of sample 0 of the current schedule [s]
  long sample_index_ = 0;     // index of the next sample
  Lockstep lockstep_;         // sync: the answer awaited for each published state, the late ones counted
  long published_ = 0;        // per-sample messages published (for the drain at exit)
  // State at the previous /diagnostics (rates over the interval).
  ros::WallTime diag_wall_;
  double diag_sim_ = -1.0;
  std::uint64_t diag_impacts_ = 0;
  // Effort timeout: sim time of the last motor_effort [s]; the torque was dropped for want of one.
  double last_effort_time_ = 0.0;
  bool effort_timed_out_ = false;
  bool paused_ = false;
  std::string fault_;  // the core error holding the simulation; empty while healthy
  diagnostic_updater::Updater diagnostics_;
  ros::WallTime last_diagnostics_;
};

}  // namespace backlash_servo
