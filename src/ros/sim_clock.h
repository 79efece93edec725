/**
 * @file sim_clock.h
 * @brief The node's sim time against ROS time: which clock leads (the wall clock scaled by real_time_factor, the
 *        node publishing /clock, or an external /clock), when a sample is due, and when /clock is published (at most
 *        at clock_publish_rate of wall time unless every sample must have one). Shared by the joint's node and the
 *        arm's.
 */
#pragma once

#include <ros/ros.h>

#include "node_config.h"

namespace backlash_servo
{
/// Serves callbacks for `seconds` of wall time (or until shutdown): a start delay, a drain before exit.
void serveCallbacksFor(double seconds);

class SimClock
{
 public:
  enum class Mode
  {
    RealTime,   ///< follow the wall clock scaled by real_time_factor
    Publisher,  ///< the node publishes /clock
    External    ///< follow /clock from elsewhere
  };

  /// The mode from the settings (publish_clock → Publisher; /use_sim_time → External; else RealTime); advertises
  /// /clock when publishing it.
  SimClock(ros::NodeHandle& nh, const NodeConfig& config, uint32_t queue);
  Mode mode() const { return mode_; }
  /// "real time", "publishing /clock" or "following /clock".
  const char* modeName() const;
  /// Fixes ROS time of sim time 0: start_time when publishing /clock, the first valid /clock when following one
  /// (waits for it), now in real time.
  void start();
  ros::Time stamp(double sim_time) const { return origin_ + ros::Duration(sim_time); }
  const ros::Time& origin() const { return origin_; }
  /// The wall clock's pacing starts again from sim time `sim_now` [s] (after a pause or a change of pace).
  void reanchor(double sim_now);
  /// Whether the sample at sim time t [s] is due; false: not yet (after sleeping a slice, so callbacks stay served).
  bool due(double t);
  /// Whether /clock at sim time t [s] goes out now: every sample in lockstep, when `force`d, or when the samples come
  /// no faster than clock_publish_rate of wall time; else at most at that rate. A skipped time is remembered.
  bool clockDue(double t, bool force);
  /// Sim time of the newest sample whose /clock was skipped [s]; < 0 when none is pending.
  double skipped() const { return skipped_; }
  const ros::Publisher& publisher() const { return pub_; }

 private:
  const NodeConfig& config_;
  Mode mode_;
  ros::Publisher pub_;
  ros::Time origin_;
  ros::WallTime wall_anchor_;  // wall time at which the sim was at sim_anchor_
  double sim_anchor_ = 0.0;
  ros::WallTime last_clock_wall_;
  double skipped_ = -1.0;
};
}  // namespace backlash_servo
