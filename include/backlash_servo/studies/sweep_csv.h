// The sweep's CSV: header, one row per point in grid order, and what --resume keeps of an earlier file.
#pragma once

#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

#include "backlash_servo/simulation/step_response.h"
#include "backlash_servo/studies/sweep_grid.h"

namespace backlash_servo
{
/// The row of one point: its parameter columns, verdict, limit-cycle error [rad], period [s], impacts, simulated
/// time [s], settled, steady error θ_∞ − θ_R [rad] (RunSummary::steady: converged runs that came to rest; empty
/// otherwise), maxima per period, the cycle's peak to peak and centre [rad], its peak to peak in counts of the
/// encoder the loop reads and whether that is under one count (empty without a cycle or with an ideal sensor).
/// With `tracking`: then its settling band [rad], settling time [s] (empty when never settled) and steady-state RMS
/// error [rad].
std::string sweepRow(const SweepPoint& point, const RunSummary& run, const TrackingFigures* tracking = nullptr);

/// Points first … last−1 of part K of N (1-based K): contiguous blocks by grid index.
struct SweepShard
{
  std::size_t k = 1, n = 1;
  std::size_t first = 0, last = 0;
  bool whole() const { return n == 1; }
  /// The part file's first line: "# backlash_sweep part K/N: points [F, L) of T, grid HASH" (none for n = 1).
  std::string headerLine(const SweepGrid& grid) const;
};
SweepShard shardOf(std::size_t k, std::size_t n, std::size_t total);

/**
 * Joins part files of one sharded sweep (any order) into exactly the CSV a single run writes, checking that they
 * are complete parts of the same grid, none missing and none twice. Throws ConfigError naming the problem.
 */
std::string mergeParts(const std::vector<std::string>& paths);

/**
 * Rows of an earlier run that --resume keeps: the complete rows at the start of the file (a torn last line is
 * dropped), each checked to be the point of the same index in `grid`. Throws ConfigError when the file is not a
 * sweep CSV or was written for a different grid.
 */
std::vector<std::string> resumableRows(const std::string& path, const SweepGrid& grid,
                                       const SweepShard& shard = SweepShard());

/// Writes the header and rows in grid order and checks every write; flush() reports a failed write.
class SweepCsvWriter
{
 public:
  explicit SweepCsvWriter(std::ostream& out) : out_(out) {}
  void header(const SweepGrid& grid) { out_ << grid.header() << "\n"; }
  void row(const std::string& row) { out_ << row << "\n"; }
  /// Flushes; false when any write so far failed (disk full, closed pipe).
  bool flush();

 private:
  std::ostream& out_;
};

}  // namespace backlash_servo
