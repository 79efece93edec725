/**
 * @file tracking_metrics.h
 * @brief How well a sampled response tracks its reference, e = θ_R − θ_c [rad] at each sample: the settling time [s]
 *        into a band (NaN when the samples end outside it, or a sustained oscillation leaves it), the RMS error over
 *        the run and after the transient [rad], the largest error, the overshoot beyond the final reference [rad] and
 *        the motor torque [N·m]. Analysis only, from samples of the exact run: shared by backlash_sim,
 *        backlash_design, backlash_compare and the Python module so that they report the same figures. Definitions:
 *        docs/workbench.md. No ROS dependency.
 */
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

namespace backlash_servo
{
/// Tracking figures of one run; NaN = does not apply.
struct TrackingFigures
{
  double settling_time = NAN;     ///< [s] (see the file comment)
  double rms_error = NAN;         ///< √(mean e²) over every sample [rad]
  double steady_rms_error = NAN;  ///< √(mean e²) after the transient [rad]
  double max_error = NAN;         ///< max |e| after the reference stopped moving [rad]
  double overshoot = NAN;         ///< beyond the final reference, in the direction of its last move [rad]
  double peak_torque = NAN;       ///< max |T_m| [N·m]
  double rms_torque = NAN;        ///< √(mean T_m²) [N·m]
  double band = NAN;              ///< the settling band [rad]
};

/// Accumulates samples of a response and gives its TrackingFigures.
class TrackingMetrics
{
 public:
  /**
   * @param band the settling band [rad] (settlingBand())
   * @param reference_end t_f [s]: when the reference stops moving
   * @param final_reference θ_R from t_f on [rad]
   * @param direction +1 or −1: the sign of the reference's last move (for the overshoot)
   */
  TrackingMetrics(double band, double reference_end, double final_reference, double direction);

  /// One sample at `time` [s]: reference θ_R [rad], load position θ_c [rad], motor torque T_m [N·m].
  void add(double time, double reference, double load_position, double motor_torque);
  /// The figures of the samples so far; end_time [s] is the run's last time, dt [s] the sample period. `leaves_band`:
  /// the caller knows the response keeps leaving the band (a sustained oscillation reaching beyond it): never settled,
  /// whatever the last samples show (samples can end inside a swing that will leave again).
  TrackingFigures figures(double end_time, double dt, bool leaves_band = false) const;
  /// The settling band [rad].
  double band() const { return band_; }

 private:
  double band_, reference_end_, final_reference_, direction_;
  double sum_e2_ = 0.0, sum_t2_ = 0.0, peak_torque_ = 0.0, max_after_ = 0.0, overshoot_ = 0.0;
  double last_outside_ = NAN;
  long count_ = 0;
  double since_sum_ = 0.0;  // Σ e² from the last sample outside the band on (from t_f when none) [rad²]
  long since_count_ = 0;
  /// Samples from t_f on for the second-half window of a response that never settles: (time of the first [s],
  /// Σ e² [rad²], count). One entry per sample up to MAX_ENTRIES; beyond, neighbours are merged in pairs, so memory
  /// stays bounded on an endless run (the node) and the window's start is resolved to one entry.
  struct Entry
  {
    double time, sum;
    long count;
  };
  static constexpr std::size_t MAX_ENTRIES = std::size_t(1) << 18;
  std::vector<Entry> after_;
  long entry_size_ = 1;  // samples per entry now
  double first_after_ = NAN, last_time_ = NAN;
};

}  // namespace backlash_servo
