/**
 * @file compliant_joint.h
 * @brief The compliant joint: resilient teeth (a mesh spring–damper that never pulls) and an optional torsional shaft,
 *        under the continuous P law, advanced exactly — every mode is linear with constant input (order 4, or 6 with
 *        the shaft), solved by LinearMode, and every event is a located zero crossing. The second way the gear
 *        transmits torque beside the rigid teeth with impacts (plant.h). No ROS dependency.
 *
 * Model (docs/model.md, "The compliant joint"): mesh coordinate g = θ_o − ρθ_m (θ_o = θ_c with a rigid shaft);
 * penetration y = −g on the forward flank (g < 0), y = g − Δ on the backward flank (g > Δ); P = c y + d ẏ.
 * spring_damper: Q = ±max(0, P). msl_elastobacklash: Q = ±(c y + min(c y, d ẏ)) while positive (2cy while
 * dẏ > cy — the K2 sub-mode —, else cy + dẏ — KD). A contact starts where y becomes positive, is released where P
 * would pull, and a released flank re-engages where P becomes positive again, even while y > 0.
 *   motor:  J_m ω̇_m = K(θ_R − θ_c) − f_m ω_m − ρ Q
 *   rigid shaft: (J_L + J_g) ω̇_c = Q − f_L ω_c + T_ext
 *   torsional shaft: J_g ω̇_o = Q − S, J_L ω̇_c = S − f_L ω_c + T_ext, S = k_s(θ_o − θ_c) + d_s(ω_o − ω_c).
 * Dry friction and digital drives are not part of this model yet.
 */
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <string>
#include <vector>

#include "backlash_servo/limit_cycle.h"
#include "backlash_servo/params.h"

namespace backlash_servo
{
/// The compliant mesh and shaft (MODEL Part 3 keys), SI units.
struct CompliantParams
{
  std::string mesh_law = "spring_damper";  ///< spring_damper | msl_elastobacklash
  double mesh_stiffness = 0.0;             ///< c [N·m/rad] at the output shaft (> 0)
  double mesh_damping = 0.0;               ///< d [N·m·s/rad] at the output shaft
  double gear_inertia = 0.0;               ///< J_g [kg·m²] of the output gear
  double shaft_stiffness = 0.0;            ///< k_s [N·m/rad]; 0 = rigid shaft
  double shaft_damping = 0.0;              ///< d_s [N·m·s/rad]
  /// Throws InvalidParameterError naming the key: c > 0 finite, d ≥ 0, J_g ≥ 0, k_s ≥ 0, d_s ≥ 0, d_s > 0 needs
  /// k_s > 0, k_s > 0 needs J_g > 0, the law one of the two.
  void validate() const;
};

/// A contact phase's mode of the mesh.
enum class MeshMode
{
  Free,       ///< no mesh torque (in the free play, or released while still penetrating)
  Forward,    ///< pressing on the forward flank (KD for msl_elastobacklash)
  Backward,   ///< pressing on the backward flank (KD)
  ForwardK2,  ///< msl_elastobacklash entering the forward flank: Q = 2cy while dẏ > cy
  BackwardK2  ///< the same on the backward flank
};

class CompliantJoint
{
 public:
  /// Everything at rest at 0 with the teeth touching the forward flank without deflection (MODEL Part 3's start),
  /// command θ_R [rad] applied at t = 0.
  CompliantJoint(const ServoParams& servo, const CompliantParams& mesh, double command);

  /// Replaces the state (the order of state()); the mesh takes the mode the state implies (pressing flank or free).
  /// Throws std::invalid_argument on a wrong size or non-finite entries.
  void setState(const Eigen::VectorXd& x);
  /// Advances exactly to t_end [s] (≥ time()); maxima of θ_c are recorded on the way.
  void advanceTo(double t_end);
  double time() const { return time_; }
  /// The state: (θ_m, ω_m, θ_c, ω_c) with a rigid shaft, (θ_m, ω_m, θ_o, ω_o, θ_c, ω_c) with a torsional one.
  const Eigen::VectorXd& state() const { return x_; }
  MeshMode mode() const { return mode_; }
  /// The positive maxima of θ_c so far (time [s], position [rad], velocity after [rad/s]), in time order.
  const std::vector<Maximum>& maxima() const { return maxima_; }
  /// Contact phases begun so far (each engagement of a flank, re-engagements included).
  std::uint64_t contacts() const { return contacts_; }
  /// Re-engagements of a released flank while still penetrating.
  std::uint64_t reengagements() const { return reengagements_; }

 private:
  int n() const { return torsional_ ? 6 : 4; }
  int out() const { return 2; }  // index of θ_o, the mesh's output-side angle (θ_c itself with a rigid shaft)
  int load() const { return torsional_ ? 4 : 2; }
  /// A and u of the current mode.
  void modeMatrices(MeshMode m, Eigen::MatrixXd* a, Eigen::VectorXd* u) const;
  /// The penetration y = w·x + w0 of a flank (σ = +1 forward, −1 backward) as a linear output.
  void penetration(int sigma, Eigen::VectorXd* w, double* w0) const;
  /// P = c y + d ẏ (k_y y + k_v ẏ for the given gains) of a flank as a linear output.
  void flankTorque(int sigma, double ky, double kv, Eigen::VectorXd* w, double* w0) const;
  /// The mode the mesh takes from the current state (after an event).
  MeshMode chooseMode(bool released_forward, bool released_backward) const;

  ServoParams s_;
  CompliantParams c_;
  double command_;
  bool torsional_;
  bool msl_;
  double time_ = 0.0;
  Eigen::VectorXd x_;
  MeshMode mode_ = MeshMode::Forward;
  std::vector<Maximum> maxima_;
  std::uint64_t contacts_ = 0, reengagements_ = 0;
  int last_kind_ = -1, last_sigma_ = 0;  // the event that ended the previous segment
};

}  // namespace backlash_servo
