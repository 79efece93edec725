// backlash_servo_node: loads ~params (exits with a message naming the key if they are bad) and runs the servo.
#include "servo_node.h"

int main(int argc, char** argv)
{
  ros::init(argc, argv, "backlash_servo_node");
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
  backlash_servo::ServoNode node(nh, pnh, config);
  node.run();
  return 0;
}
