// The joints of an arm advanced together: each on its own exact path between the instants their loads change.
#include "backlash_servo/robot/robot_simulator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
RobotSimulator::RobotSimulator(std::vector<RobotJoint> joints, const ArmModel* arm, double update_period)
    : joints_(std::move(joints)), arm_(arm), update_period_(update_period)
{
  if (joints_.empty())
  {
    throw std::invalid_argument("joints: an arm needs at least one joint");
  }
  if (!(update_period_ > 0.0) || !std::isfinite(update_period_))
  {
    throw std::invalid_argument("update_period: must be > 0 s (got " + std::to_string(update_period_) + ")");
  }
  time_ = joints_.front().run.initial.time;
  for (const RobotJoint& j : joints_)
  {
    if (std::count_if(joints_.begin(), joints_.end(), [&j](const RobotJoint& o) { return o.name == j.name; }) > 1)
    {
      throw std::invalid_argument("joints: '" + j.name + "' is given twice");
    }
    if (j.run.initial.time != time_)
    {
      throw std::invalid_argument("joints: '" + j.name + "' starts at another time (initial time " +
                                  std::to_string(j.run.initial.time) + " s, the first joint's " +
                                  std::to_string(time_) + " s)");
    }
    const int in_arm = arm_ != nullptr ? arm_->indexOf(j.name) : -1;
    if ((j.arm_gravity || j.arm_inertia) && in_arm < 0)
    {
      throw std::invalid_argument("joints: '" + j.name + "' takes its load from the arm, but " +
                                  (arm_ == nullptr ? std::string("no robot description is given")
                                                   : "the robot description has no movable joint '" + j.name + "'"));
    }
    arm_index_.push_back(in_arm);
    sims_.push_back(makeSimulator(j.run));
    updates_.push_back(0);
  }
  std::vector<std::size_t> all(joints_.size());
  for (std::size_t i = 0; i < all.size(); ++i)
  {
    all[i] = i;
  }
  applyArmLoad(all);
}

int RobotSimulator::indexOf(const std::string& name) const
{
  for (std::size_t i = 0; i < joints_.size(); ++i)
  {
    if (joints_[i].name == name)
    {
      return static_cast<int>(i);
    }
  }
  return -1;
}

Eigen::VectorXd RobotSimulator::pose() const
{
  Eigen::VectorXd q = Eigen::VectorXd::Zero(arm_ != nullptr ? static_cast<Eigen::Index>(arm_->joints().size()) : 0);
  for (std::size_t i = 0; i < sims_.size(); ++i)
  {
    if (arm_index_[i] >= 0)
    {
      q(arm_index_[i]) = sims_[i].state().load_position;
    }
  }
  return q;
}

double RobotSimulator::updateTime(std::size_t i, long k) const
{
  const RunConfig& run = joints_[i].run;
  const double t0 = run.initial.time;
  const double kd = static_cast<double>(k);
  return run.drive.sampled() ? t0 + kd / run.drive.controller_rate : t0 + kd * update_period_;
}

void RobotSimulator::advanceTo(double t_end, const std::vector<EventSink*>& sinks)
{
  if (!(t_end >= time_) || !std::isfinite(t_end))
  {
    throw std::invalid_argument("advanceTo: target time " + std::to_string(t_end) + " s is before the arm's time " +
                                std::to_string(time_) + " s or not finite");
  }
  const auto sink = [&sinks](std::size_t i) { return i < sinks.size() ? sinks[i] : nullptr; };
  const auto advanceAll = [&](double t) {
    for (std::size_t i = 0; i < sims_.size(); ++i)
    {
      sims_[i].advanceTo(t, sink(i));
    }
    time_ = t;
  };
  for (;;)
  {
    double next = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < sims_.size(); ++i)
    {
      if (armLoaded(i))
      {
        next = std::min(next, updateTime(i, updates_[i] + 1));
      }
    }
    if (!(next <= t_end))
    {
      break;
    }
    advanceAll(next);
    std::vector<std::size_t> due;
    for (std::size_t i = 0; i < sims_.size(); ++i)
    {
      if (armLoaded(i) && updateTime(i, updates_[i] + 1) == next)
      {
        ++updates_[i];
        due.push_back(i);
      }
    }
    applyArmLoad(due);
  }
  advanceAll(t_end);
}

void RobotSimulator::applyArmLoad(const std::vector<std::size_t>& due)
{
  if (arm_ == nullptr || due.empty())
  {
    return;
  }
  const Eigen::VectorXd q = pose();
  const Eigen::VectorXd gravity = arm_->gravityOnLoad(q);
  for (std::size_t i : due)
  {
    const int a = arm_index_[i];
    if (a < 0)
    {
      continue;
    }
    ServoParams p = sims_[i].params();
    if (joints_[i].arm_gravity)
    {
      p.load_torque = gravity(a);
    }
    if (joints_[i].arm_inertia)
    {
      p.load_inertia = arm_->inertiaAbout(q, static_cast<std::size_t>(a));  // M(q)_ii: one pass, not the matrix
    }
    sims_[i].setParams(p);
  }
}

}  // namespace backlash_servo
