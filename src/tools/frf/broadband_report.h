// backlash_frf's broadband estimates (PRBS, chirp) as text, JSON and CSV, and the chart's data.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "backlash_servo/frequency/broadband_response.h"

namespace backlash_servo
{
/// One amplitude's estimate, with the backlash-0 estimate of the same excitation when asked for (`has_linear`).
struct BroadbandEstimate
{
  double amplitude = 0.0;  ///< [rad or N·m]
  BroadbandResponse response;
  BroadbandResponse linear;
  bool has_linear = false;
};

/// Columns amplitude, frequency, gain, phase, coherence, input_power[, linear_gain, linear_phase]; one row per line.
void writeBroadbandCsv(std::ostream& out, const std::vector<BroadbandEstimate>& estimates, bool linear);
/// {"channel", "excitation", "offset", "sample_rate", "samples_per_period", "estimates": [{"amplitude", "lines":
/// [{"frequency", "gain", "phase", "coherence", "input_power"[, "linear_gain", "linear_phase"]}]}]}.
void writeBroadbandJson(std::ostream& out, const std::string& channel, const std::string& excitation, double offset,
                        const std::vector<BroadbandEstimate>& estimates);
/// A table per amplitude of at most `rows` lines spread evenly in log frequency.
void writeBroadbandText(std::ostream& out, const std::string& channel, const std::string& excitation,
                        const std::vector<BroadbandEstimate>& estimates, int rows);

}  // namespace backlash_servo
