/**
 * @file simulator.h
 * @brief Exact hybrid simulator of the backlash servo: closed-form propagation, exact event location, impacts,
 *        energy accounting. No ROS dependency; the ROS node and the tools are thin layers over this class.
 */
#pragma once

#include <cstdint>

#include "backlash_servo/modes.h"
#include "backlash_servo/params.h"
#include "backlash_servo/state.h"

namespace backlash_servo
{
enum class EventType
{
  Impact,          ///< teeth collided (see ImpactInfo)
  Separation,      ///< mesh torque reached zero and changed sign: teeth came apart (Δ = 0: pushing side flipped)
  Maximum,         ///< positive maximum of θ_c (ω_c went from + to −, smoothly or at an impact)
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
  ImpactInfo impact;  ///< filled for EventType::Impact
};

/// Receives events in time order while the simulator advances.
class EventSink
{
 public:
  virtual ~EventSink() = default;
  virtual void onEvent(const Event& event) = 0;
};

/// Cumulative energy terms since the start (or the last reset) [J].
struct EnergyLedger
{
  double input = 0.0;            ///< work of the motor torque ∫ T_m ω_m dt [J]
  double motor_friction = 0.0;   ///< ∫ f_m ω_m² dt [J]
  double load_friction = 0.0;    ///< ∫ f_L ω_c² dt [J]
  double impact_loss = 0.0;      ///< Σ energy lost in impacts [J]
  double initial_kinetic = 0.0;  ///< kinetic energy at the start [J]
};

class Simulator
{
 public:
  /// Starts in position mode with command θ_R = command [rad]. Throws InvalidParameterError on bad input.
  Simulator(const ServoParams& params, const State& initial, double command);

  const ServoParams& params() const { return params_; }
  const State& state() const { return state_; }
  ControlMode controlMode() const { return mode_; }
  double command() const { return command_; }

  /// Position mode, T_m = K(θ_R − θ_c), with θ_R = command [rad] from now on (a step). Must be finite.
  void setCommand(double command, EventSink* sink = nullptr);
  /// Effort mode, T_m = torque [N·m] from now on (the internal P loop is off). Must be finite.
  void setMotorTorque(double torque, EventSink* sink = nullptr);
  /**
   * Replaces the parameters at the current time without a jump in positions or velocities. If the current gap lies
   * outside the new [0, Δ], the motor is carried along: the gap is clamped to the nearest wall by moving θ_m (the
   * teeth touch there), then the usual contact rule decides. Throws InvalidParameterError, keeping the old ones.
   */
  void setParams(const ServoParams& params, EventSink* sink = nullptr);
  /// Replaces the state (validated: finite, gap within [0, Δ], contact consistent); resets the energy ledger.
  void setState(const State& state);

  /// Advances exactly to time t_end [s], reporting events in order to sink (may be null).
  void advanceTo(double t_end, EventSink* sink = nullptr);

  /// Gap g = θ_c − ρ θ_m [rad], in [0, Δ].
  double gap() const;
  /// Motor torque T_m [N·m].
  double motorTorque() const;
  /// Mesh torque on the load T_L [N·m] (0 when apart).
  double meshTorque() const;
  /// ½ J_m ω_m² + ½ J_L ω_c² [J].
  double kineticEnergy() const;
  const EnergyLedger& energy() const { return energy_; }
  /// Energy accounting costs ~25 % of the run time; sweeps that only need verdicts may switch it off (the ledger
  /// then stays at its last values and energyBalanceError() is meaningless).
  void setEnergyTracking(bool on) { track_energy_ = on; }
  /// input − friction − impact losses − (kinetic − initial kinetic) [J]; zero up to rounding.
  double energyBalanceError() const;
  std::uint64_t impactCount() const { return impacts_; }

 private:
  MotorInput input() const;
  void emit(EventSink* sink, EventType type, const ImpactInfo* impact = nullptr) const;
  void addFlows(const EnergyFlows& flows);
  void advanceContact(double horizon, double t_end, EventSink* sink);
  void advanceFree(double horizon, double t_end, EventSink* sink);
  void handleImpact(Contact wall, EventSink* sink);
  /// Puts teeth at relative rest on `wall` into contact if the mesh torque presses, else leaves them apart.
  void settleOnWall(Contact wall);

  ServoParams params_;
  State state_;
  ControlMode mode_ = ControlMode::Position;
  double command_ = 0.0;       // θ_R [rad]
  double motor_torque_ = 0.0;  // effort-mode torque [N·m]
  EnergyLedger energy_;
  std::uint64_t impacts_ = 0;
  bool track_energy_ = true;
};

}  // namespace backlash_servo
