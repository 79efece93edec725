#include "node_recorder.h"

#include <ros/console.h>
#include <topic_tools/shape_shifter.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "backlash_servo/files/safe_output.h"
#include "wall_throttle.h"

namespace backlash_servo
{
NodeRecorder::NodeRecorder(const std::string& path) : path_(path)
{
  // Refuses a device, directory or symbolic link as the target and never overwrites an earlier PATH.active.
  const std::string active = claimActiveFile("record_bag", path_);
  try
  {
    bag_->open(active, rosbag::bagmode::Write);
  }
  catch (const rosbag::BagException& e)
  {
    ::unlink(active.c_str());
    throw std::runtime_error("record_bag: cannot write '" + active + "': " + e.what());
  }
  open_ = true;
  pending_.reserve(BATCH);
  writer_ = std::thread([this] { writerLoop(); });
  ROS_INFO("backlash_servo_node: recording its topics to %s (read it back with backlash_bag_report)", path_.c_str());
}

int NodeRecorder::topicId(const std::string& name, const char* datatype, const char* md5, const char* definition)
{
  for (std::size_t i = 0; i < topics_.size(); ++i)
  {
    if (topics_[i].name == name)
    {
      return static_cast<int>(i);
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);  // the writer reads topics_ under the lock
  topics_.push_back({name, datatype, md5, definition});
  return static_cast<int>(topics_.size() - 1);
}

std::vector<uint8_t> NodeRecorder::takeBuffer()
{
  std::lock_guard<std::mutex> lock(mutex_);
  if (pool_.empty())
  {
    return {};
  }
  std::vector<uint8_t> b = std::move(pool_.back());
  pool_.pop_back();
  return b;
}

void NodeRecorder::push(Item&& item)
{
  std::unique_lock<std::mutex> lock(mutex_);
  drained_.wait(lock, [this] { return pending_.size() < MAX_PENDING; });  // never drop: wait for the writer
  pending_.push_back(std::move(item));
  if (pending_.size() == BATCH)
  {
    wake_.notify_one();
  }
}

void NodeRecorder::writerLoop()
{
  std::vector<Item> batch;
  std::vector<Topic> topics;
  std::vector<topic_tools::ShapeShifter> shapes;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;)
  {
    wake_.wait_for(lock, std::chrono::milliseconds(WAKE_PERIOD_MS),
                   [this] { return done_ || pending_.size() >= BATCH; });
    if (pending_.empty())
    {
      if (done_)
      {
        return;
      }
      continue;
    }
    batch.swap(pending_);
    if (topics.size() != topics_.size())
    {
      topics = topics_;
    }
    drained_.notify_all();
    lock.unlock();
    for (std::size_t i = shapes.size(); i < topics.size(); ++i)
    {
      shapes.emplace_back();
      shapes.back().morph(topics[i].md5, topics[i].datatype, topics[i].definition, "");
    }
    for (Item& item : batch)
    {
      try
      {
        topic_tools::ShapeShifter& shape = shapes[item.topic];
        ros::serialization::IStream in(item.data.data(), static_cast<uint32_t>(item.data.size()));
        shape.read(in);
        bag_->write(topics[item.topic].name, item.time, shape);
        ++written_;
      }
      catch (const std::exception& e)
      {
        ++failures_;
        BACKLASH_LOG_WALL_THROTTLE(
            ERROR, 1.0,
            "backlash_servo_node: record_bag: could not write a %s message to %s.active (%llu so "
            "far): %s",
            topics[item.topic].name.c_str(), path_.c_str(), static_cast<unsigned long long>(failures_), e.what());
      }
    }
    lock.lock();
    for (Item& item : batch)
    {
      pool_.push_back(std::move(item.data));
    }
    batch.clear();
  }
}

bool NodeRecorder::close()
{
  if (!open_)
  {
    return true;
  }
  open_ = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    done_ = true;
  }
  wake_.notify_one();
  writer_.join();
  try
  {
    bag_->close();
  }
  catch (const std::exception& e)
  {
    (void)bag_.release();  // abandoned, never destroyed: its destructor would throw the same error again
    ROS_ERROR("backlash_servo_node: record_bag: closing %s.active failed: %s (left as is; try rosbag reindex)",
              path_.c_str(), e.what());
    return false;
  }
  try
  {
    publishActiveFile("record_bag", path_);
  }
  catch (const std::exception& e)
  {
    ROS_ERROR("backlash_servo_node: %s", e.what());
    return false;
  }
  ROS_INFO("backlash_servo_node: wrote %s: %llu messages%s (backlash_bag_report %s)", path_.c_str(),
           static_cast<unsigned long long>(written_), failures_ > 0 ? ", SOME WRITES FAILED" : "", path_.c_str());
  return failures_ == 0;
}

}  // namespace backlash_servo
