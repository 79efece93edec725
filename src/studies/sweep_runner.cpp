#include "backlash_servo/studies/sweep_runner.h"

#include <algorithm>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "backlash_servo/studies/sweep_csv.h"
#include "backlash_servo/studies/sweep_grid.h"

namespace backlash_servo
{
SweepRunResult runSweepPoints(std::size_t first, std::size_t last, int jobs,
                              const std::function<std::string(std::size_t)>& evaluate,
                              const std::function<void(std::size_t, const std::string&)>& on_row,
                              std::atomic<bool>& stop)
{
  SweepRunResult result;
  std::atomic<std::size_t> next{first};
  std::mutex mutex;
  std::map<std::size_t, std::string> pending;  // finished rows waiting for the ones before them
  std::size_t written = first;
  auto worker = [&]() {
    for (;;)
    {
      const std::size_t i = next++;
      if (i >= last || stop)
      {
        return;
      }
      std::string row;
      try
      {
        row = evaluate(i);
      }
      catch (const std::exception& e)
      {
        std::lock_guard<std::mutex> lock(mutex);
        if (result.failure.empty())
        {
          result.failure = "point " + std::to_string(i + 1) + ": " + e.what();
        }
        stop = true;
        return;
      }
      std::lock_guard<std::mutex> lock(mutex);
      pending.emplace(i, std::move(row));
      for (auto it = pending.begin(); it != pending.end() && it->first == written; it = pending.erase(it))
      {
        on_row(written, it->second);
        ++written;
        ++result.delivered;
      }
    }
  };
  std::vector<std::thread> threads;
  const std::size_t count = last > first ? last - first : 0;
  for (int j = 0;
       j < static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(jobs), std::max<std::size_t>(1, count)));
       ++j)
  {
    threads.emplace_back(worker);
  }
  for (auto& t : threads)
  {
    t.join();
  }
  return result;
}

}  // namespace backlash_servo

namespace backlash_servo
{
std::string evaluateSweepPoint(const SweepPoint& point, double max_duration, bool tracking)
{
  RunConfig c = point.config();
  if (max_duration > 0.0)
  {
    c.max_duration = max_duration;
  }
  c.track_energy = false;  // verdicts only
  c.tracking = tracking;
  const RunSummary r = runResponse(c);
  return sweepRow(point, r, tracking ? &r.tracking : nullptr);
}
}  // namespace backlash_servo
