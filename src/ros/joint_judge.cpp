// One joint's verdict as published: the core's judge, the tracking figures, the steady answer and the reason.
#include "joint_judge.h"

#include <ros/console.h>

#include <cmath>
#include <utility>

#include "backlash_servo/model/params.h"
#include "status_messages.h"

namespace backlash_servo
{
JointJudge::JointJudge(std::string joint, std::string log_prefix)
    : joint_(std::move(joint)), log_prefix_(std::move(log_prefix))
{}

void JointJudge::restart(const Simulator& sim, const RunConfig& run, double command,
                         const std::shared_ptr<const CommandProfile>& profile, double sample_period,
                         const std::string& reason)
{
  sample_period_ = sample_period;
  const bool effort = sim.controlMode() == ControlMode::Effort;
  const State& now = sim.state();
  command_ = command;
  // A profile is judged from its end on (a hunt around an intermediate set-point is not the final verdict).
  const bool following = profile && !effort;
  judge_from_ = following && profile->endTime() > now.time ? profile->endTime() : -1.0;
  // Effort mode is fed by an external, usually digital, controller whose law is unknown: its rest is judged against
  // `command` itself, and its cycles may be quasi-periodic bands as a digital drive's are.
  const double equilibrium = effort ? command : loopEquilibrium(sim.params(), run.drive, command);
  monitor_ =
      std::make_unique<ResponseMonitor>(sim.params(), command, equilibrium, now, sim.drive().sampled() || effort);
  // The tracking figures start afresh with the judgement: the reference's last move is this step or the profile.
  RunConfig tracked = run;
  tracked.params = sim.params();
  tracked.initial = now;
  tracked.command = command;
  tracked.profile = following ? profile : nullptr;
  tracking_ = std::make_unique<TrackingMetrics>(trackingOf(tracked, sample_period_, INFINITY));
  announced_ = Verdict::Undecided;
  steady_ = SteadyAnswer();
  reason_ = reason.empty() ? "" : reason + " at t = " + formatNumber(now.time) + " s: judging afresh";
}

bool JointJudge::sample(const Simulator& sim, double reference)
{
  const State& s = sim.state();
  if (judge_from_ >= 0.0 && s.time >= judge_from_)
  {
    monitor_->restartAt(s);  // the profile has ended: judged afresh against its final value
    announced_ = Verdict::Undecided;
    judge_from_ = -1.0;
  }
  // Rest and quiet rules, as backlash_sim applies them; in effort mode against `command` too (the external
  // controller's integrator is not visible: its stick–slip phases count as rest only once quiet for long).
  monitor_->check(s, sim.drive().winding(), judge_from_ < 0.0 && sim.atRestForever());
  tracking_->add(s.time, reference, s.load_position, sim.motorTorque());
  return monitor_->status().verdict != announced_;
}

bool JointJudge::onEvent(const Event& e, std::string* withdrawn)
{
  if (e.type == EventType::Minimum)
  {
    monitor_->onEvent(e);  // the cycle's lowest points (peak to peak, centre)
    return false;
  }
  if (e.type != EventType::Maximum)
  {
    return false;
  }
  const std::size_t before = monitor_->maxima().size();
  monitor_->onEvent(e);
  if (monitor_->maxima().size() == before)
  {
    return false;  // not above the command
  }
  // A maximum above the quiet band after a converged verdict: the load moved again (an external controller's
  // integrator, a breakaway, a push) — the verdict no longer describes the joint.
  if (announced_ == Verdict::Converged && monitor_->leavesConvergence(e.state))
  {
    *withdrawn = "the converged verdict of t = " + formatNumber(converged_at_) +
                 " s is withdrawn: the load moved again (maximum at t = " + formatNumber(e.state.time) + " s, " +
                 formatNumber(e.state.load_position - monitor_->equilibrium()) + " rad beyond where it rested)";
    return false;
  }
  return true;
}

void JointJudge::fault(const Simulator& sim, const std::string& what)
{
  monitor_->restartAt(sim.state());
  announced_ = Verdict::Undecided;
  reason_ = "simulation stopped at t = " + formatNumber(sim.state().time) + " s: " + what;
}

TrackingFigures JointJudge::tracking(const Simulator& sim) const
{
  return tracking_->figures(sim.state().time, sample_period_,
                            cycleLeavesBand(monitor_->status(), monitor_->cycleShape(), command_, tracking_->band()));
}

const SteadyAnswer& JointJudge::steady(const Simulator& sim, const RunConfig& run)
{
  if (monitor_->status().verdict != Verdict::Converged)
  {
    steady_ = SteadyAnswer();
    return steady_;
  }
  const bool effort = sim.controlMode() == ControlMode::Effort;
  if (steady_.basis == SteadyBasis::None || (effort && steady_.basis == SteadyBasis::Unsettled))
  {
    if (!effort || sim.atRestForever())  // (held for ever: steadyAnswer's first answer, whoever drives)
    {
      steady_ = steadyAnswer(sim, run.drive, command_, monitor_->equilibrium(), monitor_->scale());
    }
    else
    {
      steady_.basis = SteadyBasis::Unsettled;
      steady_.note = "effort mode: the external controller's law is unknown";
    }
  }
  return steady_;
}

CycleResolution JointJudge::resolution(const Simulator& sim, const RunConfig& run, const CycleShape& cycle) const
{
  RunConfig read = run;
  read.params = sim.params();
  return cycleResolution(cycle, loopCount(read));
}

LimitCycleStatus JointJudge::status(const Simulator& sim, const RunConfig& run, double sim_time, bool healthy,
                                    bool maximum, bool diverged)
{
  const LimitCycleReport& st = monitor_->status();
  LimitCycleStatus m;
  m.sim_time = sim_time;
  fillVerdict(*monitor_, resolution(sim, run, monitor_->cycleShape()), &m);
  if (diverged)
  {
    m.verdict = toString(Verdict::Diverged);
  }
  m.joint = joint_;
  const SteadyAnswer& steady_answer = steady(sim, run);
  m.steady_error = steady_answer.error;
  m.steady_basis = steady_answer.basis == SteadyBasis::None ? "" : steadyBasisName(steady_answer.basis);
  const TrackingFigures figures = tracking(sim);
  m.settling_band = figures.band;
  m.settling_time = figures.settling_time;
  m.steady_rms_error = figures.steady_rms_error;
  m.command = command_;
  if (st.verdict != Verdict::Undecided && healthy)
  {
    reason_.clear();  // a verdict reached: nothing pending to explain
  }
  // A convergence is never withdrawn silently (the load moved again: an external controller's integrator, a joint
  // breaking away): the message says which verdict it replaces and since when.
  if (announced_ == Verdict::Converged && st.verdict != Verdict::Converged && healthy)
  {
    reason_ = "the converged verdict of t = " + formatNumber(converged_at_) +
              " s is withdrawn: the load moved again (maximum at t = " +
              formatNumber(monitor_->maxima().empty() ? sim_time : monitor_->maxima().back().time) + " s)";
    ROS_WARN("backlash_servo_node: %s%s", log_prefix_.c_str(), reason_.c_str());
  }
  m.reason = reason_;
  if (maximum)
  {
    // (Debug: a digital drive's hunt has hundreds of maxima a second, and a log line costs more than its sample.)
    ROS_DEBUG("%smaximum #%u at t = %.4f s: load %.6f rad (error %+.6f rad); verdict: %s", log_prefix_.c_str(),
              m.maxima_observed, m.last_maximum_time, m.last_maximum_position, m.last_maximum_position - command_,
              m.verdict.c_str());
  }
  if (st.verdict != announced_)
  {
    announced_ = st.verdict;
    if (m.detected)
    {
      ROS_INFO("%s%s detected: error %.6f rad, period %.4f s; load %.6f rad peak to peak about %.6f rad",
               log_prefix_.c_str(), st.verdict == Verdict::LimitCycle ? "LIMIT CYCLE" : "IRREGULAR OSCILLATION",
               st.error, st.period, m.peak_to_peak, m.cycle_centre);
    }
    else if (st.verdict == Verdict::Converged)
    {
      converged_at_ = sim_time;
      ROS_INFO("%sconverged to the command at t = %.4f s: no limit cycle", log_prefix_.c_str(), sim_time);
    }
  }
  return m;
}

void JointJudge::diagnose(const Simulator& sim, const RunConfig& run,
                          diagnostic_updater::DiagnosticStatusWrapper* status)
{
  const LimitCycleReport& verdict = monitor_->status();
  status->add("verdict", toString(verdict.verdict));
  status->add("equilibrium [rad]", formatNumber(monitor_->equilibrium()));
  if (verdict.verdict == Verdict::LimitCycle || verdict.verdict == Verdict::Irregular)
  {
    status->add("limit_cycle_error [rad]", formatNumber(verdict.error));
    status->add("period [s]", formatNumber(verdict.period));
    status->add("maxima_per_period", std::to_string(verdict.multiplicity));
    const CycleShape cycle = monitor_->cycleShape();
    status->add("peak_to_peak [rad]", formatNumber(cycle.peak_to_peak));
    status->add("cycle_centre [rad]", formatNumber(cycle.centre));
    const CycleResolution counted = resolution(sim, run, cycle);
    status->add("peak_to_peak_counts", formatNumber(counted.counts));
    status->add("peak_to_peak_arcmin", formatNumber(counted.arcmin));
    status->add("below_encoder_resolution", counted.below_count ? "true" : "false");
  }
  if (verdict.verdict == Verdict::Converged)
  {
    const SteadyAnswer& answer = steady(sim, run);
    status->add("steady_error [rad]", std::isnan(answer.error) ? "n/a: " + answer.note : formatNumber(answer.error));
    status->add("steady_basis", steadyBasisName(answer.basis));
  }
  const TrackingFigures figures = tracking(sim);
  status->add("settling_band [rad]", formatNumber(figures.band));
  status->add("settling_time [s]",
              std::isnan(figures.settling_time) ? "- (outside the band)" : formatNumber(figures.settling_time));
  status->add("steady_rms_error [rad]", formatNumber(figures.steady_rms_error));
}

}  // namespace backlash_servo
