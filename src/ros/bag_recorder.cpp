// backlash_record: records topics into a bag without ever dropping a message. rosbag record subscribes with a fixed
// queue of 100 messages per topic, which a lockstep or as-fast-as-possible run (thousands of samples per wall
// second) overflows whenever the recorder is starved for a few milliseconds; here every subscription queue is
// unbounded and the bag is written by a dedicated thread, so a bag holds every message published after the
// recorder connected, in arrival order per topic.
// usage: backlash_record OUTPUT.bag TOPIC... (topics resolved in the node's namespace; absolute names recommended)
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <topic_tools/shape_shifter.h>
#include <unistd.h>

#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <deque>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "backlash_servo/files/safe_output.h"
#include "wall_throttle.h"

namespace
{
/// SIGTERM ends the recorder as SIGINT does: every queued message is written and the bag closed and renamed.
extern "C" void requestShutdown(int)
{
  ros::requestShutdown();
}

struct Item
{
  std::string topic;
  ros::Time time;
  topic_tools::ShapeShifter::ConstPtr msg;
  boost::shared_ptr<ros::M_string> header;
};

std::mutex g_mutex;
std::condition_variable g_ready;
std::deque<Item> g_items;
bool g_done = false;
}  // namespace

int main(int argc, char** argv)
{
  ros::init(argc, argv, "backlash_record", ros::init_options::AnonymousName);
  std::signal(SIGTERM, requestShutdown);
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() < 2)
  {
    std::fprintf(stderr, "usage: backlash_record OUTPUT.bag TOPIC...\n");
    return 2;
  }
  const std::string path = args[0];
  // Checked before recording: a device, directory or symbolic link is refused, an earlier PATH.active is kept.
  std::string active;
  try
  {
    active = backlash_servo::claimActiveFile("backlash_record", path);
  }
  catch (const std::exception& e)
  {
    std::fprintf(stderr, "backlash_record: error: %s\n", e.what());
    return 2;
  }
  rosbag::Bag bag;
  try
  {
    bag.open(active, rosbag::bagmode::Write);
  }
  catch (const rosbag::BagException& e)
  {
    ::unlink(active.c_str());
    std::fprintf(stderr, "backlash_record: cannot write '%s': %s\n", active.c_str(), e.what());
    return 2;
  }
  ros::NodeHandle nh;
  std::vector<ros::Subscriber> subs;
  for (std::size_t i = 1; i < args.size(); ++i)
  {
    const std::string topic = nh.resolveName(args[i]);
    ros::SubscribeOptions ops;
    ops.topic = topic;
    ops.queue_size = 0;  // unbounded: never drop
    ops.md5sum = ros::message_traits::md5sum<topic_tools::ShapeShifter>();
    ops.datatype = ros::message_traits::datatype<topic_tools::ShapeShifter>();
    ops.helper =
        boost::make_shared<ros::SubscriptionCallbackHelperT<const ros::MessageEvent<topic_tools::ShapeShifter const>&>>(
            [topic](const ros::MessageEvent<topic_tools::ShapeShifter const>& event) {
              std::lock_guard<std::mutex> lock(g_mutex);
              // Record time = wall time of receipt: sim time may not be valid yet (use_sim_time before the first
              // /clock) and a bag refuses times before ros::MIN_TIME; the messages carry their own sim-time stamps.
              const ros::WallTime w = ros::WallTime::now();
              g_items.push_back({topic, ros::Time(w.sec, w.nsec), event.getMessage(), event.getConnectionHeaderPtr()});
              g_ready.notify_one();
            });
    ops.transport_hints = ros::TransportHints().tcpNoDelay();
    subs.push_back(nh.subscribe(ops));
  }
  ROS_INFO("backlash_record: recording %zu topics to %s (read it back with backlash_bag_report)", subs.size(),
           path.c_str());
  std::thread writer([&]() {
    std::unique_lock<std::mutex> lock(g_mutex);
    for (;;)
    {
      g_ready.wait(lock, [] { return g_done || !g_items.empty(); });
      if (g_items.empty() && g_done)
      {
        return;
      }
      Item item = std::move(g_items.front());
      g_items.pop_front();
      lock.unlock();
      try
      {
        bag.write(item.topic, item.time, item.msg, item.header);
      }
      catch (const std::exception& e)
      {
        BACKLASH_LOG_WALL_THROTTLE(ERROR, 1.0, "backlash_record: could not write a %s message: %s", item.topic.c_str(),
                                   e.what());
      }
      lock.lock();
    }
  });
  ros::spin();  // until shutdown (SIGINT from roslaunch): every queued message is still written
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_done = true;
  }
  g_ready.notify_one();
  writer.join();
  try
  {
    bag.close();
  }
  catch (const std::exception& e)
  {
    std::fprintf(stderr, "backlash_record: error: closing '%s' failed: %s (kept as is; try rosbag reindex)\n",
                 active.c_str(), e.what());
    std::_Exit(1);  // rosbag::Bag's destructor would retry the close and throw again
  }
  try
  {
    backlash_servo::publishActiveFile("backlash_record", path);
  }
  catch (const std::exception& e)
  {
    std::fprintf(stderr, "backlash_record: error: %s\n", e.what());
    return 1;
  }
  std::fprintf(stderr, "backlash_record: wrote %s (backlash_bag_report %s); CPU %.3f s\n", path.c_str(), path.c_str(),
               static_cast<double>(std::clock()) / CLOCKS_PER_SEC);
  return 0;
}
