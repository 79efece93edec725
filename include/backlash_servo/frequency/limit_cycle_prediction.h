/**
 * @file limit_cycle_prediction.h
 * @brief The describing-function analysis of the thesis' loop beside the exact cycle, as backlash_df and the Python
 *        module run it: harmonic balance of the classical DF of backlash (describing_function.h) with the linear
 *        servo (the continuous law, or a digital P, PID or cascade drive on the load or the motor), and the exact
 *        simulated cycle's fundamental. No ROS
 *        dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "Describing-function predictions beside the exact
 * cycle".
 */
#pragma once

#include <complex>
#include <string>
#include <vector>

#include "backlash_servo/frequency/describing_function.h"
#include "backlash_servo/simulation/response_monitor.h"
#include "backlash_servo/simulation/step_response.h"

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
  std::vector<HarmonicBalance> numerical;    ///< the real element's DF, one per classical prediction it converged from
  std::string numerical_note;                ///< why there is no numerical prediction (empty: there are, or none tried)
  SimulatedCycle simulated;
  /// A prediction's relative errors against the exact cycle (NaN without a cycle or for an unstable prediction).
  double amplitudeError(const HarmonicBalance& h) const;
  double frequencyError(const HarmonicBalance& h) const;
};

/// G(jω) of the loop's linear part under the continuous P law, as the backlash element sees it (docs/model.md, Part 4).
std::complex<double> thesisLoop(const ServoParams& params, double omega);

/// The drive law's torque in the fundamental at ω, per unit of each angle it reads: u = −K_θ Θ_c − K_x X, Θ_c the
/// load angle's fundamental, X = ρΘ_m the backlash input's (docs/model.md, Part 4).
struct LawResponse
{
  std::complex<double> load = 0.0;   ///< K_θ [N·m/rad]
  std::complex<double> motor = 0.0;  ///< K_x [N·m/rad]
};

/// The law's response at ω [rad/s] (the continuous law: K_θ = K).
LawResponse lawResponse(const ServoParams& params, const DriveParams& drive, double omega);

/// The law's static position stiffness [N·m/rad]: K for P and PID, K_v K_p for the cascade.
double lawStiffness(const ServoParams& params, const DriveParams& drive);

/// The loop's natural frequency √(ρ K / J) [rad/s], K = lawStiffness, J = J_m + ρ²(J_L + J_g): the centre of the
/// analysis' band of frequencies.
double loopNaturalFrequency(const ServoParams& params, const DriveParams& drive);

/// G(jω) of the rigid teeth's loop with the configured law, as the hysteresis sees it (docs/model.md, Part 4) [-].
std::complex<double> loopResponse(const ServoParams& params, const DriveParams& drive, double omega);

/// G(jω) of a compliant mesh's loop as the dead zone of its penetration sees it (docs/model.md, Part 4) [-].
std::complex<double> compliantLoop(const ServoParams& params, const DriveParams& drive, double omega);

/// |ρΘ_m / X|: the backlash input's amplitude per unit of the mesh deflection's in that loop at ω [rad/s].
double compliantMotorAmplitude(const ServoParams& params, const DriveParams& drive, double omega);

/// E(A, ω) of the real element's balance [N·m/rad] (docs/model.md, Part 4): amplitude A [rad], ω [rad/s].
std::complex<double> elementBalance(const ServoParams& params, double amplitude, double omega,
                                    const DriveParams& drive = DriveParams());

/// The real element's balance E = 0 solved from `start` (a classical prediction); false when Newton's method does not
/// converge within 20 steps (a step below 1e-7 in ln A and ln ω, |E| below 1e-5 lawStiffness) or leaves A > Δ/2, ω
/// within 1e±4 ω_n.
bool numericalHarmonicBalance(const ServoParams& params, const HarmonicBalance& start, HarmonicBalance* out,
                              const DriveParams& drive = DriveParams());

/// The exact cycle of `config` (a constant command; the continuous law or a digital drive).
SimulatedCycle simulateCycle(const RunConfig& config);

/// Throws InvalidParameterError, naming the key, for what the analysis does not take: a profile, a torque limit, a
/// compensator, counts of an encoder the law reads, a torsional shaft, or no backlash.
void requireDescribable(const RunConfig& config);

/// The whole analysis (requireDescribable first).
LimitCyclePrediction predictLimitCycle(const RunConfig& config);

}  // namespace backlash_servo
