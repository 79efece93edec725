// Log throttling by wall-clock time. ROS_*_THROTTLE measure ros::Time, which is sim time under use_sim_time: at
// real_time_factor 0 (thousands of sim seconds per wall second) a "once per second" message would print dozens of
// times per wall second.
#pragma once

#include <ros/console.h>
#include <ros/time.h>

/// Logs at most once per `period` wall seconds from this call site (level: DEBUG, INFO, WARN, ERROR).
#define BACKLASH_LOG_WALL_THROTTLE(level, period, ...)           \
  do                                                             \
  {                                                              \
    static double backlash_last_log_ = -1e300;                   \
    const double backlash_now_ = ::ros::WallTime::now().toSec(); \
    if (backlash_now_ - backlash_last_log_ >= (period))          \
    {                                                            \
      backlash_last_log_ = backlash_now_;                        \
      ROS_##level(__VA_ARGS__);                                  \
    }                                                            \
  } while (false)
