// example_pid_controller: an external controller as users write them — a PID on the load position read from
// joint_states, publishing motor_effort — to drive backlash_servo_node in effort mode, free-running or in lockstep
// (sync: one motor_effort per joint_states). Not part of the simulator: it knows nothing of its internals.
//
//   u_k = kp e_k + I_k − kd (y_k − y_{k−1}) / Δt_k,   I_k = I_{k−1} + ki Δt_k e_k,   e_k = θ_R − y_k
//
// with y_k the load position of the k-th joint_states message, Δt_k the difference of their stamps [s] (sim time),
// θ_R from the `command` topic (initial: ~command), u saturated at ±torque_limit with conditional integration.
// Params (SI): ~kp [N·m/rad], ~ki [N·m/(rad·s)], ~kd [N·m·s/rad], ~torque_limit [N·m] (live via
// dynamic_reconfigure), ~command [rad] (default: the servo's backlash_servo/command), ~joint [name of the load joint,
// default load_joint], ~delay [0 or 1: answer each state with the output computed for the previous one — one sample of
// transport delay; 0 N·m first].
#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "backlash_servo/ExamplePidConfig.h"

namespace
{
class PidController
{
 public:
  PidController(ros::NodeHandle& nh, ros::NodeHandle& pnh)
  {
    // θ_R: ~command, else the servo's own set-point (backlash_servo/command beside this node), else 1 rad.
    pnh.param("command", command_, nh.param("backlash_servo/command", 1.0));
    pnh.param<std::string>("joint", joint_, "load_joint");
    pnh.param("delay", delay_, 0);
    if (delay_ != 0 && delay_ != 1)
    {
      ROS_FATAL("example_pid_controller: ~delay must be 0 or 1 (got %d)", delay_);
      ros::shutdown();
    }
    effort_pub_ = nh.advertise<std_msgs::Float64>("motor_effort", 100);
    state_sub_ = nh.subscribe("joint_states", 100, &PidController::onState, this, ros::TransportHints().tcpNoDelay());
    command_sub_ = nh.subscribe("command", 10, &PidController::onCommand, this);
    server_ = std::make_unique<dynamic_reconfigure::Server<backlash_servo::ExamplePidConfig>>(pnh);
    server_->setCallback([this](backlash_servo::ExamplePidConfig& c, uint32_t) {
      for (double v : {c.kp, c.ki, c.kd, c.torque_limit})
      {
        if (!std::isfinite(v) || c.torque_limit < 0.0)
        {
          ROS_ERROR(
              "example_pid_controller: refused gains (kp %g, ki %g, kd %g, torque_limit %g): must be finite, "
              "torque_limit >= 0",
              c.kp, c.ki, c.kd, c.torque_limit);
          c = gains_;
          return;
        }
      }
      gains_ = c;
    });
  }

 private:
  void onCommand(const std_msgs::Float64& msg)
  {
    if (std::isfinite(msg.data))
    {
      command_ = msg.data;
    }
  }

  void onState(const sensor_msgs::JointState& js)
  {
    const auto it = std::find(js.name.begin(), js.name.end(), joint_);
    if (it == js.name.end() || js.position.size() != js.name.size())
    {
      ROS_WARN_THROTTLE(5.0, "example_pid_controller: no joint '%s' in joint_states", joint_.c_str());
      return;
    }
    const double y = js.position[static_cast<std::size_t>(it - js.name.begin())];
    const double t = js.header.stamp.toSec();
    const double dt = first_ ? 0.0 : t - t_prev_;
    const double e = command_ - y;
    const double derivative = first_ || dt <= 0.0 ? 0.0 : gains_.kd * (y - y_prev_) / dt;
    double integral = integral_ + gains_.ki * dt * e;
    double u = gains_.kp * e + integral - derivative;
    const double limit = gains_.torque_limit;
    if (limit > 0.0 && std::fabs(u) > limit)
    {
      if (u * e > 0.0)
      {
        integral = integral_;  // conditional integration: no wind-up against the limit
        u = gains_.kp * e + integral - derivative;
      }
      u = std::min(std::max(u, -limit), limit);
    }
    integral_ = integral;
    y_prev_ = y;
    t_prev_ = t;
    first_ = false;
    std_msgs::Float64 out;
    out.data = delay_ == 1 ? pending_ : u;
    pending_ = u;
    effort_pub_.publish(out);
  }

  backlash_servo::ExamplePidConfig gains_ = backlash_servo::ExamplePidConfig::__getDefault__();
  std::unique_ptr<dynamic_reconfigure::Server<backlash_servo::ExamplePidConfig>> server_;
  ros::Publisher effort_pub_;
  ros::Subscriber state_sub_, command_sub_;
  std::string joint_;
  double command_ = 1.0;
  double integral_ = 0.0, y_prev_ = 0.0, t_prev_ = 0.0;
  double pending_ = 0.0;  // output of the previous state (delay 1)
  int delay_ = 0;
  bool first_ = true;
};
}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "example_pid_controller");
  ros::NodeHandle nh, pnh("~");
  PidController controller(nh, pnh);
  ros::spin();
  return 0;
}
