// The rigid plant's dry friction (plant.h, docs/model.md Part 2): the rest rule at a body's stop (stick, or slide on),
// the segments in which one body or both are stuck, breakaway, and the held torque range in which a digital drive's
// samples are taken in blocks.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <memory>
#include <utility>

#include "backlash_servo/plant/plant.h"
#include "plant/plant_detail.h"

namespace backlash_servo
{
using plant_detail::CONTACT_SEARCH_PERIODS;
using plant_detail::FREE_SEARCH_PERIODS;

bool Plant::heldUnder(double torque) const
{
  const RestDecision d = decideAtRest(params_, torque, state_);
  return d.motor == 0 && d.load == 0 && d.contact == state_.contact;
}

bool Plant::heldTorqueRange(double* lo, double* hi, double* until) const
{
  if (compliant_.joint)
  {
    *until = INFINITY;  // (nothing moves and no torque on a body changes until the motor's does)
    return compliantHeld(lo, hi);
  }
  if (!dry_ || forced_motor_breakaway_ != 0 || !segmentHeld())
  {
    return false;
  }
  const double now = law_.torque(state_.load_position);
  if (!heldUnder(now))
  {
    return false;
  }
  const double rho = params_.gear_ratio;
  const double pair = (rho * params_.motor_static_friction + rho * rho * params_.load_static_friction) / rho;
  const double preload = rho * params_.load_torque;  // ρ²τ_L referred to the motor shaft
  std::array<double, 4> ends = {-params_.motor_static_friction, params_.motor_static_friction, -pair - preload,
                                pair - preload};
  std::sort(ends.begin(), ends.end());
  const auto inside = [now](double end) { return end - 1e-9 * (end - now); };  // pulled towards the torque now
  *lo = *hi = now;
  for (double end : ends)  // ascending: the ends above the torque now, nearest first
  {
    if (end > now)
    {
      if (!heldUnder(inside(end)))
      {
        break;
      }
      *hi = inside(end);
    }
  }
  for (auto it = ends.rbegin(); it != ends.rend(); ++it)  // descending: the ends below
  {
    if (*it < now)
    {
      if (!heldUnder(inside(*it)))
      {
        break;
      }
      *lo = inside(*it);
    }
  }
  *until = segment_->start.time + segment_->end_tau;
  return true;
}

void Plant::chooseDryMode(EventSink* sink, Slide* motor, Slide* load)
{
  State& s = state_;
  if (s.contact != Contact::Apart && s.load_velocity != 0.0)
  {
    // The pair slides: does the contact hold with its kinetic friction?
    const Slide dir = s.load_velocity > 0.0 ? 1 : -1;
    *motor = dir;
    *load = dir;
    ServoParams folded;
    MotorInput law;
    foldKineticFriction(params_, law_, dir, dir, &folded, &law);
    if (rigid_flip_time_ == s.time || contactHolds(folded, law, s.load_position, s.load_velocity, s.contact))
    {
      return;
    }
    s.contact = mesh_.afterSeparation(s.contact);  // Δ = 0: the other flank, the pair still sliding
    emit(sink, EventType::Separation);
    if (s.contact == Contact::Apart)
    {
      *motor = slideOf(s.motor_velocity, dir);
    }
    return;
  }
  if (s.contact != Contact::Apart)
  {
    s.motor_velocity = 0.0;  // the pair at rest
  }
  RestDecision d = decideAtRest(params_, law_.torque(s.load_position), s);
  if (forced_motor_breakaway_ != 0 && s.motor_velocity == 0.0 && d.contact == Contact::Apart)
  {
    d.motor = forced_motor_breakaway_;  // pulled free at a located event: rounding must not re-stick it there
  }
  forced_motor_breakaway_ = 0;
  if (d.contact == Contact::Apart && s.contact != Contact::Apart)
  {
    s.contact = Contact::Apart;
    emit(sink, EventType::Separation);
  }
  else if (d.contact != Contact::Apart)
  {
    s.contact = d.contact;
  }
  *motor = d.motor;
  *load = d.load;
}

void Plant::beginDrySegment(Slide motor, Slide load)
{
  const double period = period_;
  Segment& seg = openSegment();
  seg.dry = true;
  seg.motor_slide = motor;
  seg.load_slide = load;
  const bool motor_dry = params_.motor_static_friction > 0.0 || params_.motor_coulomb_friction > 0.0;
  const bool load_dry = params_.load_static_friction > 0.0 || params_.load_coulomb_friction > 0.0;
  auto finish = [&](double window, std::initializer_list<std::pair<double, Segment::End>> ends) {
    seg.end_tau = window;
    seg.end = Segment::End::Restart;
    for (const auto& e : ends)
    {
      if (e.first <= seg.end_tau && (e.first < seg.end_tau || seg.end == Segment::End::Restart))
      {
        seg.end_tau = e.first;
        seg.end = e.second;
      }
    }
    applyWatch(seg);
    if (state_.contact == Contact::Apart && !load_dry)
    {
      markLoadTurnaround(seg);  // a dry load's turnaround is its rest (and a held load has none)
    }
  };
  if (motor == 0 && load == 0)
  {
    // Everything stuck (apart, or the pair pressed together): nothing moves until an input changes.
    seg.stuck.emplace(params_, law_, state_, StuckMotion::Moving::None, 0);
    finish(INFINITY, {});
    return;
  }
  if (state_.contact != Contact::Apart)
  {
    ServoParams folded;
    MotorInput law;
    foldKineticFriction(params_, law_, motor, load, &folded, &law);
    const ContactMotion& m = seg.contact.emplace(folded, law, state_.load_position, state_.load_velocity);
    const double window = searchWindow(CONTACT_SEARCH_PERIODS * period);
    seg.rest_motor = false;
    finish(window, {{m.separationTime(GearMesh::pressingSign(state_.contact), window), Segment::End::Separation},
                    {m.restTime(motor, window), Segment::End::Rest}});
    return;
  }
  const double free_window = FREE_SEARCH_PERIODS * period;  // accuracy window of the apart closed form
  const double window = searchWindow(free_window);          // events are searched up to the drive's next sample
  Contact wall = Contact::Forward;
  if (motor != 0 && load != 0)
  {
    ServoParams folded;
    MotorInput law;
    foldKineticFriction(params_, law_, motor, load, &folded, &law);
    if (short_flights_ && impactNow(&wall) != 0.0)
    {
      // A short chatter flight with both bodies sliding: the kinetic friction is a constant torque in the model.
      ShortFlight& f = seg.flight.emplace();
      if (f.build(ShortFlight::Model(folded, law), state_, window))
      {
        const double impact = f.impactTime();
        const double motor_rest = motor_dry ? f.restTime(true, motor, impact) : INFINITY;
        const double load_rest = load_dry ? f.restTime(false, load, impact) : INFINITY;
        if (!std::isnan(motor_rest) && !std::isnan(load_rest))
        {
          ++short_flight_count_;
          seg.wall = f.wall();
          seg.rest_motor = motor_rest < load_rest;
          finish(window, {{impact, Segment::End::Impact}, {std::min(motor_rest, load_rest), Segment::End::Rest}});
          return;
        }
      }
      seg.flight.reset();
    }
    double impact, motor_rest = INFINITY, load_rest = INFINITY;
    auto search = [&](const auto& m) {
      impact = firstImpact(m, window, &wall);
      motor_rest = motor_dry ? m.restTime(true, motor, window) : INFINITY;
      load_rest = load_dry ? m.restTime(false, load, window) : INFINITY;
    };
    if (apartNeedsSeries(folded, free_window))
    {
      seg.wide = std::make_shared<const WideFreeMotion>(folded, law, state_, free_window);
      search(*seg.wide);
    }
    else
    {
      search(seg.free.emplace(folded, law, state_, free_window));
    }
    seg.wall = wall;
    seg.rest_motor = motor_rest < load_rest;
    finish(window, {{impact, Segment::End::Impact}, {std::min(motor_rest, load_rest), Segment::End::Rest}});
    return;
  }
  // One body slides, the other is held by its static friction.
  const bool motor_moves = motor != 0;
  const StuckMotion& m =
      seg.stuck.emplace(params_, law_, state_, motor_moves ? StuckMotion::Moving::Motor : StuckMotion::Moving::Load,
                        motor_moves ? motor : load);
  const double impact = firstImpact(m, window, &wall);
  seg.wall = wall;
  seg.rest_motor = motor_moves;
  const bool moving_dry = motor_moves ? motor_dry : load_dry;
  finish(window, {{impact, Segment::End::Impact},
                  {moving_dry ? m.restTime(window) : INFINITY, Segment::End::Rest},
                  {m.breakawayTime(window), Segment::End::Breakaway}});
}

void Plant::countSwitch()
{
  if (event_budget_ != 0 && ++switches_ > event_budget_)
  {
    char buf[240];
    std::snprintf(buf, sizeof buf,
                  "event budget of %llu rests and law switches exceeded at t = %.9g s (a sliding mode: the joint "
                  "sticks and slips at a switch of the law, e.g. a feed-forward dead band's edge; raise max_events "
                  "to go on)",
                  static_cast<unsigned long long>(event_budget_), state_.time);
    throw EventBudgetExceeded(buf);
  }
}

void Plant::handleRest(const Segment& seg, EventSink* sink)
{
  countSwitch();
  if (seg.end == Segment::End::Breakaway)
  {
    forced_motor_breakaway_ = law_.torque(state_.load_position) > 0.0 ? 1 : -1;
    emit(sink, EventType::Rest);
    return;
  }
  const bool load_stops = !seg.rest_motor;
  if (state_.contact != Contact::Apart)
  {
    state_.load_velocity = 0.0;
    state_.motor_velocity = 0.0;
  }
  else if (seg.rest_motor)
  {
    state_.motor_velocity = 0.0;
  }
  else
  {
    state_.load_velocity = 0.0;
  }
  if (load_stops && seg.load_slide != 0)
  {
    // a turning point of θ_c where the load comes to rest (docs/model.md Part 2)
    emit(sink, seg.load_slide > 0 ? EventType::Maximum : EventType::Minimum);
  }
  emit(sink, EventType::Rest);
}

}  // namespace backlash_servo
