/**
 * @file modes.h
 * @brief Closed-form motion of the servo in each mode (teeth in contact, teeth apart) and event location inside a mode.
 *
 * Both modes are linear with constant input, so their solutions are written in closed form in the local time τ [s]
 * since the mode (re)started. Accuracy does not depend on any step size. No ROS dependency.
 */
#pragma once

#include <cmath>

#include "backlash_servo/model/params.h"
#include "backlash_servo/model/state.h"
#include "backlash_servo/numerics/exp_poly.h"

namespace backlash_servo
{
/// Overdamped or effort-mode contact: rates [1/s] below this fraction of the reference rate are treated as 0, and a
/// root pair closer than this fraction as double (critically damped); see docs/validation.md.
constexpr double RATE_MERGE_FRACTION = 1e-7;
/// Apart mode: a decay rate λ [1/s] with 0 < λ·W ≤ SLOW_RATE_WINDOW_PRODUCT over the search window W is "slow", and
/// so is a difference of two rates: its exponential is written as a Taylor polynomial (WideExpPoly) instead of
/// e^{−λτ} with coefficients ~1/λ that would cancel catastrophically (light damping).
constexpr double SLOW_RATE_WINDOW_PRODUCT = 0.1;
/// Inside the wide form, every rate with λ·W up to this is expanded too: a moderately slow rate left exponential
/// there would need a polynomial particular solution by back substitution, which cancels (seen at λW ≈ 0.3).
constexpr double SERIES_RATE_WINDOW_PRODUCT = 0.5;
/// Two apart-mode rates closer than this fraction are the same rate (their difference is below rounding's reach).
constexpr double EQUAL_RATE_FRACTION = 1e-12;

/// Energy flows over a time interval [J].
struct EnergyFlows
{
  double input = 0.0;               ///< ∫ T_m ω_m dt, work done by the motor torque [J]
  double motor_friction = 0.0;      ///< ∫ f_m ω_m² dt [J]
  double load_friction = 0.0;       ///< ∫ f_L ω_c² dt [J]
  double load_work = 0.0;           ///< ∫ T_ext ω_c dt = T_ext Δθ_c, work of the external load torque [J]
  double motor_dry_friction = 0.0;  ///< ∫ T_cm |ω_m| dt, dissipated by the motor's dry friction [J]
  double load_dry_friction = 0.0;   ///< ∫ T_cL |ω_c| dt, dissipated by the load's dry friction [J]
  double motor_displacement = 0.0;  ///< θ_m(τ) − θ_m(0) [rad], from the closed form (accounts dry friction)
  double load_displacement = 0.0;   ///< θ_c(τ) − θ_c(0) [rad], from the closed form
};

/**
 * @brief Teeth in contact (either side): one rigid body referred to the load shaft.
 *
 * \f[ J\ddot\theta_c + F_T\dot\theta_c + \rho k\,\theta_c = \rho a,\qquad J = J_m + \rho^2 J_L,\;
 *     F_T = f_m + \rho^2 f_L \f]
 * with the motor torque \f$ T_m = a - k\theta_c \f$ (MotorInput). The mesh torque on the load is
 * \f$ T_L = J_L\ddot\theta_c + f_L\dot\theta_c \f$ [N·m].
 */
class ContactMotion
{
 public:
  ContactMotion(const ServoParams& params, const MotorInput& input, double load_position, double load_velocity);

  /// Load position [rad] and velocity [rad/s] at local time tau [s].
  void at(double tau, double* load_position, double* load_velocity) const;
  /// Mesh torque on the load [N·m] at local time tau [s].
  double meshTorque(double tau) const;
  /**
   * First τ in (0, horizon] where the mesh torque leaves its allowed side (side = +1: T_L ≥ 0 in forward contact,
   * −1: T_L ≤ 0 in backward contact), i.e. where the teeth separate. +inf if none.
   */
  double separationTime(double side, double horizon) const;
  /// First τ in (0, horizon] where sign·ω_c, positive first (or starting from rest), falls to zero: the sliding
  /// pair comes to rest (dry friction, dry_friction.h). +inf if none.
  double restTime(double sign, double horizon) const;
  /// Times in (0, horizon] where the load velocity goes from + to − (positive maxima of θ_c), ascending.
  int velocityMaxima(double horizon, double* out, int max_out) const;
  /// Times in (0, horizon] where the load velocity goes from − to + (minima of θ_c), ascending.
  int velocityMinima(double horizon, double* out, int max_out) const;
  /// Energy flows over [0, tau].
  EnergyFlows energy(double tau) const;
  /// θ_c(τ) − θ_c(0) [rad], from the closed form (no difference of large positions).
  double displacement(double tau) const;
  /// First τ in (0, horizon] where θ_c leaves [lo, hi] beyond rounding (a drive's watch event), or +inf.
  double exitTime(double lo, double hi, double horizon) const;

 private:
  /// The two signals of the contact mode whose zeros are events.
  enum class Signal
  {
    LoadVelocity,  ///< ω_c: its down-crossings are maxima of θ_c
    MeshTorque     ///< T_L: its sign change on the wrong side is a separation
  };
  /// Down-crossings (from + to −) of signal × sign.
  int downCrossings(Signal signal, double sign, double horizon, bool require_positive_first, double* out,
                    int max_out) const;
  /// Turning points of θ_c where sign·ω_c goes from + to − (sign = +1: maxima, −1: minima), ascending.
  int velocityTurns(double sign, double horizon, double* out, int max_out) const;

  /// Separation where the mesh torque has a constant part (load torque): a damped sinusoid crossing a level.
  double levelSeparationTime(double side, double horizon) const;

  ServoParams params_;
  MotorInput input_;
  double x0_, v0_;
  double torque_level_ = 0.0;  // constant part of the mesh torque, −T_ext [N·m]
  bool oscillatory_ = false;
  // Constant motor torque (effort mode, sampled drives) with a slow decay p (p·W ≤ 0.5 over a natural period):
  // θ_c = x0 + v0 Φ1 + r Φ2, Φ1 = (1 − e^{−pτ})/p, Φ2 = (τ − Φ1)/p evaluated with expm1/series (no cancellation);
  // velocity and mesh torque are monotone, so their zeros are closed forms (log1p).
  bool slow_effort_ = false;
  double p_ = 0.0, r_ = 0.0;
  double phi1(double tau) const;
  double phi2(double tau) const;
  /// The τ in (0, horizon] where ω_c reaches v (monotone), or +inf.
  double timeOfVelocity(double v, double horizon) const;
  // Oscillatory: θ_c = x_eq + e^{−στ}(A cos ωτ + B sin ωτ); velocity and mesh torque as e^{−στ}(C cos + D sin).
  double x_eq_ = 0.0, sigma_ = 0.0, omega_ = 0.0, a_ = 0.0, b_ = 0.0;
  double vel_c_ = 0.0, vel_d_ = 0.0, torque_c_ = 0.0, torque_d_ = 0.0;
  // Real exponents: closed forms as exponential polynomials.
  ExpPoly position_, velocity_, acceleration_, torque_, displacement_;
};

/**
 * @brief Teeth apart: load and motor move separately.
 *
 * \f[ J_L\ddot\theta_c + f_L\dot\theta_c = 0,\qquad J_m\ddot\theta_m + f_m\dot\theta_m = a - k\,\theta_c \f]
 * Gap \f$ g = \theta_c - \rho\theta_m \f$ [rad]. With the rates α = f_L/J_L, β = f_m/J_m the solution is a sum of
 * P(τ)e^{−λτ} terms, λ ∈ {0, α, β}. In the compact form (Poly = ExpPoly) the exponentials are exact; when a rate is
 * slow over the window W (0 < λW ≤ SLOW_RATE_WINDOW_PRODUCT) or two rates nearly coincide, those exponentials
 * become Taylor polynomials around the nearest fast rate (Poly = WideExpPoly, see apartNeedsSeries()): e.g.
 * \f$ \theta_c = x_0 + v_0 \sum_j (-\alpha)^j \tau^{j+1}/(j+1)! \f$ instead of \f$ x_0 + v_0(1 -
 * e^{-\alpha\tau})/\alpha \f$, truncated where the terms fall below 1e-20 of the largest (the remainder is then below
 * rounding on [0, W]).
 */
template <class Poly>
class BasicFreeMotion
{
 public:
  /// window W [s]: the longest local time the motion is asked about (the wide form is accurate on [0, W]).
  BasicFreeMotion(const ServoParams& params, const MotorInput& input, const State& start, double window);

  /// Positions [rad] and velocities [rad/s] at local time tau [s] (time and contact of out are not touched).
  void at(double tau, State* out) const;
  double gap(double tau) const { return gap_(tau); }
  /**
   * First τ in (0, horizon] where the gap reaches a wall: g < 0 or g > Δ beyond rounding. Grazing contacts that
   * dip past the wall by more than the rounding bound are found exactly: the gap is monotone between its critical
   * points, which are isolated exactly (ExpPoly::signChangeRoots). Returns +inf if none; *wall gets the wall hit.
   */
  double impactTime(double horizon, Contact* wall) const;
  /**
   * Energy flows over [0, tau]: the products of the closed forms integrated exactly — unless their terms are more
   * than 1e6× the flows they make (a load drifting under T_ext towards T_ext/f_L with light damping: θ_c's terms
   * ~T_ext/(f_L α) ≫ its motion, the motor's ~k/J_m times those), where that integral would cancel away most of its
   * digits: then 8-point Gauss–Legendre on panels of 1/(2 max(α, β)) (exact to rounding for these exponential
   * polynomials) of the integrands written as start + increment (ExpPoly::increment).
   */
  EnergyFlows energy(double tau) const;
  /// First τ in (0, horizon] where θ_c leaves [lo, hi] beyond rounding (a drive's watch event), or +inf.
  double exitTime(double lo, double hi, double horizon) const;
  /// First τ in (0, horizon] where sign·ω of the motor (motor = true) or the load falls below zero beyond rounding:
  /// a body with dry friction comes to rest (dry_friction.h). +inf if none.
  double restTime(bool motor, double sign, double horizon) const;

 private:
  ServoParams params_;
  MotorInput input_;
  Poly load_position_, load_velocity_, motor_position_, motor_velocity_, gap_;
  State start_;  // the start [rad, rad/s]: at() adds position increments to it, energy() velocity increments too
  bool large_load_terms_ = false, large_motor_terms_ = false;  // positions by increments (flagLargeTerms)
  /// Flags a position form whose terms are > 1e6× its position scale (|θ(0)| + Δ, at the shaft): at() then adds
  /// increments to the start instead of evaluating the form directly.
  void flagLargeTerms();
  /// energy() by quadrature when the closed form's integrals would cancel; false (e untouched) otherwise.
  bool energyByQuadrature(const Poly& torque, double tau, EnergyFlows* e) const;
};
using FreeMotion = BasicFreeMotion<ExpPoly>;
using WideFreeMotion = BasicFreeMotion<WideExpPoly>;
/// Compact form: every rate 0 or fast (the closed forms written out).
template <>
BasicFreeMotion<ExpPoly>::BasicFreeMotion(const ServoParams& params, const MotorInput& input, const State& start,
                                          double window);
/// Wide form: slow exponentials as Taylor polynomials.
template <>
BasicFreeMotion<WideExpPoly>::BasicFreeMotion(const ServoParams& params, const MotorInput& input, const State& start,
                                              double window);
extern template class BasicFreeMotion<ExpPoly>;
extern template class BasicFreeMotion<WideExpPoly>;

/// Whether the apart mode over a window W [s] needs the wide (series) form: a rate or a difference of two rates
/// is slow but not zero.
bool apartNeedsSeries(const ServoParams& params, double window);

/**
 * Whether teeth at rest relative to each other on wall `wall` (Forward or Backward) stay in contact: the contact
 * mesh torque must press into the wall (T_L ≥ 0 forward, ≤ 0 backward). When T_L is zero within rounding, the first
 * derivative of T_L that is not decides, so this choice and the floating motion that follows it agree exactly.
 */
bool contactHolds(const ServoParams& params, const MotorInput& input, double load_position, double load_velocity,
                  Contact wall);

/// Load acceleration in contact [rad/s²]: \f$ \ddot\theta_c = (\rho T_m - F_T\dot\theta_c)/J \f$.
double contactAcceleration(const ServoParams& params, const MotorInput& input, double load_position,
                           double load_velocity);

/// Mesh torque on the load in contact [N·m] for the given state: \f$ T_L = J_L\ddot\theta_c + f_L\dot\theta_c \f$.
double contactMeshTorque(const ServoParams& params, const MotorInput& input, double load_position,
                         double load_velocity);

/**
 * An upper bound of |contactMeshTorque()| [N·m] without its division, for one parameter set: its terms by magnitude,
 * \f$ \frac{J_L}{J}(\rho|T_m| + \rho^2|T_{ext}| + F_T|\dot\theta_c|) + f_L|\dot\theta_c| + |T_{ext}| \f$, × 1.001 —
 * above contactMeshTorque()'s computed value too (its rounding is ~10 ε of that sum). The impact rule tests a rebound
 * against it first and computes the mesh torque only when the bound does not decide.
 */
class MeshTorqueBound
{
 public:
  MeshTorqueBound() = default;
  explicit MeshTorqueBound(const ServoParams& params);
  /// For motor torque T_m [N·m] and load velocity ω_c [rad/s].
  double operator()(double motor_torque, double load_velocity) const
  {
    return 1.001 * (motor_ * std::fabs(motor_torque) + constant_ + velocity_ * std::fabs(load_velocity));
  }

 private:
  double motor_ = 0.0, constant_ = 0.0, velocity_ = 0.0;  // J_L ρ/J [-], the T_ext part [N·m], [N·m·s/rad]
};

/// Mesh torque on the load [N·m] in state s: the contact value, or 0 when the teeth are apart.
double meshTorque(const ServoParams& params, const MotorInput& input, const State& s);

}  // namespace backlash_servo
