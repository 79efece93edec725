// Runs the points of a sweep on a pool of threads and hands their rows over in grid order.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <string>

namespace backlash_servo
{
struct SweepRunResult
{
  std::size_t delivered = 0;  ///< rows handed to on_row (a prefix of the points asked for)
  std::string failure;        ///< first error ("point N: message"), empty if none
};

/**
 * Evaluates points first … last−1 with `jobs` threads. Rows are delivered to on_row (under a lock) strictly in
 * index order as soon as the prefix is complete, so an interrupted run leaves a valid prefix. Stops early when
 * `stop` becomes true or evaluate throws (the error is returned, not rethrown).
 */
struct SweepPoint;
/// One point's CSV row: its run until settled (capped at max_duration [s] when > 0), verdicts only; with `tracking`
/// also its tracking figures (a sampled replay of the run, replayTracking).
std::string evaluateSweepPoint(const SweepPoint& point, double max_duration, bool tracking = false);

SweepRunResult runSweepPoints(std::size_t first, std::size_t last, int jobs,
                              const std::function<std::string(std::size_t)>& evaluate,
                              const std::function<void(std::size_t, const std::string&)>& on_row,
                              std::atomic<bool>& stop);

}  // namespace backlash_servo
