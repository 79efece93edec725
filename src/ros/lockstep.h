/**
 * @file lockstep.h
 * @brief Lockstep (sync: true) as both nodes keep it: before sim time starts, wait for a controller; after each
 *        published state, serve callbacks until its one answer arrives (or sync_timeout of wall time passes). The
 *        input callbacks say answered(); what counts as an answer is the node's (motor_effort, a command, a
 *        trajectory).
 */
#pragma once

#include <functional>
#include <string>

namespace backlash_servo
{
class Lockstep
{
 public:
  /// Serves callbacks until `connected()` (a subscriber of the states and a publisher of `answer_topic`), then one
  /// second more for the controller's own subscription to settle; says what it waits for every 10 s.
  void waitForController(const std::function<bool()>& connected, const std::string& answer_topic) const;
  /**
   * After a state at sim time `sim_time` [s] is published: serves callbacks until an input callback calls
   * answered(), or `timeout` [s of wall time] passes (0: never) (a late answer: counted and warned about, naming
   * `answer`). While `held()` (paused, a fault) the wait goes on without a deadline.
   */
  void awaitAnswer(const std::function<bool()>& held, const std::string& answer, double sim_time, double timeout);
  /// From an input callback: the answer to the state just published (nothing when none is awaited).
  void answered() { answered_ = answered_ || awaiting_; }
  /// Answers that came after their timeout.
  long late() const { return late_; }

 private:
  bool awaiting_ = false;
  bool answered_ = false;
  long late_ = 0;
};

}  // namespace backlash_servo
