/**
 * @file arm_model.h
 * @brief An arm's rigid-body dynamics from its URDF: the movable joints (names, axes, limits), the simple
 *        transmissions (reduction and actuator per joint), and at a pose q the gravity torque on each joint's load
 *        and the joint-space mass matrix. No ROS dependency (urdfdom parses the XML; orocos-kdl's frames and inertias, in a
 *        recursive Newton–Euler pass of our own over the bodies in an array).
 *
 * Units SI: q in rad (m for a prismatic joint), torques in N·m, inertias in kg·m². Signs as the model's
 * `load_torque`: gravityOnLoad(q)[i] is the torque gravity applies to joint i's load, positive in +q_i (the torque
 * the joint must supply to hold the pose is its negative). Every movable joint the URDF lists counts in the pose;
 * a joint the caller does not simulate stays where the caller puts it.
 */
#pragma once

#include <Eigen/Dense>

#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace backlash_servo
{
/// Standard gravity [m/s²].
constexpr double STANDARD_GRAVITY = 9.80665;

/// One movable URDF joint (revolute, continuous or prismatic) and its transmission, if the URDF gives one.
struct ArmJoint
{
  std::string name;        ///< URDF joint name
  bool prismatic = false;  ///< a prismatic joint's position is in m, its "torque" a force in N
  double lower = -std::numeric_limits<double>::infinity();  ///< position limit [rad] (±inf for continuous)
  double upper = std::numeric_limits<double>::infinity();   ///< position limit [rad]
  double velocity_limit = 0.0;                              ///< URDF <limit velocity> [rad/s]; 0 = not given
  double effort_limit = 0.0;                                ///< URDF <limit effort> [N·m]; 0 = not given
  double reduction = 0.0;  ///< <mechanicalReduction> n of its SimpleTransmission (motor turns per joint turn); 0 = none
  std::string actuator;    ///< the transmission's actuator name; empty = none
};

/// The arm: parsed once, then evaluated at any pose. Not copyable; one thread at a time (a pass of the inverse
/// dynamics keeps scratch state).
class ArmModel
{
 public:
  /// Parses URDF text. Throws std::invalid_argument naming the element on malformed XML, a joint without its
  /// links, a non-positive or non-finite mass/inertia/reduction, a transmission naming an unknown joint, or a
  /// transmission other than transmission_interface/SimpleTransmission.
  explicit ArmModel(const std::string& urdf_xml);
  ~ArmModel();
  ArmModel(const ArmModel&) = delete;
  ArmModel& operator=(const ArmModel&) = delete;

  const std::string& robotName() const { return robot_name_; }
  /// The movable joints, in the order of every vector here: depth-first from the root (as KDL numbers them), then
  /// those of subtrees without mass (a motor's drawing, a mark), which change neither gravity nor inertia.
  const std::vector<ArmJoint>& joints() const { return joints_; }
  /// Index of a joint by URDF name; -1 when the URDF has no movable joint by that name.
  int indexOf(const std::string& name) const;
  /// Gravity's torque on each joint's load at pose q [N·m] (positive in +q_i), gravity g [m/s²] along −z of the
  /// root link.
  Eigen::VectorXd gravityOnLoad(const Eigen::VectorXd& q, double g = STANDARD_GRAVITY) const;
  /// The joint-space mass matrix M(q) [kg·m²]: M(q)_ii is the inertia joint i moves at pose q with the others held.
  Eigen::MatrixXd massMatrix(const Eigen::VectorXd& q) const;
  /// M(q)_ii [kg·m²] alone: one pass of the inverse dynamics instead of one per joint.
  double inertiaAbout(const Eigen::VectorXd& q, std::size_t i) const;

 private:
  /// Column c of M(q) [kg·m²].
  Eigen::VectorXd massColumn(const Eigen::VectorXd& q, std::size_t c) const;

  struct Dynamics;
  std::string robot_name_;
  std::vector<ArmJoint> joints_;
  std::unique_ptr<Dynamics> dynamics_;
};

}  // namespace backlash_servo
