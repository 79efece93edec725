#include "sim_clock.h"

#include <rosgraph_msgs/Clock.h>

namespace backlash_servo
{
void serveCallbacksFor(double seconds)
{
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < end)
  {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
  }
}

SimClock::SimClock(ros::NodeHandle& nh, const NodeConfig& config, uint32_t queue)
    : config_(config),
      mode_(config.publish_clock ? Mode::Publisher : (ros::Time::isSimTime() ? Mode::External : Mode::RealTime))
{
  if (mode_ == Mode::Publisher)
  {
    pub_ = nh.advertise<rosgraph_msgs::Clock>("/clock", queue);
    if (!ros::Time::isSimTime())
    {
      ROS_WARN(
          "backlash_servo_node: publish_clock is true but /use_sim_time is false: other nodes will not follow "
          "the simulator's clock (launch with publish_clock:=true, or set use_sim_time:=true)");
    }
  }
}

const char* SimClock::modeName() const
{
  const char* names[] = {"real time", "publishing /clock", "following /clock"};
  return names[static_cast<int>(mode_)];
}

void SimClock::start()
{
  if (mode_ == Mode::External)
  {
    ros::Time::waitForValid();
    origin_ = ros::Time::now();
  }
  else if (mode_ == Mode::Publisher)
  {
    origin_ = ros::Time(config_.start_time);  // sim time 0 is ROS time start_time (default 0, as in Gazebo)
  }
  else
  {
    origin_ = ros::Time::now();
  }
}

void SimClock::reanchor(double sim_now)
{
  wall_anchor_ = ros::WallTime::now();
  sim_anchor_ = sim_now;
}

bool SimClock::due(double t)
{
  if (mode_ == Mode::External)
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

bool SimClock::clockDue(double t, bool force)
{
  if (mode_ != Mode::Publisher)
  {
    return false;
  }
  const double rate = config_.clock_publish_rate;
  const bool every_sample = config_.sync || rate == 0.0 ||
                            (config_.real_time_factor > 0.0 && config_.publish_rate * config_.real_time_factor <= rate);
  const ros::WallTime now = ros::WallTime::now();
  if (!force && !every_sample && (now - last_clock_wall_).toSec() < 1.0 / rate)
  {
    skipped_ = t;
    return false;
  }
  last_clock_wall_ = now;
  skipped_ = -1.0;
  return true;
}
}  // namespace backlash_servo
