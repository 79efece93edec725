// The sweep's grid: axes over any numeric parameter (by default the five chart-form axes of the 1961 study), a
// point identified by its index (last axis fastest), and the run configuration of a point.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "backlash_servo/config/key_values.h"
#include "backlash_servo/simulation/step_response.h"
#include "backlash_servo/studies/monte_carlo.h"

namespace backlash_servo
{
/// One axis: a Real parameter-table key and its values.
struct SweepAxis
{
  std::string key;
  std::vector<double> values;
};

class SweepGrid;

/// The end of a tolerance study's fingerprint: its rows are draws, not a grid's enumeration.
constexpr const char* DRAWN_SUFFIX = "-drawn";

/// One point of the grid: a value per axis.
struct SweepPoint
{
  const SweepGrid* grid = nullptr;
  std::vector<double> values;

  /// The run of this point: the grid's fixed settings plus the axis values; throws ConfigError /
  /// InvalidParameterError naming the bad key.
  RunConfig config() const;
  /// The CSV's parameter columns ("%.10g" each), as written and read back by --resume.
  std::string columns() const;
};

class SweepGrid
{
 public:
  /// The chart-form axes, in column order (always columns in the chart form, so the thesis CSV keeps its shape).
  static const std::vector<std::string>& chartAxes();
  /// Largest grid accepted (points); a bigger one is refused before anything is allocated.
  static constexpr double MAX_POINTS = 1e9;

  /// One value per chart axis: the thesis' App. D1 case.
  SweepGrid();
  /// The 1961 grid (1344 points).
  static SweepGrid thesis();

  /**
   * Axis `key` (a Real key of the servo — physical or chart form —, drive or initial section of the parameter
   * table): replaces that axis or adds it after the others. Physical-only keys (motor_inertia … gain) switch the
   * grid to the physical form, which drops the chart axes; mixing both forms throws ConfigError.
   */
  void setAxis(const std::string& key, std::vector<double> values);
  /// Settings every point shares (drive law, fixed parameters, run length); checked for the form like axes.
  void setFixed(const KeyValues& fixed);
  const std::vector<SweepAxis>& axes() const { return axes_; }
  const KeyValues& fixed() const { return fixed_; }
  /// The CSV header: the axis keys, then the result columns.
  std::string header() const;
  /// Number of points; throws std::length_error when above MAX_POINTS.
  std::size_t size() const;
  /// Point `index` in [0, size()): nested loops over the axes in column order, the last axis fastest.
  SweepPoint point(std::size_t index) const;
  /// Builds every point's run before any work: throws (one clear message) on the first that is not valid.
  void requireValidPoints() const;
  /// A fingerprint of the axes' keys and values, the fixed settings and the run signature (FNV-1a, hex): parts of
  /// one grid agree. A tolerance study's also holds its draws, N and seed, and ends in DRAWN_SUFFIX.
  std::string fingerprint() const;
  /// What else changes a row besides the settings (the run-length cap, a profile file's content), as text; hashed
  /// into the fingerprint when not empty.
  void setRunSignature(const std::string& signature) { signature_ = signature; }
  /// A key drawn from a distribution (a tolerance study): its axis column holds each point's draw.
  void addDraw(const Distribution& d);
  /// The tolerance study's size: `n` points, drawn under `seed` (drawValue; point i's joint is the same in any shard
  /// or rerun). With draws, size() refuses a study without n, and any other axis with more than one value.
  void setMonteCarlo(std::size_t n, std::uint64_t seed);
  const std::vector<Distribution>& draws() const { return draws_; }
  /// Rows also carry the tracking figures (trackingColumns(); a sampled replay of each run, replayTracking).
  void setTracking(bool on) { tracking_ = on; }
  bool tracking() const { return tracking_; }

 private:
  /// Refuses a mix of the two forms; the physical form drops the chart axes left at their defaults.
  void requireOneForm();
  /// size() of a tolerance study (setMonteCarlo), after its checks.
  std::size_t monteCarloSize() const;

  std::vector<SweepAxis> axes_;
  std::vector<bool> given_;  // axis set explicitly (a chart axis left at its default is dropped by the physical form)
  KeyValues fixed_;
  std::string signature_;
  bool tracking_ = false;
  std::vector<Distribution> draws_;
  std::size_t draw_count_ = 0;  // --monte-carlo N (0: none)
  std::uint64_t seed_ = 1;
};

/// The result columns of every sweep CSV, after the axis columns (the last columns of SweepGrid::header()).
const std::string& resultColumns();
/// The tracking columns that follow them with --tracking: settling_band [rad], settling_time [s] (empty when the run
/// never settles into the band), steady_rms_error [rad] (TrackingFigures).
const std::string& trackingColumns();

/// Values of an axis flag: a list "0.1,0.2", a range "start:stop:count" or "log:start:stop:count". Throws
/// ConfigError naming the flag.
std::vector<double> parseAxis(const std::string& flag, const std::string& text);
/**
 * The axes and shared settings of `keys` added to *grid (backlash_sweep's flags and --config, the Python API's
 * dict): a numeric key given a list or a range (or a chart axis given one value) is an axis, in parameter-table
 * order; every other key is a setting every point shares. `max_duration` is the caller's (a run option).
 */
void addSweepKeys(const KeyValues& keys, SweepGrid* grid);

/// Whether `text` is an axis (a list or a range) rather than one value (a distribution is neither).
bool isAxisText(const std::string& text);

}  // namespace backlash_servo
