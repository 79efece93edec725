/**
 * @file experiment_design.h
 * @brief An identification experiment checked on the prior's own joint before it is run on the real one.
 *
 * The excitation of identificationExperiment() at growing travels (3Δ, 6Δ, 12Δ, … up to the largest allowed), each
 * simulated on the prior (its drive, guesses, load torque and friction) and read back by estimateInitial(): the first
 * travel whose recording gives back every body parameter the prior states within `tolerance` is chosen. A load torque
 * (gravity) that keeps the teeth on one flank, or a load that friction keeps from sliding, shows here as keys not
 * given back, and the travel grows until they are — or the largest travel is returned with the keys it leaves
 * uninformed named. Units SI (rad, s).
 */
#pragma once
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/model/run_config.h"

namespace backlash_servo
{
/// What is asked of the experiment.
struct ExperimentRequest
{
  double duration = 60.0;   ///< [s]
  double travel = 0.0;      ///< [rad] the command's largest excursion; 0: grown from 3Δ up to `max_travel`
  double max_travel = 0.0;  ///< [rad] the largest travel tried when growing (0: the command's range)
  double dither_amplitude = 0.0, dither_frequency = 0.0;  ///< [rad], [Hz] (identification.h)
  double tolerance = 0.02;  ///< relative error of a body parameter given back (a level: of the peak torque's 1 %)
};

/// The experiment chosen and what its check on the prior's joint found.
struct CheckedExperiment
{
  std::vector<ProfileSegment> segments;
  double travel = 0.0;        ///< [rad]
  std::uint64_t impacts = 0;  ///< in the simulated run on the prior's joint
  /// Each checked key's relative error on the prior's joint (NaN: not estimated from the run).
  std::map<std::string, double> errors;
  /// Keys not given back within the tolerance, with why (empty: the experiment informs every one).
  std::map<std::string, std::string> uninformed;
  std::vector<double> travels_tried;  ///< [rad], in order
};

/**
 * Designs and checks the experiment on `prior` (its params must hold guesses of the inertias, frictions, backlash and
 * the drive the joint will run under). `progress` (may be empty) hears each travel tried. Throws
 * InvalidParameterError as identificationExperiment() does.
 */
CheckedExperiment designExperiment(const RunConfig& prior, const ExperimentRequest& request,
                                   const std::function<void(const std::string&)>& progress = {});

}  // namespace backlash_servo
