/**
 * @file limit_cycle_prediction.h
 * @brief The describing-function analysis of the thesis' loop beside the exact cycle, as backlash_df and the Python
 *        module run it: harmonic balance of the classical DF of backlash (describing_function.h) with the linear
 *        servo (the continuous law, or a digital P, PID or cascade drive on the load or the motor), and the exact
 *        simulated cycle's fundamental. No ROS
 *        dependency.
 *
 * **The loop.** Under the continuous P law the backlash element's input is x = ρθ_m, driven by the error through the
 * linear servo ẍ + 2ζω_n ẋ = ω_n²(θ_R − θ_c): G(jω) = ω_n² / (−ω² + 2jζω_n ω), the element's output θ_c fed back
 * with −1.
 *
 * **The numerical DF of the real element** (driven_backlash.h): the classical balance lumps the load into the motor's
 * inertia and friction and takes the backlash as massless hysteresis; the real element is the load with its inertia,
 * friction and impacts, driven by the motor's tooth. Its two describing functions — N_θ of the load angle, N_T of the
 * torque the teeth pass to the load — balance the motor's equation J_m θ̈_m + f_m θ̇_m + T_cm sgn θ̇_m =
 * −K θ_c − ρT (about the cycle's centre) in the fundamental, per unit amplitude A of x = ρθ_m:
 *   E(A, ω) = (−ω² J_m + jω f_m)/ρ + j 4T_cm/(πA) + K N_θ(A, ω) + ρ N_T(A, ω) = 0,
 * two real equations for A and ω, solved by Newton's method in (ln A, ln ω) (Jacobian by central differences, steps
 * 1e-4) from each classical prediction. Stability by Loeb's criterion on E (E = (D/ρ)(G N + 1) near a solution in the
 * classical limit, D/ρ ≠ 0, so the criterion carries over). Taken when there is no load torque (the element's cycle
 * must be symmetric); a Newton that does not converge (a non-periodic element: its DFs are means) gives no prediction.
 *
 * **A digital drive** (sampled at f_s = 1/T, held; optionally one sample late) reads the load angle θ_c or the motor's
 * x = ρθ_m (`feedback`), and the cascade also the motor's speed. Its torque's fundamental is u = −K_θ Θ_c − K_x X
 * (lawResponse), with the hold's fundamental H = (1 − e^{−jωT})/(jωT) [e^{−jωT}] and, from the drive's recurrences
 * (backward-rectangle integral, derivative of the measurement, the speed a backward difference of the motor encoder):
 *   P / PID:  C(z) = K + K_i T/(1 − z⁻¹) + K_d (1 − z⁻¹)/T, K_θ = C H on load feedback, K_x = C H on motor feedback;
 *   cascade:  C_v(z) = K_v + K_vi T/(1 − z⁻¹), K_θ = C_v K_p H (load feedback), K_x = C_v ((1 − z⁻¹)/T [+ K_p on
 *             motor feedback]) H.
 * The continuous law is K_θ = K. The element's balance is then
 *   E(A, ω) = (−ω² J_m + jω f_m)/ρ + j 4T_cm/(πA) + K_θ N_θ(A, ω) + K_x + ρ N_T(A, ω) = 0.
 * The classical balance 1 + G N = 0 lumps the load into the motor (J = J_m + ρ²J_L, F = f_m + ρ²f_L):
 *   G(jω) = ρK_θ / (−ω²J + jωF + ρK_x)   (= thesisLoop · K_θ/K for K_x = 0).
 * When the law reads the motor alone (K_θ = 0) nothing lumped passes the backlash; the load's reaction through the
 * hysteresis does (the load follows θ_c = H(x), its torque L Θ_c with L = −ω²J_L + jωf_L):
 *   G(jω) = ρ²L / (M + ρK_x),  M = −ω²J_m + jωf_m.
 * An approximation beyond the DF's own: the sampled harmonics alias onto the fundamental — small while the cycle is
 * slow against the sampling, and the search stops at the Nyquist frequency π f_s. The band of frequencies searched is
 * [1e-4, 1e4] ω_n about the loop's ω_n = √(ρK/J) (loopNaturalFrequency; K = K_v K_p for the cascade).
 *
 * **A compliant mesh** (`mesh_stiffness` c > 0, `mesh_damping` d; rigid shaft): the teeth pass the torque
 * T = (c + jωd) N_dz(A) X in the fundamental, X the deflection x = ρθ_m − θ_c about its centre, N_dz the DF of a dead
 * zone of half-width Δ/2 (describing_function.h; a damper gated by the same contact has the same DF). The bodies
 * M Θ_m = U − ρT, L Θ_c = T with U = −K_θ Θ_c − K_x ρΘ_m give X = −G T,
 *   G(jω) = ρ(ρ + K_θ/L)/(M + ρK_x) + 1/L,
 * so the balance is (c + jωd) G(jω) N_dz(A) = −1 (compliantLoop): real N_dz, solutions where that product is real and
 * ≤ −1. A prediction's amplitude is ρθ_m's, |ρ(K_θ/L + ρ)/(G (M + ρK_x))| A. Motor Coulomb friction, the
 * never-pulling clip of the spring–damper law and a torsional shaft are outside it (a shaft is refused). The numerical
 * balance E = 0 then takes the compliant element's DFs (driven_mesh.h), started from these predictions and the rigid
 * teeth's.
 *
 * **The exact cycle.** The joint is run until its verdict settles (runResponse); on a limit cycle one more period
 * from the settled state is sampled at 4096 even points, and the fundamental of ρθ_m about its mean gives the
 * amplitude (peak: the largest excursion from the mean), the frequency 2π/period.
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

/// G(jω) of the loop's linear part under the continuous P law, as the backlash element sees it (see the file comment).
std::complex<double> thesisLoop(const ServoParams& params, double omega);

/// The drive law's torque in the fundamental at ω, per unit of each angle it reads: u = −K_θ Θ_c − K_x X, Θ_c the
/// load angle's fundamental, X = ρΘ_m the backlash input's (see the file comment).
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

/// G(jω) of the rigid teeth's loop with the configured law, as the hysteresis sees it (see the file comment) [-].
std::complex<double> loopResponse(const ServoParams& params, const DriveParams& drive, double omega);

/// G(jω) of a compliant mesh's loop as the dead zone of its penetration sees it (see the file comment) [-].
std::complex<double> compliantLoop(const ServoParams& params, const DriveParams& drive, double omega);

/// |ρΘ_m / X|: the backlash input's amplitude per unit of the mesh deflection's in that loop at ω [rad/s].
double compliantMotorAmplitude(const ServoParams& params, const DriveParams& drive, double omega);

/// E(A, ω) of the real element's balance [N·m/rad] (see the file comment): amplitude A [rad], ω [rad/s].
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
