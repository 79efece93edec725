#include "backlash_servo/plant.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "backlash_servo/compliant_joint.h"
#include "backlash_servo/impact.h"

namespace backlash_servo
{
namespace
{
constexpr double EPS = std::numeric_limits<double>::epsilon();
/// Iterations without advancing time before the simulator declares a bug instead of hanging.
constexpr int MAX_STALLED_ITERATIONS = 10000;
/// Apart mode: impacts are searched this far ahead per segment [natural periods] (fastest on the benchmarks).
constexpr double FREE_SEARCH_PERIODS = 0.5;
/// Contact mode: separations and maxima are searched this far ahead per segment [natural periods].
constexpr double CONTACT_SEARCH_PERIODS = 1.0;
constexpr double PI = 3.14159265358979323846;

/// Apart, the load alone under its viscous friction and a constant torque T [N·m] (the load torque): J_L ω̇ + f_L ω = T,
/// so ω relaxes monotonically to T/f_L and turns from + to − at most once — a maximum of θ_c inside the flight — at
/// τ* = (v0 J_L/(−T))·log1p(x)/x, x = v0 f_L/(−T) (→ v0 J_L/(−T) without friction). τ* [s] if in (0, horizon], else
/// +inf.
double loadTurnaround(const ServoParams& p, double v0, double horizon)
{
  const double t = p.load_torque;
  if (!((v0 > 0.0 && t < 0.0) || (v0 < 0.0 && t > 0.0)))
  {
    return INFINITY;
  }
  const double x = std::fabs(v0) * p.load_friction / std::fabs(t);
  const double tau = std::fabs(v0) * p.load_inertia / std::fabs(t) * (x > 0.0 ? std::log1p(x) / x : 1.0);
  return tau > 0.0 && tau <= horizon ? tau : INFINITY;
}

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
  segment_.reset();
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
  segment_.reset();
}

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

void Plant::setParams(const ServoParams& params, EventSink* sink, bool frame)
{
  if (!frame)
  {
    params.validate();
  }
  if (params_.compliant() || params.compliant())
  {
    setCompliantParams(params, sink);
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
  segment_.reset();  // the closed form restarts from the state now
  const double balance_before = energyBalanceError();
  const double old_gap = gap();
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
  if (state_.contact == Contact::Backward && g < delta)
  {
    state_.contact = Contact::Apart;  // Δ grew: the teeth float at relative rest inside the larger gap
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

void Plant::addFlows(const EnergyFlows& f)
{
  energy_.input += f.input;
  energy_.motor_friction += f.motor_friction;
  energy_.load_friction += f.load_friction;
  energy_.load_work += f.load_work;
  energy_.motor_dry_friction += f.motor_dry_friction;
  energy_.load_dry_friction += f.load_dry_friction;
  energy_.input_magnitude += std::fabs(f.input);
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
      // t_end falls inside the segment: evaluate there, keep the segment anchored where it began.
      const double tau = t_end - seg.start.time;
      emitExtremaUpTo(tau, sink);
      placeInSegment(tau);
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
      segment_.reset();
      handleRest(ended, sink);
      stalled = state_.time == before ? stalled + 1 : 0;
      if (stalled > MAX_STALLED_ITERATIONS)
      {
        throw std::logic_error("backlash_servo::Plant made no progress at t = " + std::to_string(before) +
                               " s (dry friction; internal error, please report with the parameters)");
      }
      continue;
    }
    segment_.reset();
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

void Plant::beginSegment()
{
  requireBounded();
  const double period = period_;
  segment_.emplace();
  Segment& seg = *segment_;
  seg.start = state_;
  seg.energy_at_start = energy_;
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
  requireBounded();
  const double period = period_;
  segment_.emplace();
  Segment& seg = *segment_;
  seg.start = state_;
  seg.energy_at_start = energy_;
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
    if (track_energy_ && with_energy)
    {
      energy_ = seg.energy_at_start;
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
      addFlows(flows);
    }
  });
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
