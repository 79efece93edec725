/**
 * @file joint_fit.h
 * @brief The joint fit: the listed parameters at once, with the exact simulator as the model, by nonlinear least
 *        squares over windows of the recording re-anchored on the measured state (replay_windows.h). No ROS
 *        dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "The joint fit".
 */
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "backlash_servo/identification/identification.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
struct JointFitSettings
{
  /// The parameters fitted (of jointFitKeysFor(start)); the others stay at the start's values.
  std::vector<std::string> keys;
  double window = 0.2;        ///< each window's length [s]
  int windows = 40;           ///< how many, spread evenly over the recording
  int max_evaluations = 600;  ///< the budget of replays of all windows
  double tolerance = 1e-7;    ///< stop when a step changes every scaled parameter by less than this [-]
  /// [rad]: stop once the residuals' rms is below this (far below any encoder's resolution: exact data)
  double residual_floor = 1e-8;
  /// Called after each evaluation with (evaluations done, budget); may be empty.
  std::function<void(int, int)> progress;
};

struct FittedParameter
{
  std::string key;
  double start = 0.0;                ///< the initial estimate [its unit]
  double value = 0.0;                ///< the fitted value [its unit]
  double standard_error = 0.0;       ///< [its unit]; NaN when not informed
  bool informed = true;              ///< false: the recording does not move the objective with it
  double largest_correlation = 0.0;  ///< the largest |correlation| with another fitted parameter [-]
  std::string most_correlated_with;  ///< that parameter's key (empty when alone or not informed)
};

struct JointFit
{
  ServoParams params;                       ///< the start with the fitted values in place
  std::vector<FittedParameter> parameters;  ///< in the order of JointFitSettings::keys
  Eigen::MatrixXd correlation;              ///< between the parameters (NaN rows for those not informed)
  double start_rms = 0.0;                   ///< the residuals' rms at the start [rad]
  double rms = 0.0;                         ///< at the fit [rad]
  double condition = 0.0;                   ///< of the informed parameters' scaled Jacobian [-]
  std::size_t windows = 0, residuals = 0;   ///< windows used (after dropping), residuals at the fit
  std::size_t windows_dropped = 0;          ///< windows left out: their residual stayed beyond 5 × the median
  std::vector<std::size_t> window_starts;   ///< each window's first sample
  std::size_t window_length = 0;            ///< [samples]
  /// Per window, the corrections fitted to its anchor's velocities ω_m, ω_c [rad/s] (ReplayWindows::residuals).
  std::vector<double> anchor_corrections;
  int evaluations = 0;
  bool budget_exhausted = false;  ///< stopped by max_evaluations, not by the tolerance
};

/// The fittable keys, in table order: backlash, motor_inertia, load_inertia, motor_friction, load_friction,
/// motor_coulomb_friction, load_coulomb_friction, load_torque, restitution, mesh_stiffness, mesh_damping.
const std::vector<std::string>& jointFitKeys();
/// Those that describe `joint`: the restitution for rigid teeth, the mesh's stiffness and damping for a compliant
/// mesh (mesh_stiffness > 0), the others for both.
std::vector<std::string> jointFitKeysFor(const ServoParams& joint);

/**
 * Fits `settings.keys` of the joint `start` (rigid teeth or a compliant mesh; its other values held) to the
 * recording. `zero_offset` [rad] is the gap the encoders read on the forward flank (InitialEstimates::zero_offset).
 * Throws InvalidParameterError for an unknown key, a key that does not describe `start` (jointFitKeysFor), a
 * torsional shaft (its gear is not measured), no key, or a recording too short for one window.
 */
JointFit fitJoint(const Recording& data, const IdentificationSettings& identification, double zero_offset,
                  const ServoParams& start, const JointFitSettings& settings);

}  // namespace backlash_servo
