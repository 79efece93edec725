#include "lockstep.h"

#include <ros/callback_queue.h>
#include <ros/ros.h>

namespace backlash_servo
{
void Lockstep::waitForController(const std::function<bool()>& connected, const std::string& answer_topic) const
{
  // Lockstep needs its controller connected before the first state goes out (a state nobody answers would stall the
  // run until sync_timeout).
  ROS_INFO(
      "backlash_servo_node: lockstep: waiting for a controller (subscribing joint_states or encoder_states, "
      "publishing %s)",
      answer_topic.c_str());
  ros::WallTime said = ros::WallTime::now();
  while (ros::ok() && !connected())
  {
    ros::spinOnce();
    ros::WallDuration(0.01).sleep();
    if ((ros::WallTime::now() - said).toSec() > 10.0)
    {
      ROS_INFO("backlash_servo_node: lockstep: still waiting for a controller");
      said = ros::WallTime::now();
    }
  }
  ros::WallDuration(1.0).sleep();
  ros::spinOnce();
}

void Lockstep::awaitAnswer(const std::function<bool()>& held, const std::string& answer, double sim_time,
                           double timeout)
{
  answered_ = false;
  awaiting_ = true;
  const ros::WallTime start = ros::WallTime::now();
  while (ros::ok() && !answered_)
  {
    ros::getGlobalCallbackQueue()->callAvailable(ros::WallDuration(0.001));
    if (held())
    {
      continue;  // a paused or faulted node waits with its controller
    }
    if (timeout > 0.0 && (ros::WallTime::now() - start).toSec() >= timeout)
    {
      ++late_;
      ROS_WARN(
          "backlash_servo_node: lockstep: no %s for t = %.6f s within sync_timeout %g s; advancing on the last input "
          "(this run is no longer reproducible)",
          answer.c_str(), sim_time, timeout);
      break;
    }
  }
  awaiting_ = false;
}

}  // namespace backlash_servo
