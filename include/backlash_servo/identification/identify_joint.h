/**
 * @file identify_joint.h
 * @brief The whole identification, as backlash_identify and the Python module run it: the initial estimates
 *        (identification.h for rigid teeth, identify_mesh.h for a compliant mesh), the restitution of rigid teeth by
 *        replays around impacts, the static friction from the rests, then the joint fit (joint_fit.h) of the chosen
 *        estimates. No ROS dependency.
 */
#pragma once

#include <optional>
#include <set>
#include <string>
#include <vector>

#include "backlash_servo/identification/identification.h"
#include "backlash_servo/identification/joint_fit.h"
#include "backlash_servo/identification/measured_angles.h"

namespace backlash_servo
{
/// Which estimates the joint fit adjusts.
enum class JointFitMode
{
  Off,   ///< none: the initial estimates are the result
  On,    ///< every estimate it can fit
  Auto,  ///< every one on exact angles (no contact band given); on measured ones only the backlash and the restitution
         ///< (or the mesh's stiffness and damping)
};

struct IdentifyOptions
{
  /// The keys estimated (empty: all of identifiedKeysFor(prior)); the others keep the prior's values.
  std::set<std::string> keys;
  JointFitMode joint = JointFitMode::Auto;
  JointFitSettings fit;  ///< windows, budget, progress (its keys are chosen here)
  /// The prior's keys the user stated (the others are unknown: never reported as known, their values placeholders);
  /// empty optional: every value of the prior is known.
  std::optional<std::set<std::string>> stated;
};

/// One estimated parameter.
struct IdentifiedParameter
{
  std::string key;
  Estimate initial;  ///< from the data alone [its unit]
  Estimate value;    ///< the result: the joint fit's when it fitted this key [its unit]
  /// false: this recording does not inform it — `reason` says why; `value` is the prior's when stated, else NaN
  bool identifiable = true;
  std::string reason;
  bool in_joint_fit = false;  ///< adjusted by the joint fit
  bool informed = true;       ///< (joint fit) the recording moves the residuals with it
  double largest_correlation = NAN;
  std::string most_correlated_with;
};

struct JointIdentification
{
  MeasuredAngles measurement;       ///< the angles as recognised, the smoothing and band used
  IdentificationSettings settings;  ///< as used (the smoothing and band from the data unless given)
  InitialEstimates initial;
  std::vector<IdentifiedParameter> parameters;  ///< in identifiedKeys() order, every one asked for
  bool joint_fit = false;                       ///< the joint fit ran
  JointFit fit;                                 ///< its report (when it ran)
  std::string restitution_note;                 ///< why the restitution was not estimated (empty: it was)
  ServoParams model;                            ///< the prior with the estimates in place (T_s ≥ T_c kept)
  /// Sentences for the user: the identified joint outside the validated envelope (named by its keys), and what that
  /// skipped.
  std::vector<std::string> warnings;
};

/// What can be estimated, in the parameter table's order: the joint fit's keys and the static friction levels.
const std::vector<std::string>& identifiedKeys();
/// Those that describe `joint` (jointFitKeysFor: the restitution of rigid teeth, or a compliant mesh's stiffness and
/// damping) and the static friction levels.
std::vector<std::string> identifiedKeysFor(const ServoParams& joint);

/**
 * Identifies the joint from the recording: `prior` holds what is known (the gear ratio at least; its values are kept
 * for the keys not estimated, and start the joint fit for the others when the data give none) and says which model
 * is fitted — rigid teeth, or a compliant mesh when its mesh_stiffness is > 0 (the value itself is estimated).
 * Throws InvalidParameterError naming what is missing (identification.h, identify_mesh.h), an unknown key, a key that
 * does not describe the prior's joint, or a torsional shaft (not identified: its gear's angle is not measured).
 */
JointIdentification identifyJoint(const Recording& data, const IdentificationSettings& settings,
                                  const ServoParams& prior, const IdentifyOptions& options);

}  // namespace backlash_servo
