// backlash_servo_node: loads ~params (exits with a message naming the key if they are bad) and runs the servo.
#include "robot_node.h"
#include "servo_node.h"

#include <clocale>
#include <csignal>
#include <cstring>
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
  // rosconsole passes messages through log4cxx, which converts them with the process locale: under the "C" locale of
  // a service or a container every non-ASCII character (ζ, ω, ρ, Δ, ², ·) of a message became '?' on the console
  // and in /rosout. The messages are UTF-8: read them as such whatever the environment says.
  const char* ctype = std::setlocale(LC_CTYPE, "");
  if (ctype == nullptr || (std::strstr(ctype, "UTF-8") == nullptr && std::strstr(ctype, "utf8") == nullptr))
  {
    std::setlocale(LC_CTYPE, "C.UTF-8");
  }
  ros::init(argc, argv, "backlash_servo_node");
  std::signal(SIGTERM, requestShutdown);
  ros::NodeHandle nh, pnh("~");
  try
  {
    // An arm (~joints given): every joint of the robot description in one node.
    const backlash_servo::PrivateParams given = backlash_servo::readPrivateParams(pnh);
    if (given.arm)
    {
      const backlash_servo::RobotNodeConfig config = backlash_servo::loadRobotNodeConfig(nh, given);
      backlash_servo::RobotNode node(nh, pnh, config);
      return node.run() ? 0 : 1;
    }
  }
  catch (const std::exception& e)
  {
    ROS_FATAL("backlash_servo_node: bad parameter: %s", e.what());
    return 1;
  }
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
