/**
 * @file step_response.h
 * @brief One complete run: simulate a response, watch its maxima, stop when the limit-cycle verdict is settled.
 *
 * Shared by backlash_sim, the sweep and design tools and the benchmarks, so they all judge a run the same way.
 * No ROS dependency.
 */
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "backlash_servo/response_monitor.h"
#include "backlash_servo/simulator.h"

namespace backlash_servo
{
struct RunConfig
{
  ServoParams params;
  State initial;              ///< default: everything 0, forward contact
  double command = 1.0;       ///< θ_R [rad], applied at the initial time
  double duration = 0.0;      ///< simulate exactly this long [s]; 0 = until the verdict is settled
  double max_duration = 0.0;  ///< cap when running until settled [s]; 0 = 2000/ω_n
  bool track_energy = true;   ///< energy ledger (off: ~25 % faster, energy fields of the summary are zero)
};

struct RunSummary
{
  LimitCycleReport status;
  std::vector<Maximum> maxima;  ///< positive maxima above the command, in time order
  std::uint64_t impacts = 0;
  EnergyLedger energy;
  double kinetic = 0.0;        ///< kinetic energy at the end [J]
  double balance_error = 0.0;  ///< energy balance residual [J]
  State final_state;
  double simulated = 0.0;  ///< simulated time [s]
  bool settled = false;    ///< the verdict was settled (not cut off by the duration or the cap)
};

/// Called at every sample time (sample_period > 0) with the simulator positioned there.
using SampleCallback = std::function<void(const Simulator&)>;

/**
 * Runs config; events go to sink (may be null) as well as to the response monitor (checked every natural period,
 * or at every sample); samples every
 * sample_period [s] (0 = none) go to on_sample. Throws InvalidParameterError on bad parameters.
 */
RunSummary runResponse(const RunConfig& config, EventSink* sink = nullptr, double sample_period = 0.0,
                       const SampleCallback& on_sample = nullptr);

}  // namespace backlash_servo
