/**
 * @file robot_simulator.h
 * @brief Several geared joints of one arm in one simulated time: each joint is a Simulator (plant, drive, events
 *        located exactly); the arm couples them through the load each joint carries — gravity's torque on its load
 *        and the inertia it moves, both functions of the whole arm's pose, recomputed at each of the joint's
 *        controller samples (a continuous law: every `update_period`) and held until its next. No ROS dependency.
 *
 * Between two update instants the joints do not interact, so each advances on its own closed form with its own
 * events, exactly as a single joint does; advanceTo(t) visits every update instant of every joint in time order, so
 * the pose read at an instant is every joint's state at that same instant. What is neglected: the off-diagonal
 * terms of the mass matrix (another joint's acceleration driving this one) and the velocity terms (Coriolis,
 * centrifugal) — docs/model.md gives their size on the example arm. Units SI; torques N·m, inertias kg·m².
 */
#pragma once

#include <Eigen/Dense>

#include <memory>
#include <string>
#include <vector>

#include "backlash_servo/model/run_config.h"
#include "backlash_servo/robot/arm_model.h"
#include "backlash_servo/simulation/simulator.h"

namespace backlash_servo
{
/// One simulated joint of the arm.
struct RobotJoint
{
  std::string name;          ///< URDF joint name (its load); also the name on its topics
  std::string motor_name;    ///< the motor's name (the URDF transmission's actuator, else "<name>_motor")
  RunConfig run;             ///< the joint: parameters, drive, initial state and command, as a single joint's
  bool arm_gravity = false;  ///< load_torque = gravity's torque from the arm at the pose (else run's constant)
  bool arm_inertia = false;  ///< load_inertia = M(q)_ii of the arm at the pose (else run's constant)
};

class RobotSimulator
{
 public:
  /**
   * Builds every joint's simulator (makeSimulator) and sets the arm's load at the initial pose. `arm` may be null
   * when no joint takes gravity or inertia from it; it must outlive this object. `update_period` [s] is how often a
   * joint under a continuous law gets its load recomputed (> 0). Joints not simulated stay at q = 0 in the pose.
   * Throws std::invalid_argument naming the joint (unknown in the arm, a name twice, no arm for an arm load) and
   * InvalidParameterError for a joint's parameters.
   */
  RobotSimulator(std::vector<RobotJoint> joints, const ArmModel* arm, double update_period);

  std::size_t size() const { return joints_.size(); }
  const RobotJoint& spec(std::size_t i) const { return joints_[i]; }
  const Simulator& joint(std::size_t i) const { return sims_[i]; }
  Simulator& joint(std::size_t i) { return sims_[i]; }
  /// Index by name; -1 when no joint has it.
  int indexOf(const std::string& name) const;
  double time() const { return time_; }
  /// The arm's pose now: every arm joint's position [rad], the simulated ones' load positions, the others 0.
  Eigen::VectorXd pose() const;
  /// Advances every joint exactly to t_end [s] (≥ time()), recomputing each joint's load at each of its update
  /// instants on the way; `sinks[i]` (optional, may be empty or hold nulls) receives joint i's events.
  void advanceTo(double t_end, const std::vector<EventSink*>& sinks = {});
  /// The load joint i carries now: gravity's torque [N·m] and the inertia [kg·m²] (its run's constants when the
  /// joint does not take them from the arm).
  double loadTorque(std::size_t i) const { return sims_[i].params().load_torque; }
  double loadInertia(std::size_t i) const { return sims_[i].params().load_inertia; }

 private:
  /// Whether joint i takes a load (gravity or inertia) from the arm, updated at its instants.
  bool armLoaded(std::size_t i) const { return joints_[i].arm_gravity || joints_[i].arm_inertia; }
  /// Time of joint i's next update instant after its k-th [s]: its controller's sample or the update period's.
  double updateTime(std::size_t i, long k) const;
  /// Sets the arm's gravity and inertia at the current pose into the joints in `due`.
  void applyArmLoad(const std::vector<std::size_t>& due);

  std::vector<RobotJoint> joints_;
  std::vector<Simulator> sims_;
  std::vector<int> arm_index_;  // joint i's index in the arm's joints; -1 = not in the arm
  std::vector<long> updates_;   // update instants taken per joint
  const ArmModel* arm_;
  double update_period_;
  double time_ = 0.0;
};

}  // namespace backlash_servo
