/**
 * @file limit_cycle_prediction.h
 * @brief The describing-function analysis of the thesis' loop beside the exact cycle, as backlash_df and the Python
 *        module run it: harmonic balance of the classical DF of backlash (describing_function.h) with the linear
 *        servo, and the exact simulated cycle's fundamental. No ROS dependency.
 *
 * **The loop.** Under the continuous P law the backlash element's input is x = ρθ_m, driven by the error through the
 * linear servo ẍ + 2ζω_n ẋ = ω_n²(θ_R − θ_c): G(jω) = ω_n² / (−ω² + 2jζω_n ω), the element's output θ_c fed back
 * with −1.
 *
 * **The exact cycle.** The joint is run until its verdict settles (runResponse); on a limit cycle one more period
 * from the settled state is sampled at 4096 even points, and the fundamental of ρθ_m about its mean gives the
 * amplitude (peak: the largest excursion from the mean), the frequency 2π/period.
 */
#pragma once

#include <vector>

#include "backlash_servo/describing_function.h"
#include "backlash_servo/response_monitor.h"
#include "backlash_servo/step_response.h"

namespace backlash_servo
{
/// The exact cycle of the configured joint.
struct SimulatedCycle
{
  Verdict verdict = Verdict::Undecided;
  double amplitude = NAN;  ///< the fundamental of ρθ_m about its centre [rad] (NaN: no cycle)
  double peak = NAN;       ///< the largest excursion of ρθ_m from its centre [rad]
  double frequency = NAN;  ///< [rad/s]
  double centre = NAN;     ///< the mean of ρθ_m over the period [rad]
  double simulated = 0.0;  ///< the run's simulated time [s]
};

struct LimitCyclePrediction
{
  double zeta = 0.0;                         ///< ζ of the loop [-]
  double natural_frequency = 0.0;            ///< ω_n [rad/s]
  std::vector<HarmonicBalance> predictions;  ///< classical DF, ω in [1e-4, 1e4] ω_n
  SimulatedCycle simulated;
  /// A prediction's relative errors against the exact cycle (NaN without a cycle or for an unstable prediction).
  double amplitudeError(const HarmonicBalance& h) const;
  double frequencyError(const HarmonicBalance& h) const;
};

/// G(jω) of the loop's linear part as the backlash element sees it (see the file comment).
std::complex<double> thesisLoop(const ServoParams& params, double omega);

/// The exact cycle of `config` (the continuous P law with a constant command).
SimulatedCycle simulateCycle(const RunConfig& config);

/**
 * The whole analysis. Throws InvalidParameterError for a configuration other than the continuous P law with a
 * constant command (no controller_rate, torque_limit, compensation or profile) or without backlash.
 */
LimitCyclePrediction predictLimitCycle(const RunConfig& config);

}  // namespace backlash_servo
