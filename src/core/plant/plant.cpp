#include "backlash_servo/plant/plant.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/rigid/impact.h"
#include "compliant/compliant_joint.h"
#include "plant/plant_detail.h"

namespace backlash_servo
{
using plant_detail::CONTACT_SEARCH_PERIODS;
using plant_detail::FREE_SEARCH_PERIODS;
using plant_detail::loadTurnaround;

namespace
{
/// Iterations without advancing time before the simulator declares a bug instead of hanging.
constexpr int MAX_STALLED_ITERATIONS = 10000;

/// (J_m + ρ²J_L)/(J_m J_L) [1/(kg·m²)]: the relative acceleration of the teeth per unit of mesh torque.
double pressFactor(const ServoParams& p)
{
  const double rho = p.gear_ratio;
  return (p.motor_inertia + rho * rho * p.load_inertia) / (p.motor_inertia * p.load_inertia);
}

/// Whether Impact events are built for `sink` (there is one, and it reads them).
bool reportsImpacts(const EventSink* sink)
{
  return sink != nullptr && sink->wantsImpacts();
}
}  // namespace

const char* toString(Contact c)
{
  switch (c)
  {
    case Contact::Forward:
      return "forward";
    case Contact::Backward:
      return "backward";
    default:
      return "apart";
  }
}

Contact contactFromString(const std::string& s)
{
  if (s == "forward")
  {
    return Contact::Forward;
  }
  if (s == "backward")
  {
    return Contact::Backward;
  }
  if (s == "apart" || s == "none")
  {
    return Contact::Apart;
  }
  throw std::invalid_argument("contact must be forward, backward or none (got '" + s + "')");
}

const char* toString(EventType t)
{
  switch (t)
  {
    case EventType::Impact:
      return "impact";
    case EventType::Separation:
      return "separation";
    case EventType::Maximum:
      return "maximum";
    case EventType::Minimum:
      return "minimum";
    case EventType::Rest:
      return "rest";
    case EventType::Engagement:
      return "engagement";
    case EventType::InputChange:
      return "input_change";
    default:
      return "parameter_change";
  }
}

Plant::Plant(const ServoParams& params, const State& initial, const MotorInput& law) : params_(params), law_(law)
{
  params_.validate();
  deriveConstants();
  if (params_.compliant())
  {
    state_ = initial;
    beginCompliant();
  }
  setState(initial);
  if (!params_.compliant() && law_.wave.active())
  {
    enterWave(law_);
  }
}

void Plant::deriveConstants()
{
  dry_ = params_.hasDryFriction();
  mesh_ = GearMesh(params_);
  period_ = 2.0 * PI / params_.naturalFrequency();
  apart_needs_series_ = apartNeedsSeries(params_, FREE_SEARCH_PERIODS * period_);
  press_factor_ = pressFactor(params_);
  mesh_bound_ = MeshTorqueBound(params_);
  elastic_impact_ = ImpactMap(params_, params_.restitution);
  plastic_impact_ = ImpactMap(params_, 0.0);
}

void Plant::setState(const State& s)
{
  requireFinite("time", s.time);
  requireFinite("load_position", s.load_position);
  requireFinite("load_velocity", s.load_velocity);
  requireFinite("motor_position", s.motor_position);
  requireFinite("motor_velocity", s.motor_velocity);
  if (params_.compliant())
  {
    requireFinite("shaft_twist", s.shaft_twist);
    requireFinite("shaft_twist_rate", s.shaft_twist_rate);
    state_ = s;
    energy_ = EnergyLedger();
    impacts_ = 0;
    switches_ = 0;
    stateToCompliant();  // the joint's fresh ledger comes back with the state
    return;
  }
  const double rho = params_.gear_ratio;
  const double delta = params_.backlash;
  const double g = mesh_.gap(s.load_position, s.motor_position);
  const double tol = 1e-9 * std::max({1.0, std::fabs(s.load_position), delta});
  State n = s;
  if (s.contact != Contact::Apart)
  {
    const double wall = mesh_.wallGap(s.contact);
    if (std::fabs(g - wall) > tol)
    {
      throw InvalidParameterError("motor_position",
                                  std::string("in ") + toString(s.contact) + " contact the gap θ_c − ρθ_m must be " +
                                      (wall == 0.0 ? "0" : "Δ") + " (got " + std::to_string(g) + " rad)");
    }
    if (std::fabs(s.load_velocity - rho * s.motor_velocity) > 1e-9 * std::max(1.0, std::fabs(s.load_velocity)))
    {
      throw InvalidParameterError("motor_velocity", "in contact the teeth move together: ρ ω_m must equal ω_c");
    }
    n.motor_position = mesh_.motorPosition(s.load_position, wall);
    n.motor_velocity = mesh_.motorVelocityInContact(s.load_velocity);
  }
  else
  {
    if (g < -tol || g > delta + tol)
    {
      throw InvalidParameterError("motor_position",
                                  "gap θ_c − ρθ_m = " + std::to_string(g) + " rad lies outside [0, backlash]");
    }
    n.motor_position = mesh_.motorPosition(s.load_position, std::min(std::max(g, 0.0), delta));
  }
  state_ = n;
  restartSegment();
  forced_motor_breakaway_ = 0;
  energy_ = EnergyLedger();
  impacts_ = 0;
  switches_ = 0;
  if (compliant_.joint)
  {
    // Rigid teeth carrying a sine: the joint goes on from the new state.
    wave_base_ = EnergyLedger();
    wave_balance_ = 0.0;
    stateToCompliant();
  }
  energy_.initial_kinetic = kineticEnergy();
}

void Plant::setLaw(const MotorInput& law)
{
  if (!params_.compliant() && (law.wave.active() || load_wave_.active()) != static_cast<bool>(compliant_.joint))
  {
    // Rigid teeth: a law with a sine is carried by the joint's closed forms from now on, one without by the thesis
    // modes again (plant_compliant.cpp) — unless the load's torque carries a sine.
    if (law.wave.active())
    {
      enterWave(law);
      return;
    }
    law_ = law;
    leaveWave();
  }
  law_ = law;
  flight_model_.reset();
  if (compliant_.joint)
  {
    watchCompliant();  // the law and the watch go to the joint together
    return;
  }
  // A digital drive's new sample on a joint held by stiction (stick–slip phases: most samples): if the rest rule
  // still holds everything, the held segment is exactly what a new one would be.
  if (dry_ && segmentHeld() && forced_motor_breakaway_ == 0 && heldUnder(law_.torque(state_.load_position)))
  {
    return;
  }
  restartSegment();
}

void Plant::setParams(const ServoParams& params, EventSink* sink, bool frame)
{
  if (!frame)
  {
    params.validate();
  }
  if (params_.compliant() || params.compliant())
  {
    setCompliantParams(params, sink, frame);
    return;
  }
  if (compliant_.joint)
  {
    // Rigid teeth carrying a sine: the thesis modes take the change, the joint the motion again after it.
    requireExactWave(params, "a sine");
    leaveWave();
    const MotorInput law = law_;
    setParams(params, sink, frame);
    enterWave(law);
    return;
  }
  restartSegment();  // the closed form restarts from the state now
  const double balance_before = energyBalanceError();
  const double old_gap = gap();
  const double old_delta = params_.backlash;
  params_ = params;
  flight_model_.reset();
  forced_motor_breakaway_ = 0;
  deriveConstants();
  const double delta = params_.backlash;
  // θ_c and ω_c are kept; the motor is re-expressed on the new mesh with the gap clamped into [0, Δ].
  double g = std::min(std::max(old_gap, 0.0), delta);
  if (state_.contact == Contact::Forward)
  {
    g = 0.0;
  }
  if (state_.contact == Contact::Backward)
  {
    if (delta > old_delta)
    {
      state_.contact = Contact::Apart;  // Δ grew: the teeth float at relative rest inside the larger gap
    }
    else
    {
      g = delta;  // still on the flank (a gap read from the positions may differ from Δ in its last bits)
    }
  }
  state_.motor_position = mesh_.motorPosition(state_.load_position, g);
  if (state_.contact != Contact::Apart)
  {
    state_.motor_velocity = mesh_.motorVelocityInContact(state_.load_velocity);
  }
  else if (old_gap < 0.0 || old_gap > delta || (g == delta && delta == 0.0))
  {
    // Δ shrank below the gap: the wall now touches the teeth; closing teeth collide, resting ones settle.
    handleImpact(g == 0.0 ? Contact::Forward : Contact::Backward, sink, reportsImpacts(sink));
  }
  // A parameter change is not a physical process: re-base the kinetic energy so the ledger keeps its balance.
  energy_.initial_kinetic = kineticEnergy() - energy_.input - energy_.load_work + energy_.motor_friction +
                            energy_.load_friction + energy_.motor_dry_friction + energy_.load_dry_friction +
                            energy_.impact_loss + balance_before;
  emit(sink, EventType::ParameterChange);
}

double Plant::meshTorque() const
{
  if (compliant_.joint)
  {
    return compliantMeshTorque();
  }
  if (dry_ && state_.contact != Contact::Apart)
  {
    // The kinetic friction of the sliding pair is part of the load's balance (at rest: the static share is not
    // determined by the model; reported without it).
    const Slide dir = slideOf(state_.load_velocity, 0);
    ServoParams folded;
    MotorInput law;
    foldKineticFriction(params_, law_, dir, dir, &folded, &law);
    return backlash_servo::meshTorque(folded, law, state_);
  }
  return backlash_servo::meshTorque(params_, law_, state_);
}

void Plant::setEnergyTracking(bool on)
{
  track_energy_ = on;
  if (compliant_.joint)
  {
    compliantEnergyTracking();
  }
}

double Plant::kineticEnergy() const
{
  if (compliant_.joint)
  {
    return compliantKineticEnergy();
  }
  return 0.5 * params_.motor_inertia * state_.motor_velocity * state_.motor_velocity +
         0.5 * params_.load_inertia * state_.load_velocity * state_.load_velocity;
}

double Plant::energyBalanceError() const
{
  syncLedger();
  if (compliant_.joint)
  {
    return compliantBalanceError();
  }
  return energy_.input + energy_.load_work - energy_.motor_friction - energy_.load_friction -
         energy_.motor_dry_friction - energy_.load_dry_friction - energy_.impact_loss -
         (kineticEnergy() - energy_.initial_kinetic);
}

void Plant::emit(EventSink* sink, EventType type, const ImpactInfo* impact) const
{
  if (sink == nullptr)
  {
    return;
  }
  Event e;
  e.type = type;
  e.state = state_;
  e.law = law_;
  if (compliant_.joint)
  {
    e.mesh_torque = compliantMeshTorque();
  }
  if (impact != nullptr)
  {
    e.impact = *impact;
  }
  sink->onEvent(e);
}

void Plant::addFlowsTo(EnergyLedger* e, const EnergyFlows& f)
{
  e->input += f.input;
  e->motor_friction += f.motor_friction;
  e->load_friction += f.load_friction;
  e->load_work += f.load_work;
  e->motor_dry_friction += f.motor_dry_friction;
  e->load_dry_friction += f.load_dry_friction;
  e->input_magnitude += std::fabs(f.input);
}

void Plant::syncLedger() const
{
  if (!ledger_pending_)
  {
    return;
  }
  ledger_pending_ = false;
  energy_ = ledgerAt(*segment_, state_.time - segment_->start.time);
}

bool Plant::advanceTo(double t_end, EventSink* sink)
{
  if (!(t_end >= state_.time) || !std::isfinite(t_end))
  {
    throw std::invalid_argument("advanceTo: target time " + std::to_string(t_end) + " s is before the current time " +
                                std::to_string(state_.time) + " s or not finite");
  }
  if (compliant_.joint)
  {
    return advanceCompliant(t_end, sink);
  }
  int stalled = 0;
  const bool report_impacts = reportsImpacts(sink);
  while (state_.time < t_end)
  {
    if (!segment_ && dry_)
    {
      Slide motor = 0, load = 0;
      chooseDryMode(sink, &motor, &load);
      beginDrySegment(motor, load);
    }
    if (!segment_)
    {
      if (state_.contact != Contact::Apart && rigid_flip_time_ != state_.time &&
          !contactHolds(params_, law_, state_.load_position, state_.load_velocity, state_.contact))
      {
        // The mesh torque pulls the teeth off this wall right now.
        state_.contact = mesh_.afterSeparation(state_.contact);
        emit(sink, EventType::Separation);
        if (++stalled > MAX_STALLED_ITERATIONS)
        {
          throw std::logic_error("backlash_servo::Plant made no progress at t = " + std::to_string(state_.time) +
                                 " s (internal error; please report with the parameters)");
        }
        continue;
      }
      beginSegment();
    }
    Segment& seg = *segment_;
    const double end_time = seg.start.time + seg.end_tau;
    if (end_time > t_end && seg.stuck && seg.motor_slide == 0 && seg.load_slide == 0)
    {
      state_.time = t_end;  // everything held: positions, velocities and the ledger stay as they are
      return false;
    }
    if (end_time > t_end)
    {
      // t_end falls inside the segment: evaluate there, keep the segment anchored where it began (the ledger when
      // it is read).
      const double tau = t_end - seg.start.time;
      emitExtremaUpTo(tau, sink);
      placeInSegment(tau, false);
      ledger_pending_ = track_energy_;
      state_.time = t_end;
      return false;
    }
    const double before = state_.time;
    const double ended_after = seg.end_tau;
    emitExtremaUpTo(seg.end_tau, sink);
    placeInSegment(seg.end_tau);
    state_.time = end_time;
    const Segment::End end = seg.end;
    const Contact wall = seg.wall;
    const bool flight = seg.flight.has_value();
    if (end == Segment::End::Rest || end == Segment::End::Breakaway)
    {
      const Segment ended = seg;
      restartSegment();
      handleRest(ended, sink);
      stalled = state_.time == before ? stalled + 1 : 0;
      if (stalled > MAX_STALLED_ITERATIONS)
      {
        throw std::logic_error("backlash_servo::Plant made no progress at t = " + std::to_string(before) +
                               " s (dry friction; internal error, please report with the parameters)");
      }
      continue;
    }
    restartSegment();
    if (end == Segment::End::Separation)
    {
      state_.contact = mesh_.afterSeparation(state_.contact);
      if (params_.backlash == 0.0 && ended_after <= 64.0 * EPS * std::fabs(state_.time))
      {
        rigid_flip_time_ = state_.time;  // the other flank at once (see the member's comment)
      }
      emit(sink, EventType::Separation);
    }
    else if (end == Segment::End::Impact)
    {
      handleImpact(wall, sink, report_impacts);
      if (flight)
      {
        chatter(t_end, sink, report_impacts);
      }
    }
    else if (end == Segment::End::Watch)
    {
      countSwitch();
      return true;
    }
    stalled = state_.time == before ? stalled + 1 : 0;
    if (stalled > MAX_STALLED_ITERATIONS)
    {
      throw std::logic_error("backlash_servo::Plant made no progress at t = " + std::to_string(before) +
                             " s (internal error; please report with the parameters)");
    }
  }
  return false;
}

template <class F>
void Plant::visitMotion(const Segment& seg, F&& f)
{
  if (seg.flight)
  {
    f(*seg.flight);
  }
  else if (seg.contact)
  {
    f(*seg.contact);
  }
  else if (seg.free)
  {
    f(*seg.free);
  }
  else if (seg.stuck)
  {
    f(*seg.stuck);
  }
  else
  {
    f(*seg.wide);
  }
}

void Plant::requireBounded() const
{
  constexpr double MAX_ANGLE = 1e9;      // [rad]
  constexpr double MAX_VELOCITY = 1e14;  // [rad/s]
  const double rho = params_.gear_ratio;
  const State& s = state_;
  if (std::fabs(s.load_position) <= MAX_ANGLE && std::fabs(rho * s.motor_position) <= MAX_ANGLE &&
      std::fabs(s.load_velocity) <= MAX_VELOCITY && std::fabs(rho * s.motor_velocity) <= MAX_VELOCITY)
  {
    return;
  }
  throwDiverged();
}

void Plant::throwDiverged() const
{
  const State& s = state_;
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "the motion diverged at t = %.9g s (load %.3g rad, %.3g rad/s): the loop is unstable, or the run "
                "left the validated envelope (docs/validation.md)",
                s.time, s.load_position, s.load_velocity);
  throw MotionDiverged(buf);
}

Plant::Segment& Plant::openSegment()
{
  requireBounded();
  segment_.emplace();
  Segment& seg = *segment_;
  seg.start = state_;
  seg.energy_at_start = energy_;
  return seg;
}

void Plant::beginSegment()
{
  const double period = period_;
  Segment& seg = openSegment();
  if (state_.contact != Contact::Apart)
  {
    const Contact wall = state_.contact;
    const ContactMotion& m = seg.contact.emplace(params_, law_, state_.load_position, state_.load_velocity);
    const double window = searchWindow(CONTACT_SEARCH_PERIODS * period);
    const double separation = m.separationTime(GearMesh::pressingSign(wall), window);
    double end = std::min(separation, window);
    seg.end = separation <= window ? Segment::End::Separation : Segment::End::Restart;
    constexpr int room = static_cast<int>(std::tuple_size<decltype(seg.extrema)>::value / 2);
    double maxima[room], minima[room];
    const int n_max = m.velocityMaxima(end, maxima, room);
    const int n_min = m.velocityMinima(end, minima, room);
    for (const auto& [times, n] : {std::pair<const double*, int>{maxima, n_max}, {minima, n_min}})
    {
      if (n == room && times[n - 1] < end)
      {
        end = times[n - 1];  // restart there; later turning points are found by the next segment
        seg.end = Segment::End::Restart;
      }
    }
    int i = 0, j = 0;
    while ((i < n_max && maxima[i] <= end) || (j < n_min && minima[j] <= end))
    {
      const bool take_max = j >= n_min || minima[j] > end || (i < n_max && maxima[i] <= end && maxima[i] < minima[j]);
      seg.extrema[seg.extrema_count++] =
          take_max ? Segment::Extremum{maxima[i++], true} : Segment::Extremum{minima[j++], false};
    }
    seg.end_tau = end;
    applyWatch(seg);
    return;
  }
  // Apart: search at most half a natural period ahead: impacts come sooner almost always, and a short window keeps
  // the critical points and brackets of the search local (a longer flight simply continues in a new segment).
  const double window = FREE_SEARCH_PERIODS * period;
  Contact wall = Contact::Forward;
  const double search = searchWindow(window);
  if (short_flights_ && impactNow(&wall) != 0.0)
  {
    // A short flight from a wall (chatter: back to it; rattle: across), as a certified Taylor series.
    if (!flight_model_)
    {
      flight_model_.emplace(params_, law_);
    }
    if (seg.flight.emplace().build(*flight_model_, state_, search))
    {
      ++short_flight_count_;
      seg.end = Segment::End::Impact;
      seg.end_tau = seg.flight->impactTime();
      seg.wall = seg.flight->wall();
      applyWatch(seg);
      markLoadTurnaround(seg);
      return;
    }
    seg.flight.reset();
  }
  if (apart_needs_series_)
  {
    seg.wide = std::make_shared<const WideFreeMotion>(params_, law_, state_, window);
  }
  else
  {
    seg.free.emplace(params_, law_, state_, window);
  }
  const double impact = seg.wide ? firstImpact(*seg.wide, search, &wall) : firstImpact(*seg.free, search, &wall);
  seg.end = impact <= search ? Segment::End::Impact : Segment::End::Restart;
  seg.end_tau = std::min(impact, search);
  seg.wall = wall;
  applyWatch(seg);
  markLoadTurnaround(seg);
}

void Plant::markLoadTurnaround(Segment& seg) const
{
  const double tau = loadTurnaround(params_, seg.start.load_velocity, seg.end_tau);
  if (tau <= seg.end_tau)
  {
    seg.extrema[0] = {tau, seg.start.load_velocity > 0.0};
    seg.extrema_count = 1;
  }
}

void Plant::applyWatch(Segment& seg) const
{
  if (std::isinf(watch_lo_) && std::isinf(watch_hi_))
  {
    return;
  }
  double exit = INFINITY;
  visitMotion(seg, [&](const auto& m) { exit = m.exitTime(watch_lo_, watch_hi_, seg.end_tau); });
  if (exit < seg.end_tau || (exit == seg.end_tau && seg.end == Segment::End::Restart))
  {
    seg.end_tau = exit;
    seg.end = Segment::End::Watch;
  }
}

EnergyLedger Plant::ledgerAt(const Segment& seg, double tau) const
{
  EnergyLedger ledger = seg.energy_at_start;
  visitMotion(seg, [&](const auto& m) {
    using M = std::decay_t<decltype(m)>;
    EnergyFlows flows = m.energy(tau);
    if (seg.dry && !std::is_same_v<M, StuckMotion>)
    {
      // The motion ran with the kinetic friction folded into its inputs: split it back out of them.
      const double motor_dry = seg.motor_slide * params_.motor_coulomb_friction * flows.motor_displacement;
      const double load_dry = seg.load_slide * params_.load_coulomb_friction * flows.load_displacement;
      flows.input += motor_dry;
      flows.motor_dry_friction = motor_dry;
      flows.load_work += load_dry;
      flows.load_dry_friction = load_dry;
    }
    addFlowsTo(&ledger, flows);
  });
  return ledger;
}

void Plant::placeInSegment(double tau, bool with_energy)
{
  const Segment& seg = *segment_;
  if (tau == 0.0)
  {
    // An event where the segment begins (e.g. an impact at once): the state is the start's, not the closed form's
    // rounding-level re-evaluation of it.
    const double t = state_.time;
    state_ = seg.start;
    state_.time = t;
    if (track_energy_ && with_energy)
    {
      energy_ = seg.energy_at_start;
      ledger_pending_ = false;
    }
    return;
  }
  const double t = state_.time;
  visitMotion(seg, [&](const auto& m) {
    using M = std::decay_t<decltype(m)>;
    if constexpr (std::is_same_v<M, ContactMotion>)
    {
      m.at(tau, &state_.load_position, &state_.load_velocity);
      state_.motor_position = mesh_.motorPositionOnWall(state_.load_position, seg.start.contact);
      state_.motor_velocity = mesh_.motorVelocityInContact(state_.load_velocity);
    }
    else
    {
      m.at(tau, &state_);
    }
  });
  if (track_energy_ && with_energy)
  {
    energy_ = ledgerAt(seg, tau);
    ledger_pending_ = false;
  }
  state_.time = t;
}

void Plant::emitExtremaUpTo(double tau, EventSink* sink)
{
  Segment& seg = *segment_;
  while (seg.extrema_emitted < seg.extrema_count && seg.extrema[seg.extrema_emitted].tau <= tau)
  {
    if (sink != nullptr)
    {
      const Segment::Extremum& x = seg.extrema[seg.extrema_emitted];
      const State keep = state_;
      placeInSegment(x.tau, false);  // an event carries the state, not the ledger
      state_.time = seg.start.time + x.tau;
      emit(sink, x.maximum ? EventType::Maximum : EventType::Minimum);
      state_ = keep;
    }
    ++seg.extrema_emitted;
  }
}

}  // namespace backlash_servo
