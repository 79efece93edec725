#include "backlash_servo/simulation/steady_state.h"

#include <algorithm>
#include <cstdio>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
namespace
{
SteadyAnswer answerAt(double position, double command, SteadyBasis basis)
{
  SteadyAnswer a;
  a.position = position;
  a.error = position - command;
  a.basis = basis;
  return a;
}

/**
 * The Limit basis: a copy runs on in windows of h [s] (from a natural period, doubled while the moves shrink by less
 * than half a window) until, at a window's end, the load moved at most the tolerance, less than half its previous
 * window's move, and both bodies' speeds at the load shaft times h are within the tolerance — a geometric decay whose
 * remaining travel is then below its last move.
 */
SteadyAnswer runOnToLimit(const Simulator& sim, const DriveParams& drive, double command, double scale)
{
  Simulator copy = sim;
  copy.setSampleObserver(nullptr);  // (the copy's samples are nobody's readings)
  const ServoParams& p = copy.params();
  const double start = copy.state().time;
  const double budget = steadyBudget(p, drive);
  double h = TWO_PI / p.naturalFrequency();
  double previous_move = INFINITY;
  double move = INFINITY;
  try
  {
    while (copy.state().time - start < budget)
    {
      if (copy.atRestForever())
      {
        return answerAt(copy.state().load_position, command, SteadyBasis::Held);
      }
      const double from = copy.state().load_position;
      copy.advanceTo(copy.state().time + h);
      const State& s = copy.state();
      move = std::fabs(s.load_position - from);
      const double tolerance = LIMIT_TOLERANCE * std::max(std::fabs(s.load_position), scale);
      const bool still =
          std::fabs(s.load_velocity) * h <= tolerance && std::fabs(p.gear_ratio * s.motor_velocity) * h <= tolerance;
      if (move <= tolerance && still && (move == 0.0 || move < 0.5 * previous_move))
      {
        return answerAt(s.load_position, command, SteadyBasis::Limit);
      }
      if (move > 0.5 * previous_move)
      {
        h *= 2.0;  // a decay slow against the window: a longer one shows it
        previous_move = INFINITY;
      }
      else
      {
        previous_move = move;
      }
    }
  }
  catch (const EventBudgetExceeded& e)
  {
    SteadyAnswer a;
    a.basis = SteadyBasis::Unsettled;
    a.note = std::string("the event budget ran out while it settled: ") + e.what();
    return a;
  }
  catch (const MotionDiverged& e)
  {
    SteadyAnswer a;
    a.basis = SteadyBasis::Unsettled;
    a.note = std::string("the motion ran away while it settled: ") + e.what();
    return a;
  }
  SteadyAnswer a;
  a.basis = SteadyBasis::Unsettled;
  char buf[160];
  std::snprintf(buf, sizeof buf, "the load still moved %.3g rad in %.3g s after %.3g s more", move, h, budget);
  a.note = buf;
  return a;
}
}  // namespace

const char* steadyBasisName(SteadyBasis basis)
{
  switch (basis)
  {
    case SteadyBasis::Held:
      return "held";
    case SteadyBasis::Equilibrium:
      return "equilibrium";
    case SteadyBasis::Limit:
      return "limit";
    case SteadyBasis::Unsettled:
      return "unsettled";
    case SteadyBasis::None:
      break;
  }
  return "none";
}

bool hasClosedFormRest(const ServoParams& params, const DriveParams& drive)
{
  const bool ideal_load_sensor =
      !drive.sampled() || (drive.feedback != "motor" && drive.load_encoder_resolution == 0.0);
  return !params.hasDryFriction() && ideal_load_sensor && drive.compensation == "none";
}

double steadyBudget(const ServoParams& params, const DriveParams& drive)
{
  RunConfig c;
  c.params = params;
  c.drive = drive;
  return std::max(2000.0 / params.naturalFrequency(), 100.0 * std::max(driveTimeScale(c), plantTimeScale(params)));
}

SteadyAnswer steadyAnswer(const Simulator& sim, const DriveParams& drive, double command, double equilibrium,
                          double scale)
{
  if (sim.atRestForever())
  {
    return answerAt(sim.state().load_position, command, SteadyBasis::Held);
  }
  if (hasClosedFormRest(sim.params(), drive))
  {
    return answerAt(equilibrium, command, SteadyBasis::Equilibrium);
  }
  return runOnToLimit(sim, drive, command, scale);
}

}  // namespace backlash_servo
