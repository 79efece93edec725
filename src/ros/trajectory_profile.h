// command_trajectory → a set-point profile: shared by the single joint's node and the arm's.
#pragma once

#include <ros/time.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <memory>
#include <string>

#include "backlash_servo/drive/command_profile.h"

namespace backlash_servo
{
/// Where a trajectory starts [s of sim time]: its header's stamp, or `now` for a zero stamp (the ROS convention).
/// Throws ConfigError for a stamp before sim time 0 (`origin` is the ROS time of sim time 0).
double trajectoryStart(const trajectory_msgs::JointTrajectory& msg, const ros::Time& origin, double now);

/// Joint `name`'s points of `msg` as a profile from `from` [rad] at `start` [s]: ramps between points, a step where
/// time_from_start repeats. Throws ConfigError naming the problem ("no joint named …", "point 3: …").
std::shared_ptr<CommandProfile> trajectoryProfile(const trajectory_msgs::JointTrajectory& msg, const std::string& name,
                                                  double start, double from);
}  // namespace backlash_servo
