/**
 * @file broadband_response.h
 * @brief The frequency response as a commissioning tool measures it in one go: a periodic broadband excitation
 *        (PRBS or chirp, u_k = u₀ + A s_k [N·m or rad]) held at the drive's rate, the output sampled at the same
 *        instants, and per DFT line ω_k [rad/s] the H1 estimate with its coherence γ² in [0, 1]. The motion is exact
 *        (a held input keeps every mode closed-form); for a linear joint in its periodic steady state H1 is the
 *        sampled-data transfer function at z = e^{jω_k/f_s} and γ² = 1. Excitations, settling and the estimate:
 *        docs/frequency_response.md, "Broadband: PRBS and chirp, H1 and coherence". No ROS dependency.
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
