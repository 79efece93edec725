// The sample loop and its clock: when a sample is due, the step and its judgement, lockstep answers, the stop.
#include "servo_node.h"

#include <ros/callback_queue.h>
#include <rosgraph_msgs/Clock.h>
#include <algorithm>
#include <ctime>
#include "launch_end.h"

namespace backlash_servo
{
void ServoNode::awaitStart()
{
  serveCallbacksFor(config_.start_delay);  // recorders and monitors subscribe before sim time starts
  if (config_.sync)
  {
    // A subscriber of joint_states or encoder_states and a publisher of the answer topic.
    const ros::Subscriber& answer = config_.control_mode == ControlMode::Effort ? effort_sub_ : command_sub_;
    lockstep_.waitForController(
        [&] {
          return (joint_pub_.getNumSubscribers() > 0 || encoder_pub_.getNumSubscribers() > 0) &&
                 answer.getNumPublishers() > 0;
        },
        answer.getTopic());
  }
}

void ServoNode::publishClock(double t, bool force)
{
  if (clock_.clockDue(t, force))
  {
    rosgraph_msgs::Clock clock;
    clock.clock = stamp(t);
    emit(clock_.publisher(), clock_topic_, clock);
    ++published_;
  }
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
  const double now = sim_.state().time;
  const double reference = profile_ && sim_.controlMode() == ControlMode::Position ? profile_->at(now) : command_;
  if (judge_.sample(sim_, reference))
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
             lockstep_.late());
  }
  const double wall = (ros::WallTime::now() - run_start).toSec();
  const double cpu = static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
  ROS_INFO("backlash_servo_node: stop_after %g s reached: verdict %s, error %.6g rad, period %.6g s, %llu impacts",
           config_.stop_after, toString(judge_.monitor().status().verdict), judge_.monitor().status().error,
           judge_.monitor().status().period, static_cast<unsigned long long>(sim_.impactCount()));
  ROS_INFO(
      "backlash_servo_node: %ld samples at %g Hz in %.3f s wall: achieved real-time factor %.1f, "
      "CPU %.3f s (%.1f %% of one core)",
      sample_index_, config_.publish_rate, wall, t / wall, cpu, 100.0 * cpu / wall);
  drainBeforeExit(wall);
}

void ServoNode::endLaunch(bool reached_stop)
{
  // Every input served so far is in the bag (the drain above serves the last ones).
  if (reached_stop && config_.stop_launch)
  {
    endParentLaunchAndWait();
  }
}

bool ServoNode::run()
{
  awaitStart();
  clock_.reanchor(sim_.state().time);
  const ros::WallTime run_start = ros::WallTime::now();
  publishClock(0.0, true);
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
      if (clock_.skipped() >= 0.0)
      {
        publishClock(clock_.skipped(), true);  // a paused graph sees the time the node stands at
      }
      ros::WallDuration(0.005).sleep();
      clock_.reanchor(sim_.state().time);
      continue;
    }
    const double t = sample_base_ + static_cast<double>(sample_index_) / config_.publish_rate;
    if (!clock_.due(t))
    {
      continue;
    }
    if (!stepTo(t))
    {
      continue;
    }
    checkEffortTimeout();
    const bool stop = config_.stop_after > 0.0 && t >= config_.stop_after;
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
  judge_.fault(sim_, what);
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
  if (drain > 0.5)
  {
    ROS_INFO("backlash_servo_node: %.1f s for subscribers (recorders) to receive the %ld messages still queued", drain,
             published_);
  }
  serveCallbacksFor(std::max(drain, 0.2));
}

void ServoNode::awaitAnswer()
{
  if (config_.sync)
  {
    lockstep_.awaitAnswer([this] { return paused_ || !fault_.empty(); },
                          sim_.controlMode() == ControlMode::Effort ? "motor_effort" : "command", sim_.state().time,
                          config_.sync_timeout);
  }
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
}  // namespace backlash_servo
