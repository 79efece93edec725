/**
 * @file joint_judge.h
 * @brief One joint's verdict as the node publishes it (limit_cycle, /diagnostics): the core's ResponseMonitor with
 *        backlash_sim's rest and quiet rules, the tracking figures since the judgement began (every sample), the
 *        steady answer once converged, and why the verdict is (still) undecided. The single joint's node has one,
 *        the arm's node one per joint; the judge itself is the core's.
 *
 * In effort mode the external controller's law is unknown: the joint is judged against its `command` itself, and only
 * a joint held for ever (dry friction) has a steady answer. Units SI: angles rad, times s of sim time.
 */
#pragma once

#include <diagnostic_updater/DiagnosticStatusWrapper.h>

#include <memory>
#include <string>

#include "backlash_servo/LimitCycleStatus.h"
#include "backlash_servo/simulation/response_monitor.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/steady_state.h"
#include "backlash_servo/simulation/step_response.h"
#include "backlash_servo/simulation/tracking_metrics.h"

namespace backlash_servo
{
class JointJudge
{
 public:
  /// `joint`: the name its messages carry; `log_prefix`: what its log lines start with ("" for the single joint,
  /// "<joint>: " for an arm's).
  JointJudge(std::string joint, std::string log_prefix);

  /**
   * Judges afresh from the joint's state now, against the set-point `command` [rad] (a profile's final value).
   * `run`: the joint's configuration (its drive's settings); `profile`: the position profile θ_R follows, or null
   * (its end is where the verdict starts); `sample_period`: the node's sample period [s]. A non-empty `reason` (what
   * restarted it) becomes the status's reason, with the time, until a verdict is reached.
   */
  void restart(const Simulator& sim, const RunConfig& run, double command,
               const std::shared_ptr<const CommandProfile>& profile, double sample_period, const std::string& reason);
  /// The sample just taken, at θ_R = `reference` [rad] now (a profile's value). True when the verdict differs from
  /// the one last published (publish a status).
  bool sample(const Simulator& sim, double reference);
  /**
   * A plant event. Maxima and minima go to the judge; true when a new maximum should be published. When that maximum
   * leaves a converged verdict (the load moved again), `withdrawn` receives why: the caller says so and restarts.
   */
  bool onEvent(const Event& e, std::string* withdrawn);
  /// The simulation stopped at the joint's state (a core error `what`): the verdict is undecided with that reason.
  void fault(const Simulator& sim, const std::string& what);

  /**
   * The status at `sim_time`: the judge's fields, the steady answer, the tracking figures, the command and the
   * reason; `healthy`: no fault holds the simulation; `maximum`: a new maximum caused it (logged); `diverged`: the
   * motion ran away. Logs a change of verdict and remembers it as published.
   */
  LimitCycleStatus status(const Simulator& sim, const RunConfig& run, double sim_time, bool healthy, bool maximum,
                          bool diverged = false);
  /// The verdict's figures under backlash_sim's names and units, for /diagnostics.
  void diagnose(const Simulator& sim, const RunConfig& run, diagnostic_updater::DiagnosticStatusWrapper* status);

  const ResponseMonitor& monitor() const { return *monitor_; }
  /// The set-point judged against [rad].
  double command() const { return command_; }

 private:
  /// The tracking figures now (settling into the band, steady RMS error), as backlash_sim defines them.
  TrackingFigures tracking(const Simulator& sim) const;
  /// The steady answer of this judgement, found once when it turns converged; none before.
  const SteadyAnswer& steady(const Simulator& sim, const RunConfig& run);
  /// A cycle's size in counts of the encoder the loop reads and in arcmin (the joint's settings now).
  CycleResolution resolution(const Simulator& sim, const RunConfig& run, const CycleShape& cycle) const;

  std::string joint_, log_prefix_;
  double sample_period_ = 0.0;
  double command_ = 0.0;
  std::unique_ptr<ResponseMonitor> monitor_;
  std::unique_ptr<TrackingMetrics> tracking_;
  SteadyAnswer steady_;
  Verdict announced_ = Verdict::Undecided;
  double converged_at_ = 0.0;  // sim time of the latest converged verdict published [s]
  double judge_from_ = -1.0;   // a profile's end [s]: the verdict starts afresh there (-1: none pending)
  std::string reason_;         // why the verdict is (still) undecided
};

}  // namespace backlash_servo
