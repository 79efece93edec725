// The sweep's CSV: header, one row per point in grid order, and what --resume keeps of an earlier file.
#pragma once

#include <cstddef>
#include <ostream>
#include <string>
#include <vector>

#include "backlash_servo/step_response.h"
#include "sweep_grid.h"

namespace backlash_servo
{
extern const char* const SWEEP_CSV_HEADER;

/// The row of one point: its parameter columns, verdict, limit-cycle error [rad], period [s], impacts, simulated
/// time [s], settled.
std::string sweepRow(const SweepPoint& point, const RunSummary& run);

/**
 * Rows of an earlier run that --resume keeps: the complete rows at the start of the file (a torn last line is
 * dropped), each checked to be the point of the same index in `grid`. Throws ConfigError when the file is not a
 * sweep CSV or was written for a different grid.
 */
std::vector<std::string> resumableRows(const std::string& path, const SweepGrid& grid);

/// Writes the header and rows in grid order and checks every write; flush() reports a failed write.
class SweepCsvWriter
{
 public:
  explicit SweepCsvWriter(std::ostream& out) : out_(out) {}
  void header() { out_ << SWEEP_CSV_HEADER << "\n"; }
  void row(const std::string& row) { out_ << row << "\n"; }
  /// Flushes; false when any write so far failed (disk full, closed pipe).
  bool flush();

 private:
  std::ostream& out_;
};

}  // namespace backlash_servo
