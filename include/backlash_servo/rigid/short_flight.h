/**
 * @file short_flight.h
 * @brief The chatter fast path: a short flight of the teeth apart (elastic chatter under a pressing torque, rattle
 *        across a small gap, flights of microseconds between impacts) as a Taylor polynomial with a rigorous remainder
 *        bound, its impact located by Newton's method on a certified gap. No ROS dependency.
 *
 * Guaranteed: the impact where the closed form finds it, to rounding (the series' remainder below 1 % of the
 * positions' rounding); a flight the series cannot certify is left to the closed form (solve() returns false).
 * How it is computed and what it guarantees: docs/model.md, Part 4, "Short flights: the chatter fast path".
 */
#pragma once

#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"
#include "backlash_servo/rigid/modes.h"

namespace backlash_servo
{
class ShortFlight
{
 public:
  /// Highest Taylor order kept.
  static constexpr int MAX_ORDER = 16;
  /// Largest M·T [-] (norm of the mode's matrix times the flight) for which a flight is taken.
  static constexpr double MAX_NORM_TIME = 0.1;

  // User-provided: value-initialising (optional::emplace()) would otherwise zero the series storage first.
  ShortFlight() {}

  /// The constants of the apart mode for one parameter set and motor law (built once, used by every flight).
  struct Model
  {
    double load_friction = 0.0, motor_friction = 0.0, load_torque = 0.0;  ///< f_L, f_m [N·m·s/rad], T_ext [N·m]
    double offset = 0.0, stiffness = 0.0;  ///< the law T_m = a − k θ_c: a [N·m], k [N·m/rad]
    double alpha = 0.0, beta = 0.0;        ///< f_L/J_L, f_m/J_m [1/s]
    double motor_stiffness = 0.0;          ///< k/J_m [1/s²]
    double motor_offset = 0.0;             ///< a/J_m [rad/s²]
    double load_accel = 0.0;               ///< T_ext/J_L [rad/s²]
    double rho = 1.0, delta = 0.0;         ///< ρ [-], Δ [rad]
    double omega_ref = 0.0;                ///< max(α, β, √(ρ|k|/J_m)) [1/s]: 1/s of the weighted norm (0: none)
    double norm = 0.0;        ///< M [1/s], the matrix norm in the weighted norm with s = 1/ω_ref (when ω_ref > 0)
    double scale_time = 0.0;  ///< s = 1/ω_ref [s] (0 when ω_ref = 0: each flight then takes its own)
    Model() = default;
    Model(const ServoParams& params, const MotorInput& input);
  };

  /**
   * Builds the flight from state `start` (apart, on or at rounding distance from a wall) under the model's law,
   * with events searched up to `horizon` [s]. Returns false — and the caller uses the closed form — unless the
   * conditions in the file comment hold and the impact falls within the horizon.
   */
  bool build(const Model& model, const State& start, double horizon);
  bool build(const ServoParams& params, const MotorInput& input, const State& start, double horizon)
  {
    return build(Model(params, input), start, horizon);
  }

  /**
   * build() and at(impactTime()) in one, for a flight followed at once by its impact (the chatter loop): the
   * positions [rad] and velocities [rad/s] at the impact go into *end (its time and contact untouched; it may be
   * `start` itself, written only once the flight is accepted); the model is
   * not kept, so energy() and restTime() are not available after it. The same operations as build() then at()
   * (bit-identical results), without a second dispatch on the order or a copy of the model.
   */
  bool flyToImpact(const Model& model, const State& start, double horizon, State* end);

  /// Local time [s] of the impact that ends the flight, and the wall hit (the one the teeth left, or the other).
  double impactTime() const { return impact_; }
  Contact wall() const { return wall_; }
  /// Positions [rad] and velocities [rad/s] at local time tau ∈ [0, impactTime()] [s] (time, contact untouched).
  void at(double tau, State* out) const;
  /// Energy flows over [0, tau] (products of the series integrated exactly).
  EnergyFlows energy(double tau) const;
  /// First τ in (0, horizon] where θ_c leaves [lo, hi] beyond rounding (a drive's watch event), or +inf. θ_c has
  /// at most one extremum in a flight (ω_c is monotone: it relaxes exponentially to T_ext/f_L).
  double exitTime(double lo, double hi, double horizon) const;
  /**
   * Dry friction (the kinetic friction folded into the model's constant torques): the first τ in (0, horizon]
   * (horizon ≤ impactTime()) where sign·ω of the motor (motor = true) or the load falls below zero beyond rounding —
   * the body comes to rest — or +inf. Certified on the series: no zero when sign·ω stays above the sum of the
   * magnitudes of its terms and the remainder; else the velocity must be certified monotone (its slope's lowest
   * term dominating the rest), and the zero is bisected. NaN when neither can be certified: the caller then uses
   * the closed form.
   */
  double restTime(bool motor, double sign, double horizon) const;

 private:
  /// What build() and flyToImpact() share: the series, its order and the certified impact; at_impact(order, τ) is
  /// called with the order as a compile-time constant (0: read at run time) once the impact is accepted.
  template <class AtImpact>
  bool solve(const Model& model, const State& start, double horizon, AtImpact&& at_impact);
  /// at() for order N (0: n_).
  template <int N>
  void evaluateAt(double tau, State* out) const;

  Model model_;
  int n_ = 0;                // order kept
  double weighted_ = 0.0;    // ||y_N||_D, the last kept order's weighted norm
  double scale_time_ = 0.0;  // s [s] of the weighted norm
  double norm_time_ = 0.0;   // M·T [-] (T = end_)
  double end_ = 0.0;         // T [s], the end of the interval the series is certified on
  // Taylor coefficients (uninitialised beyond n_: a flight is built per impact)
  double load_position_[MAX_ORDER + 1], load_velocity_[MAX_ORDER + 1];
  double motor_position_[MAX_ORDER + 1], motor_velocity_[MAX_ORDER + 1];
  double impact_ = 0.0;
  Contact wall_ = Contact::Forward;
};

}  // namespace backlash_servo
