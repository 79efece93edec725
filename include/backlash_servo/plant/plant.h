/**
 * @file plant.h
 * @brief The mechanical plant: motor and load bodies, the gear mesh with backlash, contact, tooth impacts and the
 *        stick rule, advanced exactly (closed-form modes, exact event location) under a given motor-torque law.
 *        It knows nothing of set-points or controllers (drive.h) nor of limit cycles (response_monitor.h).
 *        No ROS dependency.
 */
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>

#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"
#include "backlash_servo/rigid/dry_friction.h"
#include "backlash_servo/rigid/impact.h"
#include "backlash_servo/rigid/modes.h"
#include "backlash_servo/rigid/short_flight.h"
#include "backlash_servo/rigid/stuck_motion.h"

namespace backlash_servo
{
class CompliantJoint;

enum class EventType
{
  Impact,          ///< teeth collided (see ImpactInfo)
  Separation,      ///< mesh torque reached zero and changed sign: teeth came apart (Δ = 0: pushing side flipped);
                   ///< for a compliant mesh: a contact phase ended (the torque would pull)
  Maximum,         ///< load velocity went from + to − (smoothly or at an impact): a maximum of θ_c (kinematic event
                   ///< located exactly by the plant; the response monitor decides what it means)
  Minimum,         ///< load velocity went from − to +: a minimum of θ_c (located like Maximum; the monitor reads the
                   ///< cycle's peak-to-peak amplitude and centre from both)
  Rest,            ///< a body with dry friction came to rest: it sticks or breaks away again (rest rule,
                   ///< dry_friction.h); also a stuck motor pulled free by the continuous law
  Engagement,      ///< a compliant mesh's flank began to transmit torque: a contact phase began (state.contact)
  InputChange,     ///< command θ_R or motor torque changed
  ParameterChange  ///< parameters replaced
};

const char* toString(EventType t);

/// Details of one impact, velocities at the load/motor shafts.
struct ImpactInfo
{
  Contact wall = Contact::Forward;     ///< wall hit: Forward (g = 0) or Backward (g = Δ)
  double load_velocity_before = 0.0;   ///< ω_c before [rad/s]
  double load_velocity_after = 0.0;    ///< ω_c after [rad/s]
  double motor_velocity_before = 0.0;  ///< ω_m before [rad/s]
  double motor_velocity_after = 0.0;   ///< ω_m after [rad/s]
  double approach_speed = 0.0;         ///< |ġ| before, relative speed of the teeth at the load shaft [rad/s]
  double impulse = 0.0;                ///< angular impulse on the load [N·m·s]
  double energy_loss = 0.0;            ///< kinetic energy lost [J]
  bool stuck = false;                  ///< teeth stayed in contact afterwards (stick rule)
};

/// An event at state.time; state is the state just after the event.
struct Event
{
  EventType type = EventType::Impact;
  State state;
  MotorInput law;     ///< motor-torque law in force just after the event: T_m = law.torque(θ_c) [N·m]
  ImpactInfo impact;  ///< filled for EventType::Impact
  /// With a compliant mesh: its torque on the output gear just after the event [N·m]. NaN with rigid teeth, whose
  /// mesh torque follows from the law and the state (modes.h, meshTorque()).
  double mesh_torque = std::numeric_limits<double>::quiet_NaN();
};

/// Receives events in time order while the simulator advances.
class EventSink
{
 public:
  virtual ~EventSink() = default;
  virtual void onEvent(const Event& event) = 0;
  /// Whether this sink reads Impact events (default: yes). One that does not — the response monitor reads only
  /// maxima — spares the plant building them: elastic chatter has millions (the sweep's runs). Asked once per
  /// Plant::advanceTo(); every other event type is always sent.
  virtual bool wantsImpacts() const { return true; }
};

/// The run met more impacts than its budget allows (an impact storm): stopped instead of hanging.
class EventBudgetExceeded : public std::runtime_error
{
 public:
  using std::runtime_error::runtime_error;
};

/// The motion ran away (an unstable loop, e.g. a digital drive's gains beyond its stability limit): the state left
/// the bounds within which the closed forms are meaningful (|θ_c|, |ρθ_m| ≤ 1e9 rad; |ω_c|, |ρω_m| ≤ 1e14 rad/s,
/// 1000× the validated envelope, docs/validation.md) or became non-finite. Stopped instead of computing with
/// overflowing numbers.
class MotionDiverged : public std::domain_error
{
 public:
  using std::domain_error::domain_error;
};

/// Cumulative energy terms since the start (or the last reset) [J].
struct EnergyLedger
{
  double input = 0.0;               ///< work of the motor torque ∫ T_m ω_m dt [J]
  double motor_friction = 0.0;      ///< ∫ f_m ω_m² dt [J]
  double load_friction = 0.0;       ///< ∫ f_L ω_c² dt [J]
  double impact_loss = 0.0;         ///< Σ energy lost in impacts [J]
  double load_work = 0.0;           ///< work of the external load torque ∫ T_ext ω_c dt [J]
  double motor_dry_friction = 0.0;  ///< ∫ T_cm |ω_m| dt, dissipated by the motor's dry friction [J]
  double load_dry_friction = 0.0;   ///< ∫ T_cL |ω_c| dt, dissipated by the load's dry friction [J]
  double input_magnitude = 0.0;     ///< Σ |motor work| over the segments [J]: the rounding scale of `input` when the
                                    ///< drive's torque alternates (a sampled loop pumping energy in and out)
  double initial_kinetic = 0.0;     ///< kinetic energy at the start [J]
  // A compliant mesh only (0 with rigid teeth):
  double mesh_loss = 0.0;          ///< the mesh's damping and its jumps of stored energy (CompliantEnergy) [J]
  double shaft_loss = 0.0;         ///< ∫ d_s (ω_o − ω_c)² dt [J]
  double potential = 0.0;          ///< energy stored in the mesh and the shaft now [J]
  double initial_potential = 0.0;  ///< the same at the start (re-based by a parameter change) [J]
};

/**
 * @brief Motor and load coupled through a gear mesh with backlash, under a motor-torque law T_m = a − k θ_c.
 *
 * Contact: \f$ J\ddot\theta_c + F_T\dot\theta_c = \rho T_m \f$; apart: \f$ J_L\ddot\theta_c + f_L\dot\theta_c = 0,
 * \; J_m\ddot\theta_m + f_m\dot\theta_m = T_m \f$; impacts by impact.h; separation where the mesh torque changes
 * sign. See docs/model.md and docs/validation.md ("How it is exact").
 *
 * With a compliant mesh (params.compliant()) the plant delegates the motion to a CompliantJoint (compliant_joint.h):
 * the second way the gear transmits torque, with contact phases instead of impacts; the Plant's own interface, law,
 * watch and events stay the same (plant_compliant.cpp). With rigid teeth it delegates the same way while the law
 * carries a sine (a sine command under the continuous law, a sine torque in effort mode), whose forced motion the
 * thesis modes cannot express; the joint then resolves the impacts with the same map.
 */
class Plant
{
 public:
  /// Throws InvalidParameterError on bad parameters or a state that does not fit them.
  Plant(const ServoParams& params, const State& initial, const MotorInput& law);

  const ServoParams& params() const { return params_; }
  const GearMesh& mesh() const { return mesh_; }
  const State& state() const { return state_; }
  /// The motor-torque law in force.
  const MotorInput& law() const { return law_; }
  /// A new motor-torque law from now on (the state is not touched; the closed form restarts here — unless dry
  /// friction holds everything and still does under the new law: then nothing moves and the segment stays).
  void setLaw(const MotorInput& law);
  /// A sinusoidal torque on the load from now on, added to `load_torque`: T_ext(t) = load_torque + Σ B_i
  /// sin(ω_i(t − t₀,i) + φ_i) [N·m] — a disturbance, exact: the joint's modes carry it (on rigid teeth the sine's
  /// closed forms take the motion as for a motor sine, plant_compliant.cpp). Empty: none. Throws
  /// InvalidParameterError naming the key for what cannot carry it exactly (dry friction on rigid teeth; more sines,
  /// the motor's and the load's together, than the modes hold).
  void setLoadWave(const Waveform& wave);
  const Waveform& loadWave() const { return load_wave_; }
  /// The plant stops (advanceTo() returns true) where θ_c leaves [lo, hi] [rad]: a drive's switch. ±inf: none.
  void setWatch(double lo, double hi)
  {
    if (lo == watch_lo_ && hi == watch_hi_)
    {
      return;  // unchanged (every sample of a digital drive sets "none")
    }
    watch_lo_ = lo;
    watch_hi_ = hi;
    restartSegment();
    if (compliant_.joint)
    {
      watchCompliant();
    }
  }

  /// Events need not be searched beyond time t [s] (a drive's next sample, where the law changes anyway): shortens
  /// the event searches of the segments that begin before it. Depends only on drive times, so chunk-independence
  /// holds. +inf: no limit.
  void setSearchHorizon(double t)
  {
    search_horizon_ = t;
    if (compliant_.joint)
    {
      horizonCompliant();
    }
  }
  /// Fully held by stiction past time t [s] (dry friction; the segment's rest rule holds both bodies and lasts
  /// beyond t): advancing to t would only move the clock, which holdTo(t) does — the digital drive's fast path
  /// through the samples of a stick phase (exactly what advanceTo(t) does there, without its dispatch).
  bool holdsThrough(double t) const
  {
    double lo, hi;
    if (compliant_.joint)
    {
      return t >= state_.time && compliantHeld(&lo, &hi);
    }
    return segmentHeld() && segment_->start.time + segment_->end_tau > t && t >= state_.time;
  }
  void holdTo(double t)
  {
    if (compliant_.joint)
    {
      compliantHoldTo(t);
      return;
    }
    state_.time = t;
  }
  /// While holdsThrough(): an interval [*lo, *hi] of motor torques [N·m] under which the rest rule still holds both
  /// bodies (and the contact) with the state as it is, and *until [s], the end of the stick segment. The set of
  /// such torques is an interval (every test in decideAtRest() is monotone in the torque), found exactly:
  /// candidates for its ends are the static bands ±S_m and the pair's ±(ρS_m + ρ²S_L) − ρ²τ_L referred to the
  /// motor; each is confirmed by decideAtRest() itself, pulled 1e-9 towards the present torque. False when the rule
  /// does not apply (no segment held, a forced breakaway pending, or the present torque not held).
  bool heldTorqueRange(double* lo, double* hi, double* until) const;
  /// A compliant joint whose stuck load holds for ever while its motor settles on the mesh spring under the law in
  /// force (CompliantJoint::settlesForever): with the law unchanged, nothing but that decay happens again.
  bool settlesForever() const;
  /// Re-expresses the state in a frame moving relative to the present one (the continuous law's ramps, see
  /// Simulator): load angle and velocity + dx_load [rad], dv_load [rad/s], motor ones + dx_motor, dv_motor; the
  /// closed form restarts there. The caller keeps gap, contact and parameters consistent with the new frame.
  void shiftFrame(double dx_load, double dv_load, double dx_motor, double dv_motor)
  {
    syncLedger();
    state_.load_position += dx_load;
    state_.load_velocity += dv_load;
    state_.motor_position += dx_motor;
    state_.motor_velocity += dv_motor;
    segment_.reset();
    if (compliant_.joint)
    {
      stateToCompliant();
    }
  }

  /// See Simulator::setParams. Throws InvalidParameterError, keeping the old ones. `frame`: the parameters of a
  /// moving frame (Simulator's ramps), derived from validated ones — the frame's constant torques (f_L·v) are not
  /// user inputs and are not held to the load_torque key's range.
  void setParams(const ServoParams& params, EventSink* sink, bool frame = false);
  /// Replaces the state (validated: finite, gap within [0, Δ], contact consistent); resets the energy ledger.
  void setState(const State& state);
  /**
   * Advances exactly to time t_end [s] under the current law, reporting events in order to sink (may be null).
   * The closed form of the current segment stays anchored where the segment began (at the last event or window
   * end, never at t_end), so how a run is cut into advanceTo() calls — output samples, node ticks — does not change
   * a single bit of it. Only a change of law, parameters or state restarts the closed form.
   */
  bool advanceTo(double t_end, EventSink* sink);

  double gap() const { return mesh_.gap(state_.load_position, state_.motor_position); }
  /// T_m [N·m] now (the law's wave included).
  double motorTorque() const { return law_.torque(state_.load_position, state_.time); }
  double meshTorque() const;
  double kineticEnergy() const;
  const EnergyLedger& energy() const
  {
    syncLedger();
    return energy_;
  }
  void setEnergyTracking(bool on);
  double energyBalanceError() const;
  std::uint64_t impactCount() const { return impacts_; }
  /// At most this many impacts — and, counted apart, this many rests and law switches — since the last setState()
  /// (0 = no limit); one more throws EventBudgetExceeded.
  void setEventBudget(std::uint64_t max_impacts) { event_budget_ = max_impacts; }
  /// The chatter fast path (short_flight.h) on (default) or off: off, every flight uses the closed form — the two
  /// agree to rounding; the switch exists to compare them (tests, bench_core). Takes effect at the next segment.
  void setShortFlights(bool on) { short_flights_ = on; }
  /// Flights taken by the fast path since construction.
  std::uint64_t shortFlightCount() const { return short_flight_count_; }

  /// The compliant mesh's joint (null with rigid teeth).
  const CompliantJoint* compliantJoint() const { return compliant_.joint.get(); }
  /// Sends an event of the given type with the current state to sink (may be null).
  void emit(EventSink* sink, EventType type, const ImpactInfo* impact = nullptr) const;

 private:
  /// One mode segment: its closed form anchored at its start, where it ends and why.
  struct Segment
  {
    // User-provided: value-initialising (optional::emplace()) would otherwise zero the ~4 kB of motion storage first.
    Segment() {}
    enum class End
    {
      Restart,     ///< window end (or extrema buffer full): a new segment continues the same mode
      Separation,  ///< the mesh torque changes sign: the teeth separate
      Impact,      ///< the gap reaches a wall
      Watch,       ///< θ_c leaves the watch interval: the drive switches its law
      Rest,        ///< a sliding body with dry friction reaches zero velocity (rest_motor: which)
      Breakaway    ///< the continuous law's torque on the stuck motor leaves its static band
    };
    // Exactly one motion is set; built in place (the wide form, kilobytes and rare, lives on the heap).
    std::optional<ContactMotion> contact;
    std::optional<FreeMotion> free;
    std::shared_ptr<const WideFreeMotion> wide;  // immutable: copies of the plant may share it
    std::optional<StuckMotion> stuck;            // dry friction holds a body (or the pair)
    std::optional<ShortFlight> flight;           // a short chatter flight (apart, from a wall back to it)
    // Dry friction: slide directions of the bodies in this segment (0 stuck), kinetic friction folded into the
    // linear motions' inputs (dry_friction.h).
    bool dry = false;
    Slide motor_slide = 0, load_slide = 0;
    bool rest_motor = false;  ///< End::Rest: the motor (true) or the load (false, or the pair) came to rest
    State start;
    EnergyLedger energy_at_start;
    double end_tau = 0.0;  ///< local time of the end [s]
    End end = End::Restart;
    Contact wall = Contact::Forward;  ///< wall hit (Impact)
    /// A turning point of θ_c inside the segment: local time [s] and kind.
    struct Extremum
    {
      double tau;
      bool maximum;  ///< a maximum (ω_c from + to −), else a minimum
    };
    std::array<Extremum, 32> extrema;  ///< turning points of θ_c in (0, end_tau], ascending (up to extrema_count)
    int extrema_count = 0;
    int extrema_emitted = 0;
  };

  void addFlows(const EnergyFlows& flows) { addFlowsTo(&energy_, flows); }
  static void addFlowsTo(EnergyLedger* ledger, const EnergyFlows& flows);
  /// The ledger at local time tau [s] of the segment: its start's plus the motion's flows (dry friction split out).
  EnergyLedger ledgerAt(const Segment& seg, double tau) const;
  /// A stop inside a segment leaves the ledger to be computed when it is read (ledger_pending_): the closed form's
  /// flows cost more than the state, and most stops (output samples, node ticks) never read it. The same value, bit
  /// for bit, as computing it at the stop.
  void syncLedger() const;
  /// The closed form restarts (a change of law, parameters, state or frame): the ledger is brought up to now first.
  void restartSegment()
  {
    syncLedger();
    segment_.reset();
  }
  /// Builds the segment starting at the current state (after checking a contact still holds).
  void beginSegment();
  /// A new segment from the state now (checked bounded), its start and ledger recorded.
  Segment& openSegment();
  /// Apart, on a wall, with the teeth closing beyond rounding (a state set there, e.g. a run's start): the impact is
  /// now — 0 [s] and its wall in *wall; else +inf. (The closed form's search would find it only once the gap's
  /// penetration exceeds the rounding bound of the positions, which slow, light motions may never reach.)
  double impactNow(Contact* wall) const;
  /// Counts a rest or a law switch against the event budget (a sliding mode at a discontinuity of the law is
  /// otherwise an endless sequence of them); throws EventBudgetExceeded beyond it.
  void countSwitch();
  /// The current segment holds both bodies by stiction (dry friction; nothing moves while it lasts).
  bool segmentHeld() const
  {
    return segment_ && segment_->stuck && segment_->motor_slide == 0 && segment_->load_slide == 0;
  }
  /// The rest rule keeps both bodies and the contact as they are under motor torque `torque` [N·m].
  bool heldUnder(double torque) const;
  /// The first impact of motion m within `window` [s]: at once when the state is apart on a wall with the teeth
  /// closing (impactNow), else m's own search; its wall in *wall.
  template <class M>
  double firstImpact(const M& m, double window, Contact* wall) const
  {
    return impactNow(wall) == 0.0 ? 0.0 : m.impactTime(window, wall);
  }
  /// Throws MotionDiverged when the state is beyond the bounds of the closed forms (or not finite).
  void requireBounded() const;
  /// requireBounded()'s error (out of line: the check itself runs before every flight of a chatter).
  [[noreturn]] void throwDiverged() const;
  /// What is derived from params_: dry friction or not, the gear mesh, search period, press factor, mesh torque
  /// bound, impact maps.
  void deriveConstants();
  /// Dry friction: the rest rule and the contact check at the current state; the slide directions go to *motor and
  /// *load. A contact that no longer holds is left (Separation emitted).
  void chooseDryMode(EventSink* sink, Slide* motor, Slide* load);
  /// Builds the segment with dry friction (slide directions from chooseDryMode()).
  void beginDrySegment(Slide motor, Slide load);
  /// Ends a segment at a Rest or Breakaway: the body comes to rest exactly, the rule decides at the next segment.
  void handleRest(const Segment& seg, EventSink* sink);
  /// Calls f with the segment's motion (ContactMotion, FreeMotion, WideFreeMotion, StuckMotion or ShortFlight).
  template <class F>
  static void visitMotion(const Segment& seg, F&& f);
  /// Places state_ (and, with_energy, the ledger) at local time tau of the current segment.
  void placeInSegment(double tau, bool with_energy = true);
  /// Sends the segment's maxima and minima at local times ≤ tau [s] not yet sent.
  void emitExtremaUpTo(double tau, EventSink* sink);
  /// The event search window [s] of a segment beginning now: `window`, cut at the search horizon.
  double searchWindow(double window) const
  {
    const double left = search_horizon_ - state_.time;
    return left > 0.0 && left < window ? left : window;
  }
  /// Ends the segment early where θ_c leaves the watch interval.
  void applyWatch(Segment& seg) const;
  /// Apart with the load free of dry friction: a turning point of θ_c where a load torque turns the load round inside
  /// the segment (a maximum when its velocity crosses zero from + to −, a minimum from − to +) goes into its extrema.
  void markLoadTurnaround(Segment& seg) const;
  /// After a short flight's impact, with the teeth apart: the following short flights ending before t_end [s]
  /// (elastic chatter, up to ~10⁵ impacts per second) taken one after another, each exactly as advanceTo's loop
  /// takes a flight segment, without building segments; returns at the first one it does not take.
  void chatter(double t_end, EventSink* sink, bool report);
  /// `report`: send the Impact event (the sink wants it); a maximum or minimum at the impact goes to sink either way.
  void handleImpact(Contact wall, EventSink* sink, bool report);
  /// handleImpact()'s error when the impacts exceed the event budget (out of line, off the chatter's path).
  [[noreturn]] void throwImpactBudget() const;
  /// Puts teeth at relative rest on `wall` into contact if the mesh torque presses, else leaves them apart.
  void settleOnWall(Contact wall);

  // ---- the compliant mesh (plant_compliant.cpp) ----
  /// The joint, owned by value: copied with the plant.
  struct CompliantHolder
  {
    std::unique_ptr<CompliantJoint> joint;
    CompliantHolder();
    CompliantHolder(const CompliantHolder& other);
    CompliantHolder& operator=(const CompliantHolder& other);
    ~CompliantHolder();
  };
  /// Builds the joint for params_ at state_ (state.h's fields; contact is derived from the positions).
  void beginCompliant();
  /// Rigid teeth: a law with a sine from now on (the joint carries the motion; throws InvalidParameterError, nothing
  /// changed, where requireExactWave refuses), and back to the thesis modes (the ledger and its balance go on).
  void enterWave(const MotorInput& law);
  void leaveWave();
  /// state_ into the joint / the joint's state into state_.
  void stateToCompliant();
  void stateFromCompliant();
  void watchCompliant();
  void horizonCompliant();
  bool advanceCompliant(double t_end, EventSink* sink);
  void setCompliantParams(const ServoParams& params, EventSink* sink, bool frame);
  double compliantMeshTorque() const;
  double compliantKineticEnergy() const;
  double compliantBalanceError() const;
  void compliantEnergyTracking();
  /// Both bodies stuck with a rigid shaft and held by the law in force; *lo, *hi: the motor torques that keep it so.
  bool compliantHeld(double* lo, double* hi) const;
  void compliantHoldTo(double t);

  CompliantHolder compliant_;
  EnergyLedger wave_base_;     // rigid teeth carrying a sine: the ledger when the joint took over (else zero)
  double wave_balance_ = 0.0;  // and its balance error then [J]
  ServoParams params_;
  GearMesh mesh_;
  State state_;
  MotorInput law_;
  Waveform load_wave_;  // the load torque's sines [N·m]
  std::optional<Segment> segment_;
  bool apart_needs_series_ = false;  // apartNeedsSeries() for the current parameters (fixed window)
  double press_factor_ = 0.0;        // (J_m + ρ²J_L)/(J_m J_L) of the current parameters [1/(kg·m²)]
  MeshTorqueBound mesh_bound_;       // of the current parameters
  ImpactMap elastic_impact_;         // the impact map with the parameters' restitution e
  ImpactMap plastic_impact_;         // and with e = 0 (an impact the stick rule makes plastic)
  double period_ = 1.0;              // natural period 2π/ω_n of the current parameters [s] (sets the search windows)
  double watch_lo_ = -std::numeric_limits<double>::infinity();  // the drive's watch interval of θ_c [rad]
  double watch_hi_ = std::numeric_limits<double>::infinity();
  mutable EnergyLedger energy_;          // (brought up to date on demand: syncLedger)
  mutable bool ledger_pending_ = false;  // energy_ is the segment's start's: its flows up to now not yet added
  std::uint64_t impacts_ = 0;
  std::uint64_t event_budget_ = 0;
  std::uint64_t switches_ = 0;  // rests and watch switches since setState(), counted against the same budget
  bool track_energy_ = true;
  bool short_flights_ = true;
  std::optional<ShortFlight::Model> flight_model_;  // for params_ and law_ (reset when either changes)
  std::uint64_t short_flight_count_ = 0;
  bool dry_ = false;  // params_.hasDryFriction()
  double search_horizon_ = std::numeric_limits<double>::infinity();
  Slide forced_motor_breakaway_ = 0;  // set at a Breakaway: the motor slides this way from rest (no re-decision)
  // Time [s] of the last separation of a rigid mesh (Δ = 0) that ended its segment within the clock's resolution:
  // the mesh torque is crossing zero there, still on the old flank's side by rounding, so the contact test would send
  // the teeth straight back (and the plant would loop without advancing time). The other flank is taken
  // at once, where the torque is heading.
  double rigid_flip_time_ = -std::numeric_limits<double>::infinity();
};

}  // namespace backlash_servo
