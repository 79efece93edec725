// The rigid plant's impacts (plant.h): a flank reached in the free play — the teeth snapped onto it, Newton's
// restitution through the impact map (impact.h), made plastic where the rebound could not rise above rounding — and
// chatter, the run of short flights and impacts taken without the general segment (bit-identical to it).
#include <cmath>
#include <cstdio>

#include "backlash_servo/plant/plant.h"
#include "backlash_servo/rigid/impact.h"
#include "plant/plant_detail.h"

namespace backlash_servo
{
using plant_detail::FREE_SEARCH_PERIODS;
using plant_detail::loadTurnaround;

void Plant::chatter(double t_end, EventSink* sink, bool report)
{
  // What advanceTo's loop does for each flight segment ending before t_end, without the segment: the same checks,
  // build, evaluation and impact in the same order (bit-identical). Anything else goes back to the loop. Skipped:
  // impactNow() — each state here comes out of handleImpact() apart, the teeth leaving the wall they are on (a
  // rebound, or moving away), so no impact is due at once unless the other wall lies within rounding, where the
  // flight's build refuses (Δ ≤ 4 × its rounding bound) and the loop decides.
  if (dry_ || !(std::isinf(watch_lo_) && std::isinf(watch_hi_)) || !flight_model_)
  {
    return;
  }
  const double window = FREE_SEARCH_PERIODS * period_;
  ShortFlight f;  // rebuilt per impact (nothing initialised on construction)
  while (state_.contact == Contact::Apart && state_.time < t_end)
  {
    requireBounded();
    // With the ledger kept the flight's series stays for its energy flows; else only the state at the impact is
    // formed, in place (the start kept in case the flight is handed back to the loop).
    const State start = state_;
    const double horizon = searchWindow(window);
    if (!(track_energy_ ? f.build(*flight_model_, state_, horizon)
                        : f.flyToImpact(*flight_model_, state_, horizon, &state_)))
    {
      return;
    }
    const double tau = f.impactTime();
    if (start.time + tau > t_end || loadTurnaround(params_, start.load_velocity, tau) <= tau)
    {
      state_ = start;
      return;  // ends beyond t_end, or a maximum inside: the loop's segment keeps it
    }
    ++short_flight_count_;
    if (track_energy_)
    {
      addFlows(f.energy(tau));
      f.at(tau, &state_);
    }
    state_.time += tau;
    handleImpact(f.wall(), sink, report);
  }
}

double Plant::impactNow(Contact* wall) const
{
  if (state_.contact != Contact::Apart)
  {
    return INFINITY;
  }
  const double g = mesh_.gap(state_.load_position, state_.motor_position);
  const double v = state_.load_velocity, w = state_.motor_velocity;
  const double rounding = 1e-12 * (std::fabs(v) + std::fabs(params_.gear_ratio * w));
  for (Contact side : {Contact::Forward, Contact::Backward})
  {
    const bool on_wall = side == Contact::Forward ? g <= 0.0 : g >= params_.backlash;
    if (on_wall && mesh_.closingSpeed(side, v, w) > rounding)
    {
      *wall = side;
      return 0.0;
    }
  }
  return INFINITY;
}

void Plant::settleOnWall(Contact wall)
{
  state_.motor_velocity = mesh_.motorVelocityInContact(state_.load_velocity);
  if (dry_)
  {
    state_.contact = wall;  // the next segment decides with friction (chooseDryMode)
    return;
  }
  // With Δ = 0 there is no floating: if this flank does not press, the other one (the same gap) does.
  state_.contact = contactHolds(params_, law_, state_.load_position, state_.load_velocity, wall)
                       ? wall
                       : mesh_.afterSeparation(wall);
}

void Plant::throwImpactBudget() const
{
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "event budget of %llu impacts exceeded at t = %.9g s (an impact storm; raise max_events to go on)",
                static_cast<unsigned long long>(event_budget_), state_.time);
  throw EventBudgetExceeded(buf);
}

void Plant::handleImpact(Contact wall, EventSink* sink, bool report)
{
  const double rho = params_.gear_ratio;
  const double delta = params_.backlash;
  // Snap onto the wall (moves θ_m by rounding).
  state_.motor_position = mesh_.motorPositionOnWall(state_.load_position, wall);
  const double v = state_.load_velocity;
  const double w = state_.motor_velocity;
  if (delta == 0.0 && mesh_.closingSpeed(wall, v, w) < 0.0)
  {
    wall = GearMesh::otherWall(wall);  // rigid mesh: leaving one flank is running into the other
  }
  const double closing = mesh_.closingSpeed(wall, v, w);  // > 0: teeth approach
  // "Numerically zero" relative speed s: below rounding of the velocities, or so small that the bounce it would start
  // against the pressing mesh torque could not rise above the rounding of the gap (h = s²/2a); squares compared, and
  // the mesh torque computed only when the first test does not decide.
  const double speed_noise = 64.0 * EPS * (std::fabs(v) + rho * std::fabs(w));
  const double gap_noise =
      64.0 * EPS * (std::fabs(state_.load_position) + rho * std::fabs(state_.motor_position) + delta);
  auto bounce_floor = [&]() {  // s² of a bounce rising to the gap noise: 2 a h
    return 2.0 * gap_noise * std::fabs(contactMeshTorque(params_, law_, state_.load_position, v)) * press_factor_;
  };
  // s² > the floor, tested on the floor's bound first (no division): most speeds — every rebound of a chatter — are
  // decided without computing the floor (the same decisions: the bound is above the floor's computed value).
  auto above_floor = [&](double s) {
    return s * s > 2.0 * gap_noise * mesh_bound_(law_.torque(state_.load_position), v) * press_factor_ ||
           s * s > bounce_floor();
  };
  if (!(closing > 0.0) && -closing > speed_noise && above_floor(-closing))
  {
    state_.contact = Contact::Apart;  // clearly moving away: only rounding put the gap on the wall
    return;
  }
  // A touch without closing (rounding) or a closing speed the stick rule calls zero is made plastic; so is every
  // impact of a rigid mesh (Δ = 0, e.g. the backlash tuned to 0 while the teeth float): no room to bounce into.
  const double rebound = params_.restitution * closing;
  const bool plastic = delta == 0.0 || rebound <= speed_noise || !above_floor(rebound);
  const ImpactMap& impact = plastic ? plastic_impact_ : elastic_impact_;
  const double e = impact.restitution();
  const ImpactOutcome o = impact(v, w);
  state_.load_velocity = o.load_velocity;
  state_.motor_velocity = o.motor_velocity;
  energy_.impact_loss += o.energy_loss;
  if (!(closing > 0.0))
  {
    settleOnWall(wall);  // not an impact: nothing counted or reported
    return;
  }
  ++impacts_;
  if (event_budget_ != 0 && impacts_ > event_budget_)
  {
    throwImpactBudget();
  }
  if (e == 0.0)
  {
    settleOnWall(wall);
  }
  else
  {
    state_.contact = Contact::Apart;
  }
  if (report)
  {
    ImpactInfo info;
    info.wall = wall;
    info.load_velocity_before = v;
    info.load_velocity_after = o.load_velocity;
    info.motor_velocity_before = w;
    info.motor_velocity_after = o.motor_velocity;
    info.approach_speed = closing;
    info.impulse = o.impulse;
    info.energy_loss = o.energy_loss;
    info.stuck = state_.contact != Contact::Apart;
    emit(sink, EventType::Impact, &info);
  }
  if (v > 0.0 && o.load_velocity <= 0.0)
  {
    emit(sink, EventType::Maximum);
  }
  else if (v < 0.0 && o.load_velocity >= 0.0)
  {
    emit(sink, EventType::Minimum);
  }
}

}  // namespace backlash_servo
