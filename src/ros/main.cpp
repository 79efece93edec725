// backlash_servo_node: loads ~params (exits with a message naming the key if they are bad) and runs the servo.
#include "servo_node.h"

#include <csignal>
#include <memory>
#include <stdexcept>

namespace
{
/// SIGTERM (docker stop, systemd, kill) ends the node as SIGINT does: the sample loop stops at a step boundary and
/// the node's own bag is written out and closed (roscpp handles only SIGINT; ros::requestShutdown only sets a flag).
extern "C" void requestShutdown(int)
{
  ros::requestShutdown();
}
}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "backlash_servo_node");
  std::signal(SIGTERM, requestShutdown);
  ros::NodeHandle nh, pnh("~");
  backlash_servo::NodeConfig config;
  try
  {
    config = backlash_servo::loadNodeConfig(pnh);
  }
  catch (const std::exception& e)
  {
    ROS_FATAL("backlash_servo_node: bad parameter: %s", e.what());
    return 1;
  }
  std::unique_ptr<backlash_servo::ServoNode> node;
  try
  {
    node = std::make_unique<backlash_servo::ServoNode>(nh, pnh, config);
  }
  catch (const std::runtime_error& e)  // e.g. record_bag cannot be written
  {
    ROS_FATAL("backlash_servo_node: %s", e.what());
    return 1;
  }
  return node->run() ? 0 : 1;  // 1: the recording asked for (record_bag) failed, as logged
}
