/**
 * @file run_report.h
 * @brief One run's result as JSON — what `backlash_sim --json` prints and the Python API's run() returns (the same
 *        text, parsed): the parameters echoed with the derived ζ, ω_n and chart coordinates, the verdict and its
 *        figures, the steady answer, the tracking figures (RunSummary::tracking), the maxima, the energy ledger and
 *        the final state. SI units; fields in docs/cli.md.
 */
#pragma once

#include <ostream>
#include <string>

#include "backlash_servo/robot/robot_run.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
/// Writes the JSON object of run `r` of config `c` (one line; `r` run with RunConfig::tracking); wall_seconds [s] is
/// the run's wall time.
void writeRunJson(std::ostream& out, const RunConfig& c, const RunSummary& r, double wall_seconds);

/// Writes the JSON object of an arm's run (one line): {"robot", "simulated", "stopped_by", "wall_time", "joints":
/// [{"name", "verdict", "error", "period", "peak_to_peak", "impacts", "load_position", "motor_position",
/// "load_torque", "load_inertia"}, …]} in SI units.
void writeRobotRunJson(std::ostream& out, const std::string& robot_name, const RobotRunResult& r, double wall_seconds);

/// A sustained oscillation's size beyond radians, for the text reports: " (N counts of the encoder the loop reads,
/// A arcmin at the load)", and, under one count, that the loop cannot see the hunt; "" without a cycle.
std::string resolutionText(const CycleResolution& r);
}  // namespace backlash_servo
