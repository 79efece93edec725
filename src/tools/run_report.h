/**
 * @file run_report.h
 * @brief One run's result as JSON — what `backlash_sim --json` prints and the Python API's run() returns (the same
 *        text, parsed): the parameters echoed with the derived ζ, ω_n and chart coordinates, the verdict and its
 *        figures, the steady answer, the tracking figures (RunSummary::tracking), the maxima, the energy ledger and
 *        the final state. SI units; fields in docs/cli.md.
 */
#pragma once

#include <ostream>

#include "backlash_servo/step_response.h"

namespace backlash_servo
{
/// Writes the JSON object of run `r` of config `c` (one line; `r` run with RunConfig::tracking); wall_seconds [s] is
/// the run's wall time.
void writeRunJson(std::ostream& out, const RunConfig& c, const RunSummary& r, double wall_seconds);
}  // namespace backlash_servo
