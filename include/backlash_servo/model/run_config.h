/**
 * @file run_config.h
 * @brief One run's configuration as plain data: the joint, the drive, the initial state, the set-point (a step or
 *        a profile), how long to run and what to gather. SI units: rad, s, J. Validated by the configuration
 *        loader (config/run_config_loader.h); run by runResponse() (simulation/step_response.h).
 */
#pragma once

#include <memory>

#include "backlash_servo/model/drive_params.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"

namespace backlash_servo
{
class CommandProfile;  // drive/command_profile.h: θ_R(t) as segments

struct RunConfig
{
  ServoParams params;
  DriveParams drive;           ///< the control law (default: the thesis' continuous P law)
  State initial;               ///< default: everything 0, forward contact
  double command = 1.0;        ///< θ_R [rad], applied at the initial time
  double duration = 0.0;       ///< simulate exactly this long [s]; 0 = until the verdict is settled
  double max_duration = 0.0;   ///< cap when running until settled [s]; 0 = 2000/ω_n
  bool track_energy = true;    ///< energy ledger (off: ~25 % faster, energy fields of the summary are zero)
  double max_events = 1e7;     ///< impact budget of the run; exceeded → stopped, verdict unsettled (not a hang)
  double settling_band = 0.0;  ///< error band of the settling figures [rad]; 0 = settlingBand()'s default
  bool short_flights = true;   ///< the chatter fast path (short_flight.h); off only to compare (bench_core)
  /// The tracking figures (RunSummary::tracking) gathered in the run's own pass, as replayTracking() gives them.
  bool tracking = false;
  /// The steady answer of a converged run (RunSummary::steady, steady_state.h); off only where nobody reads it.
  bool steady_answer = true;
  /// Optional set-point profile θ_R(t); the verdict is judged from its end on, against its final value (a run until
  /// settled lasts at least to its end). A digital drive samples any profile; the continuous law takes steps, points
  /// and (without dry friction) ramps exactly (Simulator::setProfile), sines with a compliant mesh, and refuses moves
  /// and, with rigid teeth, sines
  /// (InvalidParameterError from runResponse()); after a ramp under it the energy fields are NaN (the frame's ledger).
  /// With a profile, `command` is its final value.
  std::shared_ptr<const CommandProfile> profile;
};
}  // namespace backlash_servo
