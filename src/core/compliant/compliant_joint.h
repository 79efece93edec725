/**
 * @file compliant_joint.h
 * @brief The compliant joint: resilient teeth (a mesh spring–damper that never pulls) and an optional torsional shaft,
 *        under a motor-torque law T_m = a − kθ_c, advanced exactly — every mode is linear with constant input (order
 *        4, or 6 with the shaft), solved by LinearMode, and every event is a located zero crossing. The second way the
 *        gear transmits torque beside the rigid teeth with impacts; the Plant (plant.h) delegates to it when
 *        mesh_stiffness > 0, and — with rigid teeth — while the motor-torque law carries a sine. No ROS
 *        dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "The compliant joint's modes and events".
 */
#pragma once

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"
#include "backlash_servo/rigid/impact.h"
#include "numerics/linear_mode.h"

namespace backlash_servo
{
/// A contact phase's mode of the mesh.
enum class MeshMode
{
  Free,       ///< no mesh torque (in the free play, or released while still penetrating)
  Forward,    ///< pressing on the forward flank (KD for msl_elastobacklash)
  Backward,   ///< pressing on the backward flank (KD)
  ForwardK2,  ///< msl_elastobacklash entering the forward flank: Q = 2cy while dẏ > cy
  BackwardK2  ///< the same on the backward flank
};

/// What a located event of the compliant joint is.
enum class MeshEvent
{
  Engage,            ///< a flank's penetration rose through 0: a contact phase begins
  Reengage,          ///< a released, still penetrating flank's torque rose through 0: a contact phase begins again
  LeavePenetration,  ///< a released flank's penetration fell through 0 (into the free play, or onto the other flank)
  Release,           ///< the mesh torque fell through 0 (it would pull): the contact phase ends
  SubMode,           ///< msl_elastobacklash switched between K2 and KD
  Maximum,           ///< ω_c fell through 0: a maximum of θ_c
  Minimum,           ///< ω_c rose through 0: a minimum of θ_c
  WatchExit,         ///< θ_c left the watched interval (a drive's switch)
  Stop,              ///< a sliding body with dry friction came to rest (it sticks, or slides on: the rest rule)
  Breakaway          ///< a stuck body's holding torque left its static band: it slides in that direction
};

/// The bodies with dry friction, as Stop and Breakaway events name them.
enum class Body
{
  Motor = 0,
  Load = 1
};

/// Cumulative energy terms of a compliant joint since setState() [J].
struct CompliantEnergy
{
  double input = 0.0;           ///< ∫ T_m ω_m dt, work of the motor torque
  double motor_friction = 0.0;  ///< ∫ f_m ω_m² dt
  double load_friction = 0.0;   ///< ∫ f_L ω_c² dt
  double load_work = 0.0;       ///< ∫ T_ext ω_c dt, work of the external load torque
  double mesh_loss = 0.0;       ///< ∫ d ẏ² dt while a flank presses with damping (KD), plus the mesh's jumps of
                           ///< stored energy: ½cy² at a release with y > 0, at K2 → KD; less ½cy² given back at
                           ///< a re-engagement with y > 0 and at KD → K2 (msl_elastobacklash's rule)
  double shaft_loss = 0.0;          ///< ∫ d_s (ω_o − ω_c)² dt
  double motor_dry_friction = 0.0;  ///< ∫ T_cm |ω_m| dt
  double load_dry_friction = 0.0;   ///< ∫ T_cL |ω_c| dt
  double impact_loss = 0.0;         ///< kinetic energy lost in the impacts of rigid teeth
  double input_magnitude = 0.0;     ///< Σ |motor work| over the quadrature pieces: the rounding scale of `input`
  CompliantEnergy& operator+=(const CompliantEnergy& o)
  {
    impact_loss += o.impact_loss;
    input += o.input;
    motor_friction += o.motor_friction;
    load_friction += o.load_friction;
    load_work += o.load_work;
    mesh_loss += o.mesh_loss;
    shaft_loss += o.shaft_loss;
    motor_dry_friction += o.motor_dry_friction;
    load_dry_friction += o.load_dry_friction;
    input_magnitude += o.input_magnitude;
    return *this;
  }
};

/// An impact of rigid teeth: the flank (+1 forward, −1 backward), the velocities before [rad/s], the closing speed
/// ẏ > 0 [rad/s] and what the impact map did; `stuck`: the teeth stayed in contact.
struct JointImpact
{
  int sigma = 1;
  double load_velocity_before = 0.0;
  double motor_velocity_before = 0.0;
  double closing = 0.0;
  ImpactOutcome outcome;
  bool stuck = false;
};

/// Throws InvalidParameterError naming the key unless the joint takes a law with a sine exactly: a compliant mesh
/// always; rigid teeth without dry friction (their meshed pair's rest rule is the rigid plant's, not these modes').
/// `what` names the input in the message (e.g. "a sine command").
void requireExactWave(const ServoParams& params, const std::string& what);

class CompliantJoint
{
 public:
  /// Throws InvalidParameterError unless params are valid, and — with rigid teeth (mesh_stiffness = 0) —
  /// requireExactWave() holds. The state starts at rest at 0 with the teeth touching the forward flank without
  /// deflection; law: T_m = a − kθ_c [N·m].
  CompliantJoint(const ServoParams& params, const MotorInput& law);

  /// The state's size: 4 with a rigid shaft, 6 with a torsional one.
  int size() const { return torsional_ ? 6 : 4; }
  /// Replaces the state (the order of state()) at time t [s]; the mesh takes the mode the state implies (pressing
  /// flank or free). Throws std::invalid_argument on a wrong size or non-finite entries.
  void setState(const Eigen::VectorXd& x, double t = 0.0);
  /// New parameters (same shaft model: a torsional shaft cannot appear or vanish) from now on, state kept. `frame`:
  /// they are a moving frame's (the Simulator's ramps: the load torque biased by −f_L v, which may lie beyond the
  /// envelope), derived from validated ones and not checked against the parameter table again.
  void setParams(const ServoParams& params, bool frame = false);
  /// A new motor-torque law from now on. Its wave Σ A_i sin(ω_i(t − t₀,i) + φ_i) [N·m], if any, is exact too: the
  /// modes carry an oscillator per sine (ż_c = −ωz_s, ż_s = ωz_c, z = (cos, sin) of its angle) as two more states,
  /// so every motion stays the closed form of a linear mode with constant input. Throws InvalidParameterError
  /// ("wave") when the order would pass MAX_MODE_ORDER (two sines with a rigid shaft, one with a torsional shaft).
  void setLaw(const MotorInput& law);
  /// A sinusoidal torque on the load from now on, T_ext(t) = load_torque + Σ B_i sin(ω_i(t − t₀,i) + φ_i) [N·m] (the
  /// load itself behind a torsional shaft), carried exactly like the law's wave: an oscillator per sine, after the
  /// law's. Throws InvalidParameterError ("load_wave") when the order would pass MAX_MODE_ORDER (the law's sines and
  /// these together: two with a rigid shaft, one with a torsional shaft). Empty: none.
  void setLoadWave(const Waveform& wave);
  const Waveform& loadWave() const { return load_wave_; }
  /// advanceTo() stops where θ_c leaves [lo, hi] [rad]; ±inf: none.
  void setWatch(double lo, double hi);
  /// Events need not be searched beyond time t [s] (a digital drive's next sample, where the law changes anyway):
  /// the first search window of a segment beginning before t ends there. Depends only on drive times, so
  /// chunk-independence holds. +inf: no limit.
  void setSearchHorizon(double t) { horizon_ = t; }
  /// Receives each event with the flank it concerns (+1 forward, −1 backward, 0 none; for Stop and Breakaway the
  /// Body), the state just after it.
  using Observer = std::function<void(MeshEvent, int)>;
  /**
   * Advances exactly to t_end [s] (≥ time()), reporting events in order to `observer` (may be empty). Returns true
   * when it stopped early, at a WatchExit (time() is then that instant).
   */
  bool advanceTo(double t_end, const Observer& observer = {});
  double time() const { return time_; }
  /// The state: (θ_m, ω_m, θ_c, ω_c) with a rigid shaft, (θ_m, ω_m, θ_o, ω_o, θ_c, ω_c) with a torsional one.
  Eigen::VectorXd state() const { return x_.head(size()); }
  /// Index of θ_c (and ω_c after it) in state().
  int loadIndex() const { return torsional_ ? 4 : 2; }
  MeshMode mode() const { return mode_; }
  /// The mesh torque Q on the output gear [N·m] (on the motor: −ρQ), ≥ 0 forward, ≤ 0 backward, 0 free.
  double meshTorque() const;
  /// The eigenvalues [1/s] of the current mode's matrix A (its natural modes: a pressing flank's two-mass resonance,
  /// or the free play's motions).
  Eigen::VectorXcd eigenvalues() const;
  /// The energy ledger since setState(); its integrals are exact to rounding: each segment is cut into pieces of at
  /// most half its fastest time scale, each integrated by 8-point Gauss–Legendre on the closed form (error far below
  /// rounding for exponentials e^{λs} with |λ|h ≤ 1/2), the pieces anchored at the segment's start
  /// (chunk-independent).
  const CompliantEnergy& energy() const { return energy_; }
  /// Kinetic energy ½J_m ω_m² + ½J_g ω_o² + ½J_L ω_c² [J].
  double kineticEnergy() const;
  /// Stored energy [J]: the pressing flank's spring (½cy², cy² in msl_elastobacklash's K2) and the shaft's ½k_s(θ_o −
  /// θ_c)².
  double potentialEnergy() const;
  /// input + load work − losses − (kinetic + potential − their value at the start, re-based by setParams) [J]: zero
  /// up to rounding.
  double energyBalanceError() const;
  /// Kinetic and stored energy at the start [J] (a parameter change re-bases the kinetic one by the jump it makes).
  double initialKinetic() const { return initial_kinetic_; }
  double initialPotential() const { return initial_potential_; }
  /// Energy accounting on (default) or off (the ledger then stays as it is).
  void setEnergyTracking(bool on)
  {
    track_energy_ = on;
    segment_.reset();
  }
  /// Contact phases begun so far (each engagement of a flank, re-engagements included).
  std::uint64_t contacts() const { return contacts_; }
  /// Re-engagements of a released flank while still penetrating.
  std::uint64_t reengagements() const { return reengagements_; }
  /// Rigid teeth: the impacts so far, and the latest.
  std::uint64_t impacts() const { return impacts_; }
  const JointImpact& lastImpact() const { return last_impact_; }
  /// Rigid teeth (mesh_stiffness = 0): flanks are reached by impacts.
  bool rigid() const { return rigid_; }
  /// How a body with dry friction moves: 0 stuck, ±1 sliding that way (a body without dry friction: always 1, it
  /// never sticks).
  int slide(Body b) const { return slide_[static_cast<int>(b)]; }
  /// Both bodies stuck with a rigid shaft and no wave: nothing moves until the motor torque leaves heldMotorTorque().
  bool held() const;
  /// While held(): the motor torques [N·m] that keep it so, [ρQ − T_sm, ρQ + T_sm] (the load's holding torque
  /// Q + T_ext does not depend on the motor torque while the motor stands).
  void heldMotorTorque(double* lo, double* hi) const;
  /// Moves the clock to t ≥ time() [s] while held() (nothing moves).
  void holdTo(double t);
  /**
   * The load stuck by dry friction on a pressed flank (rigid shaft, no wave) while a motor without dry friction
   * settles on the mesh spring under the law in force: the motor's mode with the load frozen, ẋ_m = M x_m + f, is
   * stable with distinct eigenvalues, and every output that could change the mode — the mesh torque P (a release),
   * msl's d·ẏ − c·y (the switch to its 2c·y sub-mode, which a settling motor is never in), the load's holding torque
   * (a breakaway) — stays on its side for ever:
   * |o(t) − o_eq| ≤ Σ_i |c_i|, the modal coefficients of its deviation from the equilibrium x_eq = −M⁻¹f (each term
   * decays), with margins beyond rounding. Then nothing but that decay ever happens: the joint converges to x_eq.
   */
  bool settlesForever() const;

 private:
  struct Watch
  {
    ModeVector w;
    double w0;
    int direction;
    MeshEvent kind;
    int sigma;  // the flank (+1 forward, −1 backward), 0 for a maximum/minimum, ±1 upper/lower for the watch
  };
  /// The closed form of the current mode anchored at its start, and how far its events were searched.
  struct Segment
  {
    /// The mode's closed form built in place from the state x at time `start` (the LinearMode is large: not copied).
    Segment(std::shared_ptr<const ModeBasis> basis, const ModeVector& u, const ModeVector& x, double start_time,
            double window_length, double first_window, std::vector<Watch> watch_list, const CompliantEnergy& ledger,
            const std::array<int, 2>& slides, double piece_length)
        : motion(std::move(basis), u, x),
          start(start_time),
          window(window_length),
          next_window(first_window),
          watches(std::move(watch_list)),
          at_start(ledger),
          slide(slides),
          piece(piece_length)
    {}
    LinearMode motion;
    double start;             // [s]
    double window;            // longest search window [s]
    double next_window;       // the next search window [s]: short first, doubling up to `window`
    double searched = 0;      // events searched over (0, searched] of local time
    double event = INFINITY;  // local time of the first event found, or +inf
    int hit = -1;             // its index in watches
    std::vector<Watch> watches;
    CompliantEnergy at_start;  // the ledger at the segment's start
    CompliantEnergy pieces;    // the integrals over its whole pieces so far
    std::array<int, 2> slide;  // the bodies' slides over the segment (slide_ at its start)
    double piece = 0.0;        // length of a piece [s]
    long pieces_done = 0;
    bool stretched = false;   // pieces lengthened since the mode's fastest parts decayed below rounding
    double pieces_end = 0.0;  // where the whole pieces end once stretched [s, local]
    double resumed = 0.0;     // local time [s] its watches were set up: 0, or a later event's that changed only them
  };
  int out() const { return 2; }  // index of θ_o, the mesh's output-side angle (θ_c itself with a rigid shaft)
  /// The law or the load has a wave: the modes carry its oscillators.
  bool forced() const { return law_.wave.active() || load_wave_.active(); }
  /// The modes' order: size(), and each sine's oscillator, two states (cos, sin of its angle) — the law's, then the
  /// load's.
  int dim() const { return size() + 2 * (law_.wave.count + load_wave_.count); }
  /// Index of the first state of the load wave's first oscillator.
  int loadWaveIndex() const { return size() + 2 * law_.wave.count; }
  /// A wave's oscillators (from state index `first`) and its torque on the row `row` (scaled by `gain`: 1/J of the
  /// body it drives).
  void addOscillators(const Waveform& wave, int first, double gain, int row, ModeMatrix* a) const;
  /// Σ A_i sin of a wave's oscillators (from state index `first`) in the mode state x [N·m].
  static double waveAt(const Waveform& wave, int first, const ModeVector& x)
  {
    double sum = 0.0;
    for (int i = 0; i < wave.count; ++i)
    {
      sum += wave.tones[static_cast<std::size_t>(i)].amplitude * x(first + 2 * i + 1);
    }
    return sum;
  }
  /// x_ sized dim() around the physical state `phys`, the oscillator's states exact at time_.
  void setModeState(const Eigen::VectorXd& phys);
  /// A and u of mesh mode m with the bodies' slides (0 stuck: its rows zeroed; ±1: −T_c·slide folded into u).
  void modeMatrices(MeshMode m, const std::array<int, 2>& slide, ModeMatrix* a, ModeVector* u) const;
  /// Indices of a body's angle (its velocity follows) and its inertia [kg·m²]; its Coulomb and static levels [N·m].
  int angleIndex(int body) const { return body == 0 ? 0 : loadIndex(); }
  double inertiaOf(int body) const;
  double coulombOf(int body) const { return body == 0 ? s_.motor_coulomb_friction : s_.load_coulomb_friction; }
  double staticOf(int body) const { return body == 0 ? s_.motor_static_friction : s_.load_static_friction; }
  /// The torque H = w·x + w₀ [N·m] that must hold a body at rest in mesh mode m (all it receives but its friction).
  void holdingTorque(int body, MeshMode m, ModeVector* w, double* w0) const;
  /// The rest rule for a body at rest now: 0 while |H| ≤ T_s, else the sign of H.
  int restSlide(int body) const;
  /// The penetration y = w·x + w0 of a flank (σ = +1 forward, −1 backward) as a linear output.
  void penetration(int sigma, ModeVector* w, double* w0) const;
  /// P = k_y y + k_v ẏ of a flank as a linear output.
  void flankTorque(int sigma, double ky, double kv, ModeVector* w, double* w0) const;
  /// The mode the mesh takes from the current state (after an event).
  MeshMode chooseMode(bool released_forward, bool released_backward) const;
  /// Rigid teeth in contact (either flank): the meshed pair's A and u, and its mesh torque Q = w·x + w₀ [N·m].
  void rigidContact(ModeMatrix* a, ModeVector* u) const;
  void rigidMeshTorque(ModeVector* w, double* w0) const;
  /// Rigid teeth: the impact on flank σ at the current state; the mode after it.
  void impact(int sigma);
  /// The basis of a mode's matrix A: computed once and kept (a few modes and drive laws recur all run long).
  std::shared_ptr<const ModeBasis> basisFor(const ModeMatrix& a);
  /// The outputs watched for events in the current mode from the current state.
  std::vector<Watch> watchList() const;
  void beginSegment();
  /// Goes on with the current segment's motion after an event at its local time tau [s] that changed only what is
  /// watched: its watches set up afresh there.
  void resumeSegment(double tau);
  /// An event at the watches' start that the state there already implies (its crossing lay within rounding); a and u
  /// the mode's ẋ = A x + u. An output starting within its rounding band is judged by the side it leaves the band on
  /// (exact searches for s ∓ band crossing outwards), where its rate alone could be turned back inside the band — but
  /// a contact begun at that very instant releases only where its output starts below the band. A contact kept with
  /// its release output below zero within the band has that output watched falling past the band.
  void checkStart(const ModeMatrix& a, const ModeVector& u);
  void searchNextWindow();
  /// The ledger's integrals over [a, b] of the segment's local time (8-point Gauss–Legendre), added to *e.
  void integrate(const Segment& seg, double a, double b, CompliantEnergy* e) const;
  /// The ledger at local time tau of the current segment (its whole pieces kept for the next call).
  void placeEnergy(double tau);
  /// The next whole piece of the ledger's integration [from, to] of local time [s]: the segment's piece length, or
  /// longer once its mode's fastest parts have decayed below rounding (LinearMode::decayedSpeedup).
  static void nextPiece(Segment* seg, double* from, double* to);
  /// The state, time t [s] and ledger at local time tau [s] of the current segment.
  void moveTo(double tau, double t);
  /// Applies the segment's event at the current state (the mode, counters, the mesh's jump of stored energy) and
  /// reports it; true for a WatchExit.
  bool handle(const Watch& watch, const Observer& observer);
  /// The mode change of an event; true when, with Δ = 0, the other flank engaged at once.
  bool applyEvent(const Watch& watch);

  ServoParams s_;
  MotorInput law_;
  bool torsional_;
  bool msl_;
  bool rigid_;
  std::uint64_t impacts_ = 0;
  JointImpact last_impact_;
  double watch_lo_ = -INFINITY, watch_hi_ = INFINITY;
  double horizon_ = INFINITY;
  double time_ = 0.0;
  Eigen::VectorXd x_;   // the state, then (forced) each oscillator's cos and sin of its sine's angle
  Waveform load_wave_;  // the load torque's sines [N·m]
  MeshMode mode_ = MeshMode::Forward;
  std::optional<Segment> segment_;
  std::vector<std::shared_ptr<const ModeBasis>> bases_;  // most recently used last
  std::uint64_t contacts_ = 0, reengagements_ = 0;
  CompliantEnergy energy_;
  double initial_kinetic_ = 0.0;    // kinetic energy at the start, re-based by setParams [J]
  double initial_potential_ = 0.0;  // stored energy at the start [J]
  bool track_energy_ = true;
  int last_kind_ = -1, last_sigma_ = 0;  // the latest event, at time last_time_ [s]
  double last_time_ = -INFINITY;
  double release_time_[2] = {-INFINITY, -INFINITY};  // the latest release of the forward [0], backward [1] flank [s]
  bool fresh_ = true;  // nothing has happened since setState (the start's mode follows the law set next)
  std::array<int, 2> slide_ = {1, 1};            // motor, load: 0 stuck, ±1 sliding (dry_[b]); 1 without dry friction
  std::array<bool, 2> dry_ = {false, false};     // the body has dry friction (T_s > 0)
  std::array<double, 2> stuck_at_ = {0.0, 0.0};  // a stuck body's angle [rad]
  std::array<double, 2> slide_began_ = {-INFINITY, -INFINITY};  // when a body last began to slide from rest [s]
};

}  // namespace backlash_servo
