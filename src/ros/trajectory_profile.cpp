#include "trajectory_profile.h"

#include <algorithm>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
double trajectoryStart(const trajectory_msgs::JointTrajectory& msg, const ros::Time& origin, double now)
{
  const double start = msg.header.stamp.isZero() ? now : (msg.header.stamp - origin).toSec();
  if (!(start >= 0.0))
  {
    throw ConfigError("header.stamp lies before the simulation's time 0");
  }
  return start;
}

std::shared_ptr<CommandProfile> trajectoryProfile(const trajectory_msgs::JointTrajectory& msg, const std::string& name,
                                                  double start, double from)
{
  const auto joint = std::find(msg.joint_names.begin(), msg.joint_names.end(), name);
  if (joint == msg.joint_names.end())
  {
    throw ConfigError("no joint named '" + name + "' in joint_names");
  }
  const std::size_t j = static_cast<std::size_t>(joint - msg.joint_names.begin());
  if (msg.points.empty())
  {
    throw ConfigError("no points");
  }
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
  return std::make_shared<CommandProfile>(from, segments);
}
}  // namespace backlash_servo
