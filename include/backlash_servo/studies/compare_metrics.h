// The workbench's metrics of one run (backlash_compare): tracking, limit cycle, impacts, torque. SI units.
#pragma once

#include <cmath>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "backlash_servo/config/compare_config.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
/// Metrics of one strategy's run; NaN = does not apply (written as null / empty).
struct CompareMetrics
{
  std::string name;
  std::string verdict;
  double limit_cycle_error = NAN;  ///< [rad] (sustained oscillations only)
  double period = NAN;             ///< [s] of the whole pattern (sustained oscillations only)
  double peak_to_peak = NAN;       ///< the load's peak-to-peak amplitude in the cycle [rad] (idem)
  double cycle_centre = NAN;       ///< midpoint of the cycle's highest and lowest load position [rad] (idem)
  /// peak_to_peak in counts of the encoder the loop reads (idem; NaN with an ideal sensor): under 1, a hunt the loop
  /// cannot see
  double peak_to_peak_counts = NAN;
  double steady_error = NAN;              ///< θ_∞ − θ_R [rad] (RunSummary::steady; converged only)
  double settling_time = NAN;             ///< last time |e| > the settling band (settlingBand), after the profile [s]
  double rms_error = NAN;                 ///< √(mean e²) over the run [rad], e = θ_R − θ_c
  double steady_rms_error = NAN;          ///< √(mean e²) after the transient: from the settling time on [rad]
  double max_error = NAN;                 ///< max |e| after the profile has ended [rad]
  double overshoot = NAN;                 ///< beyond the final reference, in the direction of the last move [rad]
  double impacts_per_second = NAN;        ///< tooth impacts [1/s]; a compliant mesh: contact phases begun [1/s]
  double impact_energy_per_second = NAN;  ///< kinetic energy lost in impacts [W]; a compliant mesh: its losses [W]
  double peak_torque = NAN;               ///< max |T_m| [N·m]
  double rms_torque = NAN;                ///< √(mean T_m²) [N·m]
  double settling_band = NAN;             ///< the band of settling_time and steady_rms_error [rad] (not a column)
  /// An `undecided` run, run on from the start until its verdict settles (capped by max_duration when set, else at
  /// most RUN_ON_FACTOR × the duration): the verdict it reaches and the simulated time it needed [s] — how long
  /// `duration` must be to decide it. Empty / NaN otherwise.
  std::string run_on_verdict;
  double run_on_time = NAN;
  /// why the run-on ended: RunSummary::stopped_by ("settled", "max_duration", …) or "wall_time" (its budget of wall
  /// time, RUN_ON_WALL_FACTOR; run_on_time is then where it stood)
  std::string run_on_stopped_by;
};

/// One sampled trajectory point of a run (for charts).
struct CompareSample
{
  double time, reference, load_position, motor_position, motor_torque;
};

/// How much longer than its duration an undecided run is run on, unless max_duration says how far [-].
constexpr double RUN_ON_FACTOR = 10.0;
/// A run-on stops after this many times the wall time of the strategy's own run, and at least RUN_ON_LEAST_WALL [s].
constexpr double RUN_ON_WALL_FACTOR = 20.0;
constexpr double RUN_ON_LEAST_WALL = 2.0;

/// Most trajectory points kept per strategy for the chart (every k-th sample beyond that; the metrics use all).
constexpr long kMaxChartSamples = 20000;

/// Runs one strategy (its config carries the profile and duration), sampling at sample_rate [Hz]; the chart's
/// trajectory (if asked for) holds at most kMaxChartSamples + 1 of the samples, evenly strided. A run the duration
/// leaves undecided is run again until settled (the metrics stay those of the duration; see run_on_verdict).
CompareMetrics runStrategy(const std::string& name, const RunConfig& config, double sample_rate,
                           std::vector<CompareSample>* trajectory);

/// Every strategy's run, in the strategies' order: its metrics, its chart trajectory (when asked for) and its error
/// message (empty when it ran).
struct StrategyRuns
{
  std::vector<CompareMetrics> metrics;
  std::vector<std::vector<CompareSample>> trajectories;
  std::vector<std::string> errors;
};

/// Runs the strategies on `jobs` threads (runStrategy each); on_done(done, total) after each, under a lock.
StrategyRuns runStrategies(const std::vector<CompareStrategy>& strategies, double sample_rate, int jobs,
                           bool trajectories, const std::function<void(std::size_t, std::size_t)>& on_done);

/// Column names of the metrics, in the order of CompareMetrics (the CSV header and the JSON keys).
const std::vector<std::string>& metricNames();
/// The numeric metrics in that order (from limit_cycle_error on).
std::vector<double> metricValues(const CompareMetrics& m);

}  // namespace backlash_servo
