/**
 * @file broadband_response.h
 * @brief The frequency response as a commissioning tool measures it in one go: a periodic broadband excitation
 *        (PRBS or chirp) sampled and held at the drive's rate, the output recorded at the same samples, and the H1
 *        estimate with its coherence per DFT line. The motion is exact (frequency_response.h: a held input keeps
 *        every mode closed-form). No ROS dependency.
 *
 * **Excitation** over a period of N samples at f_s (frequency_response.h's excitationRate), u_k = u₀ + A s_k:
 * - PRBS: a maximum-length binary sequence of order n (N = h(2ⁿ − 1), each bit held h samples), s_k = ±1 — a flat
 *   spectrum up to about f_s/(2h);
 * - chirp: s_k = sin(2π(k₀ k/N + (k₁ − k₀) k²/(2N²))), a linear sweep from DFT line k₀ to k₁ (k₁ − k₀ even, so the
 *   phase closes on a whole turn and the periodic sequence has no jump).
 * The first `settle_periods` periods let the transient decay (by default as many as cover AUTO_SETTLING_SCALES of the
 * joint's slowest time constant, at least 2); then `periods` periods are recorded.
 *
 * **Estimate.** Each recorded period p gives the DFTs U_p(k), Y_p(k) of the input sequence and of the output sampled
 * at the same instants (y_k: θ_c, ω_m or ω_c at t_k, as the drive's own recording would read it). Per line k
 * (ω_k = 2π k f_s/N [rad/s], over the lines the excitation carries):
 *   H1 = Σ_p Y_p U_p* / Σ_p |U_p|²,   γ² = |Σ_p Y_p U_p*|² / (Σ_p |U_p|² Σ_p |Y_p|²)  (coherence, in [0, 1]).
 * For a linear joint in its periodic steady state, H1 is the sampled-data transfer function from u_k to y_k at
 * z = e^{jω_k/f_s} and γ² = 1; backlash makes the response depend on the excitation and, where it does not repeat
 * from period to period (the joint's own limit cycle, chaotic impacts), lowers γ² — what a drive's tool shows. The
 * rectangular window is exact here: every period holds whole periods of every line.
 */
#pragma once

#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "backlash_servo/frequency/frequency_response.h"

namespace backlash_servo
{
enum class BroadbandKind
{
  Prbs,
  Chirp
};

struct BroadbandSettings
{
  FrfChannel channel = FrfChannel::CommandToLoadPosition;
  BroadbandKind kind = BroadbandKind::Prbs;
  double offset = 0.0;          ///< u₀ [rad or N·m]
  double injection_rate = 0.0;  ///< torque channels [Hz] (frequency_response.h's excitationRate)
  int prbs_order = 10;          ///< n, in [3, 20]: period h(2ⁿ − 1) samples
  int prbs_hold = 1;            ///< h ≥ 1: samples each bit is held
  double chirp_low = 0.0;       ///< chirp: lowest frequency [rad/s] (placed on a DFT line ≥ 1)
  double chirp_high = 0.0;      ///< chirp: highest frequency [rad/s] (≤ f_s/4 in rad/s)
  int chirp_samples = 4096;     ///< chirp: N, samples per period (≥ 16)
  int settle_periods = 0;       ///< periods run before recording; 0: automatic, AUTO_SETTLING_SCALES of the
                                ///< channel's slowestTimeScale (at least 2)
  int periods = 8;              ///< periods recorded and averaged (≥ 1)
};

/// One DFT line of the estimate.
struct BroadbandLine
{
  double frequency = 0.0;    ///< ω_k [rad/s]
  std::complex<double> h1;   ///< H1 [output unit per input unit]
  double coherence = 0.0;    ///< γ² [-]
  double input_power = 0.0;  ///< Σ_p |U_p(k)|² / periods: how much the excitation carries there [(input unit)²]
};

struct BroadbandResponse
{
  int samples_per_period = 0;        ///< N
  double sample_rate = 0.0;          ///< f_s [Hz]
  int settle_periods = 0;            ///< periods run before recording (the automatic choice, or as set)
  std::vector<BroadbandLine> lines;  ///< ascending frequency, the lines the excitation carries
};

/**
 * Runs the joint under the broadband excitation of amplitude A (> 0) [rad or N·m] and returns H1 and γ² per line.
 * Throws InvalidParameterError for bad settings (naming them) or a channel the configuration cannot take.
 * `progress`, if given, is called with the fraction of the run done.
 */
BroadbandResponse measureBroadband(const RunConfig& config, const BroadbandSettings& settings, double amplitude,
                                   const std::function<void(double)>& progress = nullptr);

/// The PRBS's ±1 sequence of order n (length 2ⁿ − 1), from a maximal-length linear feedback shift register.
std::vector<int> maximumLengthSequence(int order);

}  // namespace backlash_servo
