/**
 * @file node_recorder.h
 * @brief The node's own bag (param `record_bag`): every message the node publishes and every input it receives,
 *        written by the node itself.
 *
 * Why inside the node: a recorder process (rosbag record, backlash_record) costs the node one socket write and one
 * wake-up of roscpp's poll thread per message — at 1 kHz in real time that, not the simulation, is most of the
 * node's CPU (docs/benchmarks.md, "Node throughput"). Here a message is serialised into a pooled buffer on the
 * publishing thread (no allocation once the pool is warm) and queued; a writer thread wakes every WAKE_PERIOD or when
 * BATCH messages wait, and writes them into the bag (rosbag's own cost per message, a few µs, is then off the sample
 * loop and, as fast as possible, on the other core). Nothing is dropped: when MAX_PENDING messages wait, the publishing
 * thread waits for the writer.
 *
 * The bag holds what backlash_record writes: absolute topic names, the node's outputs as published (joint_states,
 * backlash_state, impact, limit_cycle, encoder_states, /clock) and its inputs as received (command,
 * command_trajectory, motor_effort, load_torque — before validation: a rejected input is recorded too). Record time
 * is the wall time at the publication (sim time may not be valid yet; every message carries its sim-time stamp).
 * The file is written as PATH.active and renamed to PATH when closed (a killed node leaves PATH.active, which
 * `rosbag reindex` repairs); a failed write is logged (throttled) and counted, never thrown into the sample loop.
 */
#pragma once

#include <ros/message_traits.h>
#include <ros/serialization.h>
#include <ros/time.h>
#include <rosbag/bag.h>

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace backlash_servo
{
class NodeRecorder
{
 public:
  /// Messages waiting that wake the writer before its period [-].
  static constexpr std::size_t BATCH = 1024;
  /// Messages waiting beyond which the publishing thread waits for the writer [-] (bounds the memory: ~20 MB).
  static constexpr std::size_t MAX_PENDING = 100000;
  /// The writer's period [ms] when fewer than BATCH messages wait.
  static constexpr int WAKE_PERIOD_MS = 50;

  /// Opens PATH.active for writing and starts the writer; throws std::runtime_error naming `record_bag` and the
  /// path when it cannot.
  explicit NodeRecorder(const std::string& path);
  ~NodeRecorder() { close(); }
  NodeRecorder(const NodeRecorder&) = delete;
  NodeRecorder& operator=(const NodeRecorder&) = delete;

  /// Queues one message for the absolute topic name `topic`, stamped with the wall time now (the publishing thread
  /// only: write() and close() are called from one thread).
  template <class M>
  void write(const std::string& topic, const M& msg)
  {
    if (!open_)
    {
      return;  // closed (the node is shutting down): nothing more goes into the bag
    }
    namespace mt = ros::message_traits;
    const int id = topicId(topic, mt::datatype<M>(), mt::md5sum<M>(), mt::definition<M>());
    const uint32_t length = ros::serialization::serializationLength(msg);
    const ros::WallTime w = ros::WallTime::now();
    Item item{id, ros::Time(w.sec, w.nsec), takeBuffer()};
    item.data.resize(length);
    ros::serialization::OStream out(item.data.data(), length);
    ros::serialization::serialize(out, msg);
    push(std::move(item));
  }

  /// Writes what is queued, stops the writer, closes the bag and renames PATH.active to PATH (idempotent); logs the
  /// path and the message count.
  bool close();
  const std::string& path() const { return path_; }

 private:
  struct Topic
  {
    std::string name, datatype, md5, definition;
  };
  struct Item
  {
    int topic;
    ros::Time time;
    std::vector<uint8_t> data;  // the serialised message
  };

  /// Index of a topic (registered at its first message); topics are few, looked up by name.
  int topicId(const std::string& name, const char* datatype, const char* md5, const char* definition);
  std::vector<uint8_t> takeBuffer();
  void push(Item&& item);
  void writerLoop();

  std::string path_;
  /// Heap-held so that a bag whose close failed (disk full) can be abandoned: rosbag::Bag's destructor would retry
  /// the close and throw out of a destructor, ending the node.
  std::unique_ptr<rosbag::Bag> bag_ = std::make_unique<rosbag::Bag>();
  bool open_ = false;
  std::vector<Topic> topics_;  // read by the writer under mutex_ only when it grows (copied per batch)
  std::mutex mutex_;
  std::condition_variable wake_, drained_;
  std::vector<Item> pending_;
  std::vector<std::vector<uint8_t>> pool_;  // buffers the writer has finished with
  bool done_ = false;
  std::thread writer_;
  std::uint64_t written_ = 0, failures_ = 0;  // writer's counts (read after join)
};

}  // namespace backlash_servo
