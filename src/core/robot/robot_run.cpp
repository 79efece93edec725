// An arm's run: one judge per joint, checked on a common grid, stopped at the duration or when all have settled.
#include "backlash_servo/robot/robot_run.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "backlash_servo/simulation/steady_state.h"

namespace backlash_servo
{
namespace
{
/// Whether joint i's judge has settled and, for a convergence, the joint is there (as a single run until settled).
bool settledNow(const ResponseMonitor& monitor, const Simulator& sim)
{
  return monitor.settled() && (monitor.status().verdict != Verdict::Converged || monitor.convergedNear(sim.state()));
}
}  // namespace

double robotCheckPeriod(const std::vector<RobotJoint>& joints)
{
  double fastest = 1000.0;
  for (const RobotJoint& j : joints)
  {
    fastest = std::max(fastest, j.run.drive.controller_rate);
  }
  return 1.0 / fastest;
}

RobotRunResult runRobot(RobotSimulator* robot, double duration, double max_duration, double check_period,
                        const std::function<void(const RobotSimulator&)>& on_check,
                        const std::function<void(double)>& progress)
{
  const double t0 = robot->time();
  std::vector<std::unique_ptr<ResponseMonitor>> monitors;
  std::vector<EventSink*> sinks;
  double cap = 0.0;
  for (std::size_t i = 0; i < robot->size(); ++i)
  {
    const RunConfig& run = robot->spec(i).run;
    const Simulator& sim = robot->joint(i);
    monitors.push_back(std::make_unique<ResponseMonitor>(sim.params(), sim.command(),
                                                         loopEquilibrium(sim.params(), run.drive, sim.command()),
                                                         sim.state(), sim.drive().sampled()));
    sinks.push_back(monitors.back().get());
    cap = std::max(cap, steadyBudget(sim.params(), run.drive));
  }
  const bool until_settled = !(duration > 0.0);
  const double t_stop = t0 + (until_settled ? (max_duration > 0.0 ? max_duration : cap) : duration);
  RobotRunResult out;
  out.stopped_by = until_settled ? "max_duration" : "duration";
  for (long k = 1;; ++k)
  {
    const double t = std::min(t0 + static_cast<double>(k) * check_period, t_stop);
    robot->advanceTo(t, sinks);
    bool all_settled = true;
    for (std::size_t i = 0; i < robot->size(); ++i)
    {
      const Simulator& sim = robot->joint(i);
      monitors[i]->check(sim.state(), sim.drive().winding(), sim.atRestForever());
      all_settled = all_settled && settledNow(*monitors[i], sim);
    }
    if (on_check)
    {
      on_check(*robot);
    }
    if (progress)
    {
      progress((t - t0) / (t_stop - t0));
    }
    if (until_settled && all_settled)
    {
      out.stopped_by = "settled";
      break;
    }
    if (t >= t_stop)
    {
      break;
    }
  }
  out.simulated = robot->time() - t0;
  for (std::size_t i = 0; i < robot->size(); ++i)
  {
    RobotJointResult r;
    r.name = robot->spec(i).name;
    r.status = monitors[i]->status();
    r.cycle = monitors[i]->cycleShape();
    r.impacts = robot->joint(i).impactCount();
    r.state = robot->joint(i).state();
    r.load_torque = robot->loadTorque(i);
    r.load_inertia = robot->loadInertia(i);
    out.joints.push_back(r);
  }
  return out;
}

}  // namespace backlash_servo
