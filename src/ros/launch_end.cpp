#include "launch_end.h"

#include <ros/ros.h>

#include <unistd.h>

#include <csignal>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace backlash_servo
{
namespace
{
/// The file name of the program in `cmdline` (argv NUL-separated): argv[0], or argv[1] when argv[0] is an
/// interpreter (roslaunch is a Python script: "/usr/bin/python3 /usr/bin/roslaunch …").
std::string programName(const std::string& cmdline)
{
  std::vector<std::string> argv;
  std::string::size_type from = 0;
  while (from < cmdline.size() && argv.size() < 2)
  {
    const std::string::size_type end = cmdline.find('\0', from);
    argv.push_back(cmdline.substr(from, end == std::string::npos ? std::string::npos : end - from));
    from = end == std::string::npos ? cmdline.size() : end + 1;
  }
  const auto base = [](const std::string& path) { return path.substr(path.rfind('/') + 1); };
  if (argv.empty())
  {
    return "";
  }
  const std::string first = base(argv[0]);
  return first.rfind("python", 0) == 0 && argv.size() > 1 ? base(argv[1]) : first;
}
}  // namespace

bool endParentLaunch()
{
  const pid_t parent = getppid();
  std::ifstream in("/proc/" + std::to_string(parent) + "/cmdline", std::ios::binary);
  const std::string cmdline((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (parent <= 1 || programName(cmdline) != "roslaunch")
  {
    return false;
  }
  return kill(parent, SIGINT) == 0;
}

void endParentLaunchAndWait()
{
  if (endParentLaunch())
  {
    // roslaunch stops every node of the launch, this one with SIGINT (SIGTERM after 15 s): exit then, so that the
    // end is roslaunch's ordinary shutdown and not a required node's death.
    const ros::WallTime asked = ros::WallTime::now();
    while (ros::ok() && (ros::WallTime::now() - asked).toSec() < 20.0)
    {
      ros::WallDuration(0.01).sleep();
    }
  }
}
}  // namespace backlash_servo
