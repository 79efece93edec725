/**
 * @file response_monitor.h
 * @brief Watches a response and judges it: maxima of θ_c fed to the Poincaré-map detector (limit_cycle.h), plus the
 *        rest and quiet rules. The one judge used by backlash_sim, the sweep, the design tool and the node, so they
 *        all reach the same verdict. Analysis only: it reads events and states, never changes the physics.
 *        No ROS dependency.
 *
 * Rules applied at each check (a time the caller chooses: a natural period, an output sample):
 * - **rest**: |θ_c − θ_eq|, |ω_c|/ω_n and |ρ ω_m|/ω_n all within LimitCycleDetector::ZERO_FRACTION of the scale
 *   max(Δ, |θ_R − θ_c(0)|, |θ_eq − θ_R|) → converged, where θ_eq = θ_R + ρ T_ext / K is where a load torque shifts
 *   the P law's rest (the steady error);
 * - **quiet**: no new positive maximum for max(10 natural periods, 5 × the longest interval between maxima so far)
 *   while |θ_c − θ_eq| ≤ QUIET_ERROR_FRACTION × scale → converged (the motor creeping across the backlash under a
 *   vanishing torque is not an oscillation).
 */
#pragma once

#include <cstddef>
#include <vector>

#include "backlash_servo/limit_cycle.h"
#include "backlash_servo/plant.h"

namespace backlash_servo
{
class ResponseMonitor : public EventSink
{
 public:
  /// A quiet servo must be within this fraction of the scale of its command to count as converged.
  static constexpr double QUIET_ERROR_FRACTION = 1e-2;
  /// The quiet rule waits at least this many natural periods without a new maximum.
  static constexpr double QUIET_PERIODS = 10.0;

  /**
   * @param params the servo (ω_n [rad/s] sets the time scales, ρ the motor-velocity test)
   * @param command θ_R [rad] the response is judged against
   * @param start the state the response starts from (its time starts the quiet clock, its θ_c sets the scale)
   * @param sampled_drive a digital drive runs the loop: with it (or with dry friction) sustained oscillations may
   *        be quasi-periodic bands (LimitCycleDetector::allowBands); the continuous thesis servo keeps its verdicts
   */
  ResponseMonitor(const ServoParams& params, double command, const State& start, bool sampled_drive = false);

  /// Judges afresh from `state` on (a profile has ended): maxima and verdict forgotten, the same command, scale and
  /// rules; the quiet clock starts at state.time.
  void restartAt(const State& state);
  /// Maxima (EventType::Maximum) go to the detector; every other event is ignored.
  void onEvent(const Event& event) override;
  bool wantsImpacts() const override { return false; }
  /// Where the P law comes to rest: θ_R + ρ T_ext / K [rad].
  double equilibrium() const { return equilibrium_; }
  /// Applies the rest and quiet rules to the state at a check time. drive_winding: the drive's integrator still
  /// moves (Drive::winding()): a joint standing still is then not converged (stick–slip hunting), neither rule applies.
  void check(const State& state, bool drive_winding = false);

  const LimitCycleReport& status() const { return detector_.status(); }
  const std::vector<Maximum>& maxima() const { return detector_.maxima(); }
  bool settled() const { return detector_.settled(); }
  bool oscillating() const { return detector_.oscillating(); }
  double command() const { return detector_.command(); }
  /// The scale max(Δ, |θ_R − θ_c(0)|) [rad] below which errors count as zero.
  double scale() const { return scale_; }

 private:
  double command_;
  double equilibrium_;  // rest position of the P law: θ_R + ρ T_ext / K [rad]
  double omega_n_;
  double rho_;
  double scale_;
  double start_time_;
  bool bands_;  // sampled drive or dry friction (LimitCycleDetector::allowBands)
  LimitCycleDetector detector_;
  double longest_ = 0.0;  // longest interval between successive maxima so far [s]
  std::size_t intervals_seen_ = 0;
};

}  // namespace backlash_servo
