// A progress bar with elapsed time and ETA on stderr, for long runs on a terminal.
#pragma once

#include <chrono>
#include <cstddef>

namespace backlash_servo
{
class Progress
{
 public:
  /// Shown only when `enabled` (e.g. stderr is a terminal).
  explicit Progress(bool enabled);
  /// done of total units finished.
  void update(std::size_t done, std::size_t total);
  /// Ends the bar's line.
  void finish();
  /// Wall time since construction [s].
  double elapsed() const;

 private:
  bool enabled_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace backlash_servo
