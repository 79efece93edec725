// The contact mode (modes.h: ContactMotion): both bodies as one on a wall of the free play.
#include "backlash_servo/model/constants.h"
#include "backlash_servo/rigid/modes.h"

#include "numerics/event_search.h"
#include "numerics/gauss_legendre.h"
#include "rigid/mode_rounding.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

namespace backlash_servo
{
namespace
{
/// The first of the points τ + kπ/ω (k whole) in (0, half = π/ω], for τ = (atan2(·) + π/2)/ω in [−half/2, 3half/2]
/// (fmod is exact, so this equals one subtraction or addition of half); +inf (no such point) stays +inf, so a
/// mesh torque with no oscillating part (a load torque balancing the motor's at the start) does not loop for ever.
double firstInHalfPeriod(double tau, double half)
{
  if (!std::isfinite(tau))
  {
    return tau;
  }
  tau = std::fmod(tau, half);
  return tau <= 0.0 ? tau + half : tau;
}

/// Largest rate of the model [1/s]; the scale below which rates count as zero.
double referenceRate(const ServoParams& p)
{
  return std::max({p.naturalFrequency(), p.totalFriction() / p.totalInertia(), p.load_friction / p.load_inertia,
                   p.motor_friction / p.motor_inertia});
}

double canonicalRate(double rate, double reference)
{
  return rate < RATE_MERGE_FRACTION * reference ? 0.0 : rate;
}

/// ∫_0^T e^{zτ} dτ for complex z, by series where |zT| < 1 (no cancellation).
std::complex<double> integralExp(std::complex<double> z, double upper)
{
  const std::complex<double> zt = z * upper;
  if (std::abs(zt) < 1.0)
  {
    std::complex<double> term = upper;  // T (zT)^n / (n+1)!
    std::complex<double> sum = 0.0;
    for (int n = 0; n < 60; ++n)
    {
      sum += term;
      if (std::abs(term) <= 1e-18 * std::abs(sum))
      {
        break;
      }
      term *= zt / static_cast<double>(n + 2);
    }
    return sum;
  }
  return (std::exp(zt) - 1.0) / z;
}

/**
 * Down-crossings (+ to −) of f in (0, horizon], located exactly: f is monotone between the sign changes of f'.
 * Values within rounding (bound(τ)) count as zero: a crossing needs f below −bound. With require_positive_first,
 * f must first exceed +bound (a maximum of θ_c needs a positive velocity before it).
 */
template <class Bound>
int walkDownCrossings(const ExpPoly& f, const Bound& bound, double horizon, bool require_positive_first, double* out,
                      int max_out)
{
  double crit[EXP_POLY_MAX_ROOTS];
  const int m = f.derivative().signChangeRoots(0.0, horizon, crit, CRITICAL_POINT_TOLERANCE);
  double p = 0.0;
  double fp = f(0.0);
  bool armed = !require_positive_first || fp > bound(0.0);
  int count = 0;
  for (int i = 0; i <= m && count < max_out; ++i)
  {
    const double q = i < m ? crit[i] : horizon;
    const double fq = f(q);
    const double bq = bound(q);
    if (armed && fq < -bq)
    {
      out[count++] = fp > 0.0 ? f.refineBracket(0.0, p, fp, q, fq) : p;
      armed = !require_positive_first;
      if (!require_positive_first)
      {
        break;
      }
    }
    if (fq > bq)
    {
      armed = true;
    }
    p = q;
    fp = fq;
  }
  return count;
}

}  // namespace

double contactAcceleration(const ServoParams& p, const MotorInput& in, double x, double v)
{
  const double rho = p.gear_ratio;
  return (rho * in.torque(x) + rho * rho * p.load_torque - p.totalFriction() * v) / p.totalInertia();
}

double contactMeshTorque(const ServoParams& p, const MotorInput& in, double x, double v)
{
  return p.load_inertia * contactAcceleration(p, in, x, v) + p.load_friction * v - p.load_torque;
}

MeshTorqueBound::MeshTorqueBound(const ServoParams& p)
{
  const double rho = p.gear_ratio;
  const double share = p.load_inertia / p.totalInertia();  // J_L/J
  motor_ = share * rho;
  constant_ = share * rho * rho * std::fabs(p.load_torque) + std::fabs(p.load_torque);
  velocity_ = share * p.totalFriction() + p.load_friction;
}

double meshTorque(const ServoParams& p, const MotorInput& in, const State& s)
{
  return s.contact == Contact::Apart ? 0.0 : contactMeshTorque(p, in, s.load_position, s.load_velocity);
}

bool contactHolds(const ServoParams& p, const MotorInput& in, double x, double v, Contact wall)
{
  const double j = p.totalInertia();
  const double f = p.totalFriction();
  const double rk = p.gear_ratio * in.stiffness;
  // Derivatives of θ_c from the contact ODE, and magnitudes to bound their rounding.
  const double x2 = contactAcceleration(p, in, x, v);
  const double m2 = (p.gear_ratio * (std::fabs(in.offset) + std::fabs(in.stiffness * x)) +
                     p.gear_ratio * p.gear_ratio * std::fabs(p.load_torque) + std::fabs(f * v)) /
                    j;
  const double x3 = (-rk * v - f * x2) / j;
  const double m3 = (rk * std::fabs(v) + f * m2) / j;
  const double x4 = (-rk * x2 - f * x3) / j;
  const double m4 = (rk * m2 + f * m3) / j;
  const double values[3] = {p.load_inertia * x2 + p.load_friction * v - p.load_torque,
                            p.load_inertia * x3 + p.load_friction * x2, p.load_inertia * x4 + p.load_friction * x3};
  const double bounds[3] = {p.load_inertia * m2 + p.load_friction * std::fabs(v) + std::fabs(p.load_torque),
                            p.load_inertia * m3 + p.load_friction * m2, p.load_inertia * m4 + p.load_friction * m3};
  const double side = wall == Contact::Backward ? -1.0 : 1.0;
  for (int k = 0; k < 3; ++k)
  {
    if (std::fabs(values[k]) > 64.0 * EPS * bounds[k])
    {
      return side * values[k] > 0.0;
    }
  }
  return true;  // mesh torque identically zero: nothing pulls the teeth apart
}

// ---------------------------------------------------------------------------------------------------------------
ContactMotion::ContactMotion(const ServoParams& params, const MotorInput& input, double x0, double v0)
    : params_(params), input_(input), x0_(x0), v0_(v0)
{
  const double j = params.totalInertia();
  const double ref = referenceRate(params);
  const double p_raw = params.totalFriction() / j;  // the damped sinusoid needs no merging, however slow its decay
  const double p = canonicalRate(p_raw, ref);
  const double q = params.gear_ratio * input.stiffness / j;
  // The load torque acts like a motor offset ρ T_ext on the meshed pair: ρ T_m + ρ² T_ext = ρ (a + ρ T_ext − kθ_c).
  const double offset = input.offset + params.gear_ratio * params.load_torque;
  const double r = params.gear_ratio * offset / j;
  torque_level_ = -params.load_torque;
  if (q > 0.0)
  {
    x_eq_ = offset / input.stiffness;
    const double y0 = x0 - x_eq_;
    const double disc = p * p - 4.0 * q;
    if (disc < 0.0)
    {
      oscillatory_ = true;
      sigma_ = 0.5 * p_raw;
      omega_ = 0.5 * std::sqrt(4.0 * q - p_raw * p_raw);
      a_ = y0;
      b_ = (v0 + sigma_ * y0) / omega_;
      // d/dτ of e^{−στ}(C cos ωτ + D sin ωτ) is e^{−στ}((−σC + ωD) cos + (−σD − ωC) sin).
      vel_c_ = -sigma_ * a_ + omega_ * b_;
      vel_d_ = -sigma_ * b_ - omega_ * a_;
      const double acc_c = -sigma_ * vel_c_ + omega_ * vel_d_;
      const double acc_d = -sigma_ * vel_d_ - omega_ * vel_c_;
      torque_c_ = params.load_inertia * acc_c + params.load_friction * vel_c_;
      torque_d_ = params.load_inertia * acc_d + params.load_friction * vel_d_;
      return;
    }
    const double s = std::sqrt(disc);
    position_ = ExpPoly::constant(x_eq_);
    if (s <= RATE_MERGE_FRACTION * p)
    {
      // Critically damped: y = (A + Bτ) e^{λτ}.
      const double lambda = -0.5 * p;
      position_ = position_ + ExpPoly::monomial(y0, 0, lambda) + ExpPoly::monomial(v0 - lambda * y0, 1, lambda);
      displacement_ =
          ExpPoly::constant(-y0) + ExpPoly::monomial(y0, 0, lambda) + ExpPoly::monomial(v0 - lambda * y0, 1, lambda);
    }
    else
    {
      const double l1 = -0.5 * (p + s);
      const double l2 = q / l1;  // product of the roots is q; avoids cancellation
      const double c1 = (v0 - l2 * y0) / (l1 - l2);
      position_ = position_ + ExpPoly::monomial(c1, 0, l1) + ExpPoly::monomial(y0 - c1, 0, l2);
      displacement_ = ExpPoly::constant(-y0) + ExpPoly::monomial(c1, 0, l1) + ExpPoly::monomial(y0 - c1, 0, l2);
    }
  }
  else if (p_raw > 0.0 && p_raw * 2.0 * PI / params.naturalFrequency() <= 0.5)
  {
    // Constant torque, slow decay: the φ-function form (see modes.h); no ExpPoly, no cancellation, no rate merged.
    slow_effort_ = true;
    p_ = p_raw;
    r_ = r;
    return;
  }
  else if (p > 0.0)
  {
    // Effort mode: θ̈ + p θ̇ = r, velocity relaxes to r/p.
    const double v_inf = r / p;
    const double c = (v0 - v_inf) / p;
    position_ = ExpPoly::constant(x0 + c) + ExpPoly::monomial(v_inf, 1, 0.0) + ExpPoly::monomial(-c, 0, -p);
    displacement_ = ExpPoly::constant(c) + ExpPoly::monomial(v_inf, 1, 0.0) + ExpPoly::monomial(-c, 0, -p);
  }
  else
  {
    position_ = ExpPoly::constant(x0) + ExpPoly::monomial(v0, 1, 0.0) + ExpPoly::monomial(0.5 * r, 2, 0.0);
    displacement_ = ExpPoly::monomial(v0, 1, 0.0) + ExpPoly::monomial(0.5 * r, 2, 0.0);
  }
  velocity_ = position_.derivative();
  acceleration_ = velocity_.derivative();
  torque_ = acceleration_ * params.load_inertia + velocity_ * params.load_friction;
  if (torque_level_ != 0.0)
  {
    torque_.addConstant(torque_level_);
  }
}

double ContactMotion::phi1(double tau) const
{
  const double z = p_ * tau;
  return std::fabs(z) < 1e-3 ? tau * (1.0 - z / 2.0 * (1.0 - z / 3.0 * (1.0 - z / 4.0 * (1.0 - z / 5.0))))
                             : -std::expm1(-z) / p_;
}

double ContactMotion::phi2(double tau) const
{
  // (τ − Φ1)/p = τ² Σ_j (−z)^j/(j+2)!, by its series where z = pτ is small.
  const double z = p_ * tau;
  if (std::fabs(z) < 0.5)
  {
    double term = 0.5, sum = 0.0;  // (−z)^j/(j+2)!
    for (int j = 0; j < 40 && std::fabs(term) > 1e-18 * std::fabs(sum); ++j)
    {
      sum += term;
      term *= -z / (j + 3);
    }
    return tau * tau * sum;
  }
  return (tau - phi1(tau)) / p_;
}

double ContactMotion::timeOfVelocity(double v, double horizon) const
{
  // ω(τ) − v0 = (r − p v0) Φ1(τ), Φ1 increasing from 0 to 1/p: Φ1(τ*) = φ ⇒ τ* = −log1p(−pφ)/p.
  const double slope = r_ - p_ * v0_;
  if (slope == 0.0)
  {
    return INF;
  }
  const double phi = (v - v0_) / slope;
  if (!(phi > 0.0) || !(p_ * phi < 1.0))
  {
    return INF;
  }
  const double tau = -std::log1p(-p_ * phi) / p_;
  return tau > 0.0 && tau <= horizon ? tau : INF;
}

void ContactMotion::at(double tau, double* x, double* v) const
{
  if (slow_effort_)
  {
    *x = x0_ + v0_ * phi1(tau) + r_ * phi2(tau);
    *v = v0_ * std::exp(-p_ * tau) + r_ * phi1(tau);
    return;
  }
  if (oscillatory_)
  {
    const double e = std::exp(-sigma_ * tau);
    const double c = std::cos(omega_ * tau);
    const double s = std::sin(omega_ * tau);
    *x = x_eq_ + e * (a_ * c + b_ * s);
    *v = e * (vel_c_ * c + vel_d_ * s);
    return;
  }
  *x = position_(tau);
  *v = velocity_(tau);
}

double ContactMotion::meshTorque(double tau) const
{
  if (slow_effort_)
  {
    double x, v;
    at(tau, &x, &v);
    return params_.load_inertia * (r_ - p_ * v) + params_.load_friction * v + torque_level_;
  }
  if (oscillatory_)
  {
    return torque_level_ +
           std::exp(-sigma_ * tau) * (torque_c_ * std::cos(omega_ * tau) + torque_d_ * std::sin(omega_ * tau));
  }
  return torque_(tau);
}

int ContactMotion::downCrossings(Signal signal, double sign, double horizon, bool require_positive_first, double* out,
                                 int max_out) const
{
  if (!oscillatory_)
  {
    if (signal == Signal::LoadVelocity)
    {
      auto bound = [&](double tau) { return mode_rounding::roundingBound(velocity_, tau); };
      return walkDownCrossings(velocity_ * sign, bound, horizon, require_positive_first, out, max_out);
    }
    auto bound = [&](double tau) {
      return mode_rounding::combinedBound(acceleration_, params_.load_inertia, velocity_, params_.load_friction, tau);
    };
    return walkDownCrossings(torque_ * sign, bound, horizon, require_positive_first, out, max_out);
  }
  // e^{−στ}(C cos ωτ + D sin ωτ) = R e^{−στ} cos(ωτ − φ): down-crossings at ωτ − φ = π/2 + 2πk, exactly.
  const bool velocity = signal == Signal::LoadVelocity;
  const double c = sign * (velocity ? vel_c_ : torque_c_);
  const double d = sign * (velocity ? vel_d_ : torque_d_);
  if (c == 0.0 && d == 0.0)
  {
    return 0;
  }
  const double period = 2.0 * PI / omega_;
  double tau = (std::atan2(d, c) + 0.5 * PI) / omega_;
  if (tau <= 0.0)
  {
    tau += period;
  }
  // Starting at a zero while falling (f(0) ≈ 0, crossing within a quarter period) is not a fresh maximum.
  if (require_positive_first && c <= 64.0 * EPS * std::fabs(d) && omega_ * tau < 0.5 * PI)
  {
    tau += period;
  }
  int count = 0;
  for (; tau <= horizon && count < max_out; tau += period)
  {
    out[count++] = tau;
  }
  return count;
}

double ContactMotion::separationTime(double side, double horizon) const
{
  if (slow_effort_)
  {
    // Q = J_L (r − p ω) + f_L ω − T_ext is affine in the monotone ω: one crossing at most, where ω = ω*.
    const double slope = params_.load_friction - params_.load_inertia * p_;
    if (slope == 0.0)
    {
      return INF;
    }
    const double q_end = side * meshTorque(horizon);
    const double bound = 64.0 * EPS *
                         (params_.load_inertia * (std::fabs(r_) + p_ * std::fabs(v0_)) + std::fabs(torque_level_) +
                          params_.load_friction * std::fabs(v0_) + std::fabs(slope * r_ * horizon));
    if (!(q_end < -bound))
    {
      return INF;
    }
    const double v_star = -(params_.load_inertia * r_ + torque_level_) / slope;
    const double t = timeOfVelocity(v_star, horizon);
    return t < INF ? t : (side * meshTorque(0.0) <= 0.0 ? 0.0 : horizon);
  }
  if (oscillatory_ && torque_level_ != 0.0)
  {
    return levelSeparationTime(side, horizon);
  }
  double t;
  return downCrossings(Signal::MeshTorque, side, horizon, false, &t, 1) == 1 ? t : INF;
}

double ContactMotion::levelSeparationTime(double side, double horizon) const
{
  // f(τ) = side·(L + e^{−στ}(C cos ωτ + D sin ωτ)): monotone between the critical points of the sinusoid, which
  // come every π/ω (zeros of e^{−στ}((−σC + ωD) cos + (−σD − ωC) sin)); the first piece that ends below −rounding
  // holds the separation, refined by bisection to full precision.
  auto f = [&](double tau) { return side * meshTorque(tau); };
  auto bound = [&](double tau) {
    return 64.0 * EPS *
           (std::fabs(torque_level_) + std::exp(-sigma_ * tau) * (std::fabs(torque_c_) + std::fabs(torque_d_)));
  };
  const double dc = -sigma_ * torque_c_ + omega_ * torque_d_;
  const double dd = -sigma_ * torque_d_ - omega_ * torque_c_;
  const double half = PI / omega_;
  // The first critical point after 0: both maxima and minima of the sinusoid bound monotone pieces (none when the
  // torque has no oscillating part: it is the constant level).
  double crit = firstInHalfPeriod((dc == 0.0 && dd == 0.0) ? INF : (std::atan2(dd, dc) + 0.5 * PI) / omega_, half);
  double p = 0.0;
  double fp = f(0.0);
  for (int guard = 0; guard < 100000; ++guard)
  {
    const double q = std::min(crit, horizon);
    const double fq = f(q);
    if (fq < -bound(q))
    {
      if (!(fp > 0.0))
      {
        return p;  // already at or below zero at the piece's start (rounding level there)
      }
      return bisectChange([&](double tau) { return f(tau) > 0.0; }, p, q);
    }
    if (q >= horizon)
    {
      return INF;
    }
    p = q;
    fp = fq;
    crit += half;
  }
  return INF;
}

double ContactMotion::restTime(double sign, double horizon) const
{
  if (slow_effort_)
  {
    return timeOfVelocity(0.0, horizon);  // ω is monotone: at most one zero
  }
  double t;
  return downCrossings(Signal::LoadVelocity, sign, horizon, true, &t, 1) == 1 ? t : INF;
}

int ContactMotion::velocityTurns(double sign, double horizon, double* out, int max_out) const
{
  if (slow_effort_)
  {
    // ω is monotone: a turning point of θ_c needs sign·ω going from clearly + to clearly −.
    double x, v_end;
    at(horizon, &x, &v_end);
    const double bound = 64.0 * EPS * (std::fabs(v0_) + std::fabs(r_) * horizon);
    if (max_out < 1 || !(sign * v0_ > bound) || !(sign * v_end < -bound))
    {
      return 0;
    }
    const double t = timeOfVelocity(0.0, horizon);
    out[0] = t < INF ? t : horizon;
    return 1;
  }
  return downCrossings(Signal::LoadVelocity, sign, horizon, true, out, max_out);
}

int ContactMotion::velocityMaxima(double horizon, double* out, int max_out) const
{
  return velocityTurns(1.0, horizon, out, max_out);
}

int ContactMotion::velocityMinima(double horizon, double* out, int max_out) const
{
  return velocityTurns(-1.0, horizon, out, max_out);
}

double ContactMotion::exitTime(double lo, double hi, double horizon) const
{
  auto theta = [&](double tau) {
    double x, v;
    at(tau, &x, &v);
    return x;
  };
  double crit[EXP_POLY_MAX_ROOTS];
  int m = 0;
  if (slow_effort_)
  {
    const double t = timeOfVelocity(0.0, horizon);  // ω is monotone: one turning point at most
    if (t < INF)
    {
      crit[m++] = t;
    }
  }
  else if (oscillatory_)
  {
    // Zeros of ω = e^{−στ}(C cos ωτ + D sin ωτ): every π/ω from the first one after 0.
    const double half = PI / omega_;
    double t = firstInHalfPeriod(
        (vel_c_ == 0.0 && vel_d_ == 0.0) ? INF : (std::atan2(vel_d_, vel_c_) + 0.5 * PI) / omega_, half);
    for (; t < horizon && m < EXP_POLY_MAX_ROOTS; t += half)
    {
      crit[m++] = t;
    }
  }
  else
  {
    m = velocity_.signChangeRoots(0.0, horizon, crit, CRITICAL_POINT_TOLERANCE);
  }
  return firstExit(theta, crit, m, horizon, lo, hi, levelMagnitude(lo, hi));
}

double ContactMotion::displacement(double tau) const
{
  if (slow_effort_)
  {
    return v0_ * phi1(tau) + r_ * phi2(tau);
  }
  if (oscillatory_)
  {
    return std::exp(-sigma_ * tau) * (a_ * std::cos(omega_ * tau) + b_ * std::sin(omega_ * tau)) - a_;
  }
  return displacement_(tau);
}

EnergyFlows ContactMotion::energy(double tau) const
{
  // θ_c(τ) − θ_c(0) from its own closed form: far from the origin (|θ| ≫ the motion) a difference of positions
  // would lose the digits the energy needs.
  const double dx = displacement(tau);
  const double x1 = x0_ + dx;
  double v2;  // ∫ θ̇_c² dτ
  if (slow_effort_)
  {
    // 16-point Gauss–Legendre: ω² is e^{−2pτ}, e^{−pτ} and 1 with pτ ≤ 0.5 — exact to rounding.
    static const double nodes[8] = {0.0950125098376374, 0.2816035507792589, 0.4580167776572274, 0.6178762444026438,
                                    0.7554044083550030, 0.8656312023878318, 0.9445750230732326, 0.9894009349916499};
    static const double weights[8] = {0.1894506104550685, 0.1826034150449236, 0.1691565193950025, 0.1495959888165767,
                                      0.1246289712555339, 0.0951585116824928, 0.0622535239386479, 0.0271524594117541};
    v2 = 0.0;
    for (int i = 0; i < 8; ++i)
    {
      for (double sgn : {-1.0, 1.0})
      {
        double x, v;
        at(0.5 * tau * (1.0 + sgn * nodes[i]), &x, &v);
        v2 += weights[i] * v * v;
      }
    }
    v2 *= 0.5 * tau;
  }
  else if (oscillatory_)
  {
    // v² = e^{−2στ}[(C²+D²)/2 + (C²−D²)/2 cos 2ωτ + CD sin 2ωτ]
    const std::complex<double> osc = integralExp({-2.0 * sigma_, 2.0 * omega_}, tau);
    const double mean = ExpPoly::monomial(1.0, 0, -2.0 * sigma_).integral(tau);
    v2 = 0.5 * (vel_c_ * vel_c_ + vel_d_ * vel_d_) * mean + 0.5 * (vel_c_ * vel_c_ - vel_d_ * vel_d_) * osc.real() +
         vel_c_ * vel_d_ * osc.imag();
  }
  else
  {
    v2 = (velocity_ * velocity_).integral(tau);
  }
  const double rho = params_.gear_ratio;
  EnergyFlows e;
  // ω_m = θ̇_c / ρ and T_m = a − kθ_c: ∫T_m ω_m dt = (a Δθ − k Δ(θ²)/2) / ρ exactly.
  e.input = (input_.offset * dx - input_.stiffness * dx * 0.5 * (x1 + x0_)) / rho;
  e.motor_friction = params_.motor_friction / (rho * rho) * v2;
  e.load_friction = params_.load_friction * v2;
  e.load_work = params_.load_torque * dx;
  e.load_displacement = dx;
  e.motor_displacement = dx / rho;
  return e;
}
}  // namespace backlash_servo
