/**
 * @file short_flight.h
 * @brief The chatter fast path: a short flight of the teeth apart (elastic chatter under a pressing torque, flights
 *        of microseconds between impacts) as a Taylor polynomial with a rigorous remainder bound, and its impact
 *        located by Newton's method on a certified concave gap. No ROS dependency.
 *
 * Apart, the state y = (θ_c, ω_c, θ_m, ω_m) obeys the linear ODE y' = A y + b (modes.h, BasicFreeMotion):
 * \f[ \dot\omega_c = T_{ext}/J_L - \alpha\,\omega_c,\qquad \dot\omega_m = (a - k\theta_c)/J_m - \beta\,\omega_m,
 *     \qquad \alpha = f_L/J_L,\ \beta = f_m/J_m. \f]
 * Its Taylor coefficients \f$ y(\tau) = \sum_k y_k \tau^k \f$ follow from \f$ y_1 = A y_0 + b \f$ and
 * \f$ y_{k+1} = A y_k/(k+1) \f$ (k ≥ 1) — a few multiply-adds per order instead of the exponentials, products and
 * root isolation of the closed form. In the weighted norm \f$ \|y\|_D = \max(|\theta_c|, s|\omega_c|,
 * \rho|\theta_m|, s\rho|\omega_m|) \f$ (s [s], a time scale of the motion) the matrix has a norm M [1/s], so
 * \f$ \|y_{N+j}\|_D \le \|y_N\|_D M^j N!/(N+j)! \f$ and the series cut after order N errs on [0, T] by at most
 * \f[ R_N(T) = \|y_N\|_D\,T^N\,\frac{MT/(N+1)}{1 - MT/(N+2)} \f]
 * in every (weighted) component. N is chosen so that R_N is below 1 % of the rounding of the positions: the flight
 * is as exact as the closed form, to the same tolerance (README, "How it is exact").
 *
 * A flight is taken only when it is certainly short and simple, otherwise the caller uses the closed form: the teeth
 * leave the wall they are on (ġ away from it) and the gap, relative to that wall, is certified concave on [0, T]
 * (its second derivative, with every higher term and the remainder bounded, keeps the sign of the pressing one), so
 * it rises once and comes back once; it is back beyond the wall at T; it cannot reach the other wall (the tangent at
 * 0 bounds a concave function); M·T ≤ 0.1. The return is then the only root in (peak, T], found by Newton's method
 * from T, which for a concave decreasing function approaches the root monotonically from the far side.
 */
#pragma once

#include "backlash_servo/modes.h"
#include "backlash_servo/params.h"
#include "backlash_servo/state.h"

namespace backlash_servo
{
class ShortFlight
{
 public:
  /// Highest Taylor order kept.
  static constexpr int MAX_ORDER = 16;
  /// Largest M·T [-] (norm of the mode's matrix times the flight) for which a flight is taken.
  static constexpr double MAX_NORM_TIME = 0.1;

  /**
   * Builds the flight from state `start` (apart, on or at rounding distance from a wall) under `input`, with events
   * searched up to `horizon` [s]. Returns false — and the caller uses the closed form — unless the conditions in the
   * file comment hold and the impact falls within the horizon.
   */
  bool build(const ServoParams& params, const MotorInput& input, const State& start, double horizon);

  /// Local time [s] of the impact that ends the flight, and the wall hit (the wall the teeth left).
  double impactTime() const { return impact_; }
  Contact wall() const { return wall_; }
  /// Positions [rad] and velocities [rad/s] at local time tau ∈ [0, impactTime()] [s] (time, contact untouched).
  void at(double tau, State* out) const;
  /// Energy flows over [0, tau] (products of the series integrated exactly).
  EnergyFlows energy(double tau) const;
  /// First τ in (0, horizon] where θ_c leaves [lo, hi] beyond rounding (a drive's watch event), or +inf. θ_c has
  /// at most one extremum in a flight (ω_c is monotone: it relaxes exponentially to T_ext/f_L).
  double exitTime(double lo, double hi, double horizon) const;

 private:
  /// Value of series c (order n_) at tau.
  double evaluate(const double* c, double tau) const;
  ServoParams params_;
  MotorInput input_;
  int n_ = 0;  // order kept
  double load_position_[MAX_ORDER + 1] = {}, load_velocity_[MAX_ORDER + 1] = {};
  double motor_position_[MAX_ORDER + 1] = {}, motor_velocity_[MAX_ORDER + 1] = {};
  double impact_ = 0.0;
  Contact wall_ = Contact::Forward;
};

}  // namespace backlash_servo
