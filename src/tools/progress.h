// A progress bar with elapsed time and ETA on stderr, for long runs on a terminal (sweeps, long single runs).
#pragma once

#include <chrono>
#include <cstddef>

namespace backlash_servo
{
class Progress
{
 public:
  /// Shown only when `enabled` (e.g. stderr is a terminal) and once `delay` [s] of wall time have passed (short
  /// runs stay quiet).
  explicit Progress(bool enabled, double delay = 0.0);
  /// done of total units finished.
  void update(std::size_t done, std::size_t total);
  /// A fraction in [0, 1] finished.
  void update(double fraction);
  /// Ends the bar's line.
  void finish();
  /// Wall time since construction [s].
  double elapsed() const;

 private:
  void draw(double fraction, const char* counts);

  bool enabled_;
  double delay_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace backlash_servo
