/**
 * @file steady_state.h
 * @brief Where a converged joint comes to rest: the load's limit position θ_∞ [rad] and the steady error θ_∞ − θ_R
 *        [rad] — the limit, never the offset at the moment the verdict was decided. One answer for every tool, the
 *        node and Python; the run itself is never changed (a limit is found in a copy). Its basis (SteadyBasis): held
 *        by dry friction, the law's closed-form equilibrium, the limit of the load's geometric decay, or unsettled
 *        (NaN) — docs/cli.md, "The steady error". No ROS dependency.
 */
#pragma once

#include <cmath>
#include <string>

namespace backlash_servo
{
class Simulator;
struct DriveParams;
struct ServoParams;

/// How a steady answer was found (see the file comment).
enum class SteadyBasis
{
  None,         ///< the verdict is not converged: no steady answer
  Held,         ///< dry friction holds the joint for ever: its position, exact
  Equilibrium,  ///< the law's one rest position of the load, in closed form
  Limit,        ///< the load's position once its remaining travel is within rounding
  Unsettled     ///< still moving beyond rounding after steadyBudget(): no answer
};

/// "none", "held", "equilibrium", "limit", "unsettled".
const char* steadyBasisName(SteadyBasis basis);

/// The steady answer of a converged run.
struct SteadyAnswer
{
  double position = NAN;  ///< θ_∞, the load's rest position [rad]; NaN unless held, equilibrium or limit
  double error = NAN;     ///< θ_∞ − θ_R [rad]; NaN likewise
  SteadyBasis basis = SteadyBasis::None;
  /// For Unsettled: how far the load still moved in the last window [rad] and over what time [s], in words.
  std::string note;
};

/// The load's remaining travel counts as zero within this fraction of max(|θ_c|, scale).
constexpr double LIMIT_TOLERANCE = 1e-12;

/// Whether the law has one rest position of the load, loopEquilibrium() (the Equilibrium basis's conditions).
bool hasClosedFormRest(const ServoParams& params, const DriveParams& drive);

/// How long [s] a copy may run on for the Limit basis: max(2000/ω_n, 100 × the slowest time scale of the drive and
/// the plant) — the cap of a run until settled.
double steadyBudget(const ServoParams& params, const DriveParams& drive);

/**
 * The steady answer of a joint judged converged, at `sim`'s current state (the simulator is not changed).
 * @param drive the drive's settings (which law, which sensor the loop reads)
 * @param command θ_R [rad] (a profile's final value)
 * @param equilibrium loopEquilibrium() of the law [rad]
 * @param scale the judge's scale [rad] (ResponseMonitor::scale): sets the rounding of the Limit basis
 */
SteadyAnswer steadyAnswer(const Simulator& sim, const DriveParams& drive, double command, double equilibrium,
                          double scale);

}  // namespace backlash_servo
