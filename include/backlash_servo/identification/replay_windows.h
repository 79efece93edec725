/**
 * @file replay_windows.h
 * @brief Short windows of a recording replayed by the exact simulator from the measured state: the model side of every
 *        fit that uses the simulator (the restitution, the joint fit). Each window starts from the angles recorded
 *        at its first sample k₀ (velocities by central differences, never filtered; the teeth's contact from the gap
 *        and the contact band) and runs `length` samples under the recorded torque held from sample to sample; the
 *        residuals are simulated − measured ρθ_m and θ_c [rad, at the load shaft] at k₀+1 … k₀+length, the encoders'
 *        offset put back. Why windows (an impacting joint is chaotic) and the anchors' rules:
 *        docs/identification.md, "The joint fit". No ROS dependency.
 */
#pragma once

#include <cstddef>
#include <vector>

#include "backlash_servo/identification/identification.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/model/recording.h"

namespace backlash_servo
{
class ReplayWindows
{
 public:
  /// `starts`: each window's first sample (≥ 1), `length` [samples] ≥ 1; windows must end inside the recording.
  /// Throws InvalidParameterError when they do not, or when there is no window.
  ReplayWindows(const Recording& data, const IdentificationSettings& settings, double zero_offset,
                std::vector<std::size_t> starts, std::size_t length);

  /// Windows that begin `lead` samples before the gap reaches a flank from clear of both (margin 1e-3 Δ), windows
  /// not overlapping, at most `count` spread evenly over those found (none: empty).
  static std::vector<std::size_t> beforeImpacts(const Recording& data, double gear_ratio, double zero_offset,
                                                double backlash, std::size_t length, std::size_t lead,
                                                std::size_t count);
  /// `count` windows spread evenly over the recording (fewer when it is short).
  static std::vector<std::size_t> spread(std::size_t samples, std::size_t length, std::size_t count);

  /// Corrections per window to its anchor's velocities ω_m, ω_c [rad/s]: a fit may estimate them with the
  /// parameters, since velocities differenced from the angles are an anchor's weakest part (O(h²) on smooth motion,
  /// wrong across an impact, noisy with the angles). With the teeth in contact their mean is the pair's velocity. A
  /// body at rest over the anchor's stencil (its angle within the contact band) starts at rest, uncorrected.
  static constexpr std::size_t CORRECTIONS = 2;

  /// The residuals of the joint `params` (rigid teeth or a compliant mesh without a torsional shaft; effort mode): per
  /// window, per sample, ρθ_m then θ_c
  /// (`load_only`: θ_c alone) [rad], with the anchors corrected by `corrections` (CORRECTIONS per window, or null).
  /// A window whose simulation refuses (a parameter out of range) throws.
  void residuals(const ServoParams& params, std::vector<double>* out, bool load_only = false,
                 const std::vector<double>* corrections = nullptr) const;
  /// One window's residuals (both angles, 2·length values), its anchor corrected by `corrections` (CORRECTIONS
  /// values, or null).
  void windowResiduals(const ServoParams& params, std::size_t window, const double* corrections,
                       std::vector<double>* out) const;

  /// The simulated angles of the joint `params` at every sample of the windows, NaN outside them (for charts):
  /// θ_m [rad] and θ_c [rad].
  void simulate(const ServoParams& params, std::vector<double>* motor, std::vector<double>* load,
                const std::vector<double>* corrections = nullptr) const;

  const std::vector<std::size_t>& starts() const { return starts_; }
  std::size_t length() const { return length_; }
  /// Residuals per evaluation (both angles).
  std::size_t size() const { return 2 * starts_.size() * length_; }

 private:
  struct Anchor
  {
    double time, motor_position, motor_velocity, load_position, load_velocity, gap;
    bool motor_still, load_still;  // at rest over the stencil: velocity 0, not corrected
  };
  template <class Visit>
  void replayWindow(const ServoParams& params, std::size_t window, const double* corrections, Visit visit) const;

  const Recording& data_;
  double rho_, band_, zero_offset_;
  std::vector<std::size_t> starts_;
  std::size_t length_;
  std::vector<Anchor> anchors_;
};

/**
 * The coefficient of restitution, fitted with the simulator as the model (the initial estimates for everything else,
 * static friction at the Coulomb level): windows of the recording that begin with the teeth apart shortly before an
 * impact (up to `windows` of them, spread over the recording) are replayed from the measured state — angles as
 * recorded, velocities by central differences, the gap taken relative to the estimated zero offset and clamped into
 * [0, Δ̂] — under the recorded torque, for `window` [s] each; e minimises the summed squared difference of the load
 * angle from the recording (golden-section search on [0, 1]: derivative-free, since an impact sequence is not smooth
 * in e). Re-anchoring each window on the measured state keeps the replay from parting from the recording, which an
 * impacting joint replayed open-loop over the whole recording would. Its standard error comes from the objective's
 * curvature at the minimum and the residual variance. Throws InvalidParameterError when the recording has no impact
 * to fit on.
 */
Estimate fitRestitution(const Recording& data, const IdentificationSettings& settings, const InitialEstimates& initial,
                        double window = 0.2, int windows = 40);
}  // namespace backlash_servo
