/**
 * @file response_monitor.h
 * @brief Watches a response and judges it: maxima of θ_c fed to the Poincaré-map detector (limit_cycle.h), plus the
 *        rest, held-for-ever and quiet rules, all judged against the loop's equilibrium θ_eq [rad]. The one judge
 *        used by backlash_sim, the sweep, the design tool and the node, so they all reach the same verdict. Analysis
 *        only: it reads events and states, never changes the physics. The rules: docs/validation.md, "How the
 *        limit-cycle verdict is made". No ROS dependency.
 */
#pragma once

#include <cmath>
#include <cstddef>
#include <deque>
#include <vector>

#include "backlash_servo/plant/plant.h"
#include "backlash_servo/simulation/limit_cycle.h"

namespace backlash_servo
{
struct DriveParams;

/**
 * Where the loop comes to rest under the load torque T_ext [N·m] with set-point θ_R [rad]: in contact at rest the
 * motor holds T_m = −ρ T_ext. Integral action (pid with K_i > 0, cascade with K_vi > 0) removes the offset: θ_R. A
 * proportional law: K (θ_R − θ_c) = −ρ T_ext, so θ_R + ρ T_ext / K; a cascade without integral action:
 * K_v K_p (θ_R − θ_c) = −ρ T_ext, so θ_R + ρ T_ext / (K_v K_p).
 */
double loopEquilibrium(const ServoParams& params, const DriveParams& drive, double command);

/// The shape of a sustained oscillation of the load, read from its turning points over the last pattern period.
struct CycleShape
{
  double peak_to_peak = NAN;  ///< highest minus lowest load position in the cycle [rad]; NaN: no sustained oscillation
  double centre = NAN;        ///< midpoint of the two [rad] (an offset from θ_R shows a one-sided cycle)
  double top = NAN;           ///< highest load position [rad]
  double bottom = NAN;        ///< lowest load position [rad]
};

class ResponseMonitor : public EventSink
{
 public:
  /// A quiet servo must be within this fraction of the scale of its command to count as converged.
  static constexpr double QUIET_ERROR_FRACTION = 1e-2;
  /// The quiet rule waits at least this many natural periods without a new maximum.
  static constexpr double QUIET_PERIODS = 10.0;

  /**
   * @param params the servo (ω_n [rad/s] sets the time scales, ρ the motor-velocity test)
   * @param command θ_R [rad]: errors are reported from it
   * @param equilibrium where the loop rests [rad] (loopEquilibrium): maxima and the rest rules are judged against it
   * @param start the state the response starts from (its time starts the quiet clock, its θ_c sets the scale)
   * @param sampled_drive a digital drive runs the loop: with it (or with dry friction) sustained oscillations may
   *        be quasi-periodic bands (LimitCycleDetector::allowBands); the continuous thesis servo keeps its verdicts
   */
  ResponseMonitor(const ServoParams& params, double command, double equilibrium, const State& start,
                  bool sampled_drive);

  /// Judges afresh from `state` on (a profile has ended): maxima and verdict forgotten, the same command, scale and
  /// rules; the quiet clock starts at state.time.
  void restartAt(const State& state);
  /// Turning points of the load kept for cycleShape().
  static constexpr std::size_t TURNS_KEPT = 4096;

  /// Maxima (EventType::Maximum) go to the detector; maxima and minima are kept for cycleShape(); every other event
  /// is ignored.
  void onEvent(const Event& event) override;
  bool wantsImpacts() const override { return false; }
  /**
   * The cycle's peak-to-peak amplitude and centre once the verdict is a sustained oscillation (NaN fields otherwise).
   * Between two turning points θ_c is monotone, so its extremes over a window are the extreme turning points in it;
   * the window is the last pattern period (a limit cycle), or the span of the last LimitCycleDetector::BAND_WINDOW
   * (quasi-periodic) or IRREGULAR_WINDOW (irregular) maxima when that is longer, ending at the latest turning point.
   */
  CycleShape cycleShape() const;
  /// Where the loop comes to rest [rad] (loopEquilibrium).
  double equilibrium() const { return equilibrium_; }
  /// Applies the rest and quiet rules to the state at a check time. drive_winding: the drive's integrator still
  /// moves (Drive::winding()): a joint standing still is then not converged (stick–slip hunting), neither rule applies.
  /// at_rest_forever: the joint is in a state it can never leave (Simulator::atRestForever): converged, whatever
  /// the maxima said before.
  void check(const State& state, bool drive_winding = false, bool at_rest_forever = false);

  /// Converged and the joint there: a rest rule settled it, or the load is within QUIET_ERROR_FRACTION of the scale
  /// of θ_eq now and at its latest maximum. A decay recognised on the maxima alone while the load still swings wide
  /// (a loop just inside its stability limit) is sure, but its steady error is not yet readable: a run until settled
  /// goes on until this holds (or its cap).
  bool convergedNear(const State& state) const;
  /// A maximum of the load (the state there) that contradicts a converged verdict: above the quiet band
  /// (QUIET_ERROR_FRACTION of the scale) beyond the equilibrium — the load moved again (a push, a breakaway, an
  /// external controller's integrator). False unless the verdict is converged.
  bool leavesConvergence(const State& at_maximum) const
  {
    return status().verdict == Verdict::Converged &&
           at_maximum.load_position - equilibrium_ > QUIET_ERROR_FRACTION * scale_;
  }
  const LimitCycleReport& status() const { return detector_.status(); }
  /// The positive maxima above θ_R (reported).
  const std::vector<Maximum>& maxima() const { return detector_.maxima(); }
  /// The maxima above the equilibrium, on which the verdict is judged.
  const std::vector<Maximum>& judged() const { return detector_.judged(); }
  bool settled() const { return detector_.settled(); }
  bool oscillating() const { return detector_.oscillating(); }
  double command() const { return command_; }
  /// The longest interval between successive judged maxima seen by the checks so far [s] (0 before two).
  double longestInterval() const { return longest_; }
  /// The scale max(Δ, |θ_R − θ_c(0)|) [rad] below which errors count as zero.
  double scale() const { return scale_; }

 private:
  double command_;
  double equilibrium_;  // rest position of the P law: θ_R + ρ T_ext / K [rad]
  double omega_n_;
  double rho_;
  double scale_;
  double start_time_;
  bool bands_;         // sampled drive or dry friction (LimitCycleDetector::allowBands)
  bool dry_friction_;  // no decay extrapolation (LimitCycleDetector::extrapolateDecay)
  LimitCycleDetector detector_;
  struct Turn
  {
    double time;      // [s]
    double position;  // θ_c [rad]
  };
  std::deque<Turn> turns_;  // the latest TURNS_KEPT maxima and minima of θ_c, in time order
  double longest_ = 0.0;    // longest interval between successive maxima so far [s]
  std::size_t intervals_seen_ = 0;
  bool rested_ = false;  // a rest rule (rest, held for ever, quiet) marked the convergence
};

}  // namespace backlash_servo
