#include "backlash_servo/rigid/modes.h"

#include "numerics/event_search.h"
#include "numerics/gauss_legendre.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

namespace backlash_servo
{
namespace
{
constexpr double EPS = std::numeric_limits<double>::epsilon();
constexpr double INF = std::numeric_limits<double>::infinity();
constexpr double PI = 3.14159265358979323846;

/// The first of the points τ + kπ/ω (k whole) in (0, half = π/ω], for τ = (atan2(·) + π/2)/ω in [−half/2, 3half/2]
/// (fmod is exact, so this equals one subtraction or addition of half); +inf (no such point) stays +inf. (A loop
/// subtracting half from +inf never ended: a mesh torque with no oscillating part, e.g. a load torque balancing the
/// motor's at the start, hung the simulator — found by the libFuzzer target.)
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

/// Rounding bound of f(τ), including that of its value (merging like terms can cancel, hiding the magnitudes the
/// rounding came from).
template <class Poly>
double roundingBound(const Poly& f, double tau)
{
  double b = 0.0;
  const double v = f.evaluate(tau, &b);
  return b + 16.0 * EPS * std::fabs(v);
}

/// Rounding bound of a·f(τ) + b·g(τ) from the bounds of its parts.
template <class Poly>
double combinedBound(const Poly& f, double a, const Poly& g, double b, double tau)
{
  return std::fabs(a) * roundingBound(f, tau) + std::fabs(b) * roundingBound(g, tau);
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
      auto bound = [&](double tau) { return roundingBound(velocity_, tau); };
      return walkDownCrossings(velocity_ * sign, bound, horizon, require_positive_first, out, max_out);
    }
    auto bound = [&](double tau) {
      return combinedBound(acceleration_, params_.load_inertia, velocity_, params_.load_friction, tau);
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

// ---------------------------------------------------------------------------------------------------------------
namespace
{
bool slowRate(double rate, double window, double limit = SLOW_RATE_WINDOW_PRODUCT)
{
  return rate != 0.0 && std::fabs(rate) * window <= limit;
}

bool equalRates(double a, double b)
{
  return std::fabs(a - b) <= EQUAL_RATE_FRACTION * std::max(std::fabs(a), std::fabs(b));
}

/// The rate a wide-form exponential is written around: 0 for a slow rate, the load rate α for a β that nearly
/// coincides with it, else the rate itself.
double clusterRate(double rate, double alpha, double window)
{
  if (rate == 0.0 || slowRate(rate, window, SERIES_RATE_WINDOW_PRODUCT))
  {
    return 0.0;
  }
  if (rate != alpha && !slowRate(alpha, window, SERIES_RATE_WINDOW_PRODUCT) &&
      (equalRates(rate, alpha) || slowRate(rate - alpha, window, SERIES_RATE_WINDOW_PRODUCT)))
  {
    return alpha;
  }
  return rate;
}

/// Highest degree of the Taylor polynomials of the wide form (products of two of them must fit WideExpPoly).
constexpr int SERIES_DEGREE = 15;

/**
 * y' + s y = f, y(0) = y0 in the wide form. Terms of f whose rate is far from −s get the usual particular solution
 * (back substitution dividing by r + s); the term at the cluster rate −s̄ (s̄ = clusterRate(s)) and the free decay
 * are solved together as Y(τ) e^{−s̄τ} with Y' + (s − s̄) Y = P, by the Taylor recursion
 * Y_{j+1} = (P_j − (s − s̄) Y_j)/(j + 1), which never divides by the slow s − s̄.
 */
WideExpPoly solveWide(const WideExpPoly& f, double s, double s_bar, double y0, double window)
{
  WideExpPoly cluster;
  WideExpPoly rest;
  for (int i = 0; i < f.termCount(); ++i)
  {
    const auto& t = f.term(i);
    (t.rate == -s_bar ? cluster : rest).addTerm(t.rate, t.coef.data(), t.degree);
  }
  WideExpPoly y = rest.solveFirstOrder(s);
  const double delta = s - s_bar;
  std::array<double, EXP_POLY_WIDE_DEGREE + 1> coef{};
  std::array<double, EXP_POLY_WIDE_DEGREE + 1> p{};
  int p_degree = -1;
  if (cluster.termCount() == 1)
  {
    p_degree = cluster.term(0).degree;
    std::copy(cluster.term(0).coef.begin(), cluster.term(0).coef.end(), p.begin());
  }
  coef[0] = y0 - y(0.0);
  double largest = std::fabs(coef[0]);
  int degree = 0;
  double wj = 1.0;  // W^j
  for (int j = 0; j < SERIES_DEGREE; ++j)
  {
    const double pj = j <= p_degree ? p[j] : 0.0;
    coef[j + 1] = (pj - delta * coef[j]) / (j + 1);
    wj *= window;
    const double size = std::fabs(coef[j + 1]) * wj;
    largest = std::max(largest, size);
    if (coef[j + 1] != 0.0)
    {
      degree = j + 1;
    }
    if (j >= p_degree && size <= 1e-20 * largest)
    {
      break;
    }
  }
  y.addTerm(-s_bar, coef.data(), degree);
  return y;
}
}  // namespace

bool apartNeedsSeries(const ServoParams& params, double window)
{
  const double alpha = params.load_friction / params.load_inertia;
  const double beta = params.motor_friction / params.motor_inertia;
  // A load torque on a frictionless body raises the polynomial degrees beyond the compact form's (θ_c quadratic,
  // θ_m quartic, and their products in the energy integrals).
  if (params.load_torque != 0.0 && (alpha == 0.0 || beta == 0.0))
  {
    return true;
  }
  return slowRate(alpha, window) || slowRate(beta, window) ||
         (alpha != 0.0 && beta != 0.0 && !equalRates(alpha, beta) && slowRate(beta - alpha, window));
}

template <>
BasicFreeMotion<ExpPoly>::BasicFreeMotion(const ServoParams& params, const MotorInput& input, const State& s,
                                          double /*window*/)
    : params_(params), input_(input), start_(s)
{
  // Every rate here is 0 or fast over the window (apartNeedsSeries() is false); equal rates are merged exactly.
  const double alpha = params.load_friction / params.load_inertia;
  double beta = params.motor_friction / params.motor_inertia;
  if (equalRates(alpha, beta))
  {
    beta = alpha;
  }
  const double x0 = s.load_position;
  const double v0 = s.load_velocity;
  if (params.load_torque != 0.0)
  {
    // J_L ω̇_c + f_L ω_c = T_ext: the particular solution plus the free decay matching ω_c(0).
    load_velocity_ = ExpPoly::constant(params.load_torque / params.load_inertia).solveFirstOrder(alpha);
    const double decay = v0 - load_velocity_(0.0);
    load_velocity_.addTerm(-alpha, &decay, 0);
    load_position_ = load_velocity_.antiderivative();
    load_position_.addConstant(x0 - load_position_(0.0));
  }
  else if (alpha > 0.0)
  {
    const double c = v0 / alpha;
    const double constant = x0 + c, decaying = -c;
    load_position_.addTerm(0.0, &constant, 0);
    load_position_.addTerm(-alpha, &decaying, 0);
    load_velocity_.addTerm(-alpha, &v0, 0);
  }
  else
  {
    const double line[2] = {x0, v0};
    load_position_.addTerm(0.0, line, 1);
    load_velocity_.addTerm(0.0, &v0, 0);
  }
  if (alpha > 0.0 && beta > 0.0 && alpha != beta && params.load_torque == 0.0)
  {
    // The generic case written out (same solution as the general path below, without its intermediate ExpPolys):
    // θ_c = C0 + C1 e^{−ατ}; ω_m = W0 + W1 e^{−ατ} + W2 e^{−βτ}; θ_m = M0 + W0 τ + M1 e^{−ατ} + M2 e^{−βτ}.
    const double c1 = -v0 / alpha, c0 = x0 - c1;
    const double f0 = (input.offset - input.stiffness * c0) / params.motor_inertia;
    const double f1 = -input.stiffness * c1 / params.motor_inertia;
    const double w0 = f0 / beta, w1 = f1 / (beta - alpha), w2 = s.motor_velocity - w0 - w1;
    const double m1 = -w1 / alpha, m2 = -w2 / beta;
    const double m[2] = {s.motor_position - m1 - m2, w0};
    motor_velocity_.addTerm(0.0, &w0, 0);
    motor_velocity_.addTerm(-alpha, &w1, 0);
    motor_velocity_.addTerm(-beta, &w2, 0);
    motor_position_.addTerm(0.0, m, 1);
    motor_position_.addTerm(-alpha, &m1, 0);
    motor_position_.addTerm(-beta, &m2, 0);
    const double rho = params.gear_ratio;
    const double g[2] = {c0 - rho * m[0], -rho * w0};
    const double ga = c1 - rho * m1, gb = -rho * m2;
    gap_.addTerm(0.0, g, 1);
    gap_.addTerm(-alpha, &ga, 0);
    gap_.addTerm(-beta, &gb, 0);
    flagLargeTerms();
    return;
  }
  // J_m ω̇_m + f_m ω_m = a − k θ_c(τ): particular solution plus the free decay e^{−βτ} matching ω_m(0).
  ExpPoly forcing = load_position_ * (-input.stiffness / params.motor_inertia);
  forcing.addConstant(input.offset / params.motor_inertia);
  motor_velocity_ = forcing.solveFirstOrder(beta);
  const double decay = s.motor_velocity - motor_velocity_(0.0);
  motor_velocity_.addTerm(-beta, &decay, 0);
  motor_position_ = motor_velocity_.antiderivative();
  motor_position_.addConstant(s.motor_position - motor_position_(0.0));
  gap_ = motor_position_ * -params.gear_ratio;
  gap_ += load_position_;
  flagLargeTerms();
}

template <>
BasicFreeMotion<WideExpPoly>::BasicFreeMotion(const ServoParams& params, const MotorInput& input, const State& s,
                                              double window)
    : params_(params), input_(input), start_(s)
{
  const double alpha = params.load_friction / params.load_inertia;
  const double beta = params.motor_friction / params.motor_inertia;
  // Load: ω_c' + α ω_c = T_ext/J_L; θ_c = x0 + ∫ω_c.
  WideExpPoly load_forcing;
  if (params.load_torque != 0.0)
  {
    load_forcing.addConstant(params.load_torque / params.load_inertia);
  }
  load_velocity_ = solveWide(load_forcing, alpha, clusterRate(alpha, alpha, window), s.load_velocity, window);
  load_position_ = load_velocity_.antiderivative();
  load_position_.addConstant(s.load_position - load_position_(0.0));
  // Motor: ω_m' + β ω_m = (a − k θ_c)/J_m; θ_m = θ_m0 + ∫ω_m.
  WideExpPoly forcing = load_position_ * (-input.stiffness / params.motor_inertia);
  forcing.addConstant(input.offset / params.motor_inertia);
  motor_velocity_ = solveWide(forcing, beta, clusterRate(beta, alpha, window), s.motor_velocity, window);
  motor_position_ = motor_velocity_.antiderivative();
  motor_position_.addConstant(s.motor_position - motor_position_(0.0));
  gap_ = motor_position_ * -params.gear_ratio;
  gap_ += load_position_;
  flagLargeTerms();
}

template <class Poly>
void BasicFreeMotion<Poly>::flagLargeTerms()
{
  // Σ|c| of the position forms at τ = 0 (evaluate's rounding bound is a fixed multiple of ε Σ|c|) against the
  // position scale: beyond 1e6× it, the direct form's rounding would exceed ~1e-10 of the scale.
  double load_bound = 0.0, motor_bound = 0.0;
  load_position_.evaluate(0.0, &load_bound);
  motor_position_.evaluate(0.0, &motor_bound);
  const double load_scale = std::fabs(start_.load_position) + params_.backlash;
  const double motor_scale = std::fabs(start_.motor_position) + params_.backlash / params_.gear_ratio;
  large_load_terms_ = load_bound > 1e6 * EPS * load_scale;
  large_motor_terms_ = motor_bound > 1e6 * EPS * motor_scale;
}

template <class Poly>
void BasicFreeMotion<Poly>::at(double tau, State* out) const
{
  // Where the closed form's terms are far larger than the motion (a light body under a huge torque: θ = c − c e^{−ατ}
  // with c ~ 1e8 rad for a displacement of 1e-11 rad), positions are start + increment, which keeps the rounding of
  // the motion, not of the coefficients; elsewhere the direct form (cheaper, and the golden outputs' form).
  out->load_position = large_load_terms_ ? start_.load_position + load_position_.increment(tau) : load_position_(tau);
  out->load_velocity = load_velocity_(tau);
  out->motor_position =
      large_motor_terms_ ? start_.motor_position + motor_position_.increment(tau) : motor_position_(tau);
  out->motor_velocity = motor_velocity_(tau);
}

template <class Poly>
double BasicFreeMotion<Poly>::impactTime(double horizon, Contact* wall) const
{
  double crit[EXP_POLY_MAX_ROOTS];
  const int m = gap_.derivative().signChangeRoots(0.0, horizon, crit, CRITICAL_POINT_TOLERANCE);
  const double delta = params_.backlash;
  double p = 0.0;
  double gp = gap_(0.0);
  for (int i = 0; i <= m; ++i)
  {
    const double q = i < m ? crit[i] : horizon;
    const double gq = gap_(q);
    // g = θ_c − ρθ_m cancels: its rounding is that of the positions, not of the (small) merged coefficients.
    const double bound = combinedBound(load_position_, 1.0, motor_position_, params_.gear_ratio, q);
    if (gq < -bound)
    {
      *wall = Contact::Forward;
      return gp > 0.0 ? gap_.refineBracket(0.0, p, gp, q, gq) : p;
    }
    if (gq > delta + bound + 4.0 * EPS * delta)
    {
      *wall = Contact::Backward;
      return gp < delta ? gap_.refineBracket(delta, p, gp - delta, q, gq - delta) : p;
    }
    p = q;
    gp = gq;
  }
  return INF;
}

template <class Poly>
double BasicFreeMotion<Poly>::exitTime(double lo, double hi, double horizon) const
{
  double crit[EXP_POLY_MAX_ROOTS];
  const int m = load_velocity_.signChangeRoots(0.0, horizon, crit, CRITICAL_POINT_TOLERANCE);
  return firstExit([&](double tau) { return load_position_(tau); }, crit, m, horizon, lo, hi, levelMagnitude(lo, hi));
}

template <class Poly>
double BasicFreeMotion<Poly>::restTime(bool motor, double sign, double horizon) const
{
  const Poly& v = motor ? motor_velocity_ : load_velocity_;
  double crit[EXP_POLY_MAX_ROOTS];
  const int m = v.derivative().signChangeRoots(0.0, horizon, crit, CRITICAL_POINT_TOLERANCE);
  // sign·ω is monotone between the critical points: the first piece that ends below −rounding holds the zero.
  double p = 0.0;
  double fp = sign * v(0.0);
  for (int i = 0; i <= m; ++i)
  {
    const double q = i < m ? crit[i] : horizon;
    const double fq = sign * v(q);
    if (fq < -roundingBound(v, q))
    {
      if (!(fp > 0.0))
      {
        return p > 0.0 ? p : q;  // already at zero where the piece begins (a critical point within rounding)
      }
      return bisectChange([&](double tau) { return sign * v(tau) > 0.0; }, p, q);
    }
    p = q;
    fp = fq;
  }
  return INF;
}

namespace
{
/// Most panels of the energy quadrature (beyond it, the closed form's integrals are kept).
constexpr int MAX_ENERGY_PANELS = 512;
/// The closed form's product integrals are replaced when their terms exceed the flows' size by more than this.
constexpr double ENERGY_CANCELLATION = 1e3;

/// Σ|terms| of f (its rounding scale) and max |f| at τ = 0 and τ = tau.
template <class Poly>
double termMagnitude(const Poly& f, double tau, double* value_max)
{
  double v0, s0, m0, v1, s1, m1;
  f.evaluateWithDerivative(0.0, &v0, &s0, &m0);
  f.evaluateWithDerivative(tau, &v1, &s1, &m1);
  *value_max = std::max(std::fabs(v0), std::fabs(v1));
  return std::max(m0, m1);
}
}  // namespace

template <class Poly>
bool BasicFreeMotion<Poly>::energyByQuadrature(const Poly& torque, double tau, EnergyFlows* e) const
{
  double torque_max, motor_max, load_max;
  const double torque_terms = termMagnitude(torque, tau, &torque_max);
  const double motor_terms = termMagnitude(motor_velocity_, tau, &motor_max);
  const double load_terms = termMagnitude(load_velocity_, tau, &load_max);
  const bool cancels = torque_terms * motor_terms > ENERGY_CANCELLATION * torque_max * motor_max ||
                       motor_terms * motor_terms > ENERGY_CANCELLATION * motor_max * motor_max ||
                       load_terms * load_terms > ENERGY_CANCELLATION * load_max * load_max;
  // The integrands are exponential polynomials with rates −α, −β (and their sums: at most 2·max(α, β)) times low
  // powers of τ: panels of 1/(2 max(α, β)) make the rule exact to rounding.
  const double rate =
      std::max(params_.load_friction / params_.load_inertia, params_.motor_friction / params_.motor_inertia);
  const double panels = std::max(1.0, std::ceil(2.0 * rate * tau));
  if (!cancels || !(panels <= MAX_ENERGY_PANELS))
  {
    return false;
  }
  const int n = static_cast<int>(panels);
  const double h = tau / n;
  // Every value as the start plus an increment (exact to the rounding of its own size, ExpPoly::increment).
  const double start_torque = input_.offset - input_.stiffness * start_.load_position;
  double input = 0.0, motor = 0.0, load = 0.0;
  for (int p = 0; p < n; ++p)
  {
    for (int i = 0; i < 8; ++i)
    {
      const double t = h * (p + 0.5 + 0.5 * GAUSS_NODE[i]);
      const double torque_t = start_torque - input_.stiffness * load_position_.increment(t);
      const double motor_t = start_.motor_velocity + motor_velocity_.increment(t);
      const double load_t = start_.load_velocity + load_velocity_.increment(t);
      input += GAUSS_WEIGHT[i] * torque_t * motor_t;
      motor += GAUSS_WEIGHT[i] * motor_t * motor_t;
      load += GAUSS_WEIGHT[i] * load_t * load_t;
    }
  }
  e->input = 0.5 * h * input;
  e->motor_friction = params_.motor_friction * 0.5 * h * motor;
  e->load_friction = params_.load_friction * 0.5 * h * load;
  e->load_displacement = load_position_.increment(tau);
  e->motor_displacement = motor_position_.increment(tau);
  e->load_work = params_.load_torque * e->load_displacement;
  return true;
}

template <class Poly>
EnergyFlows BasicFreeMotion<Poly>::energy(double tau) const
{
  Poly torque = load_position_ * -input_.stiffness;
  torque.addConstant(input_.offset);
  EnergyFlows e;
  if (energyByQuadrature(torque, tau, &e))
  {
    return e;
  }
  e.input = (torque * motor_velocity_).integral(tau);
  e.motor_friction = params_.motor_friction * (motor_velocity_ * motor_velocity_).integral(tau);
  e.load_friction = params_.load_friction * (load_velocity_ * load_velocity_).integral(tau);
  e.load_displacement = load_velocity_.integral(tau);
  e.motor_displacement = motor_velocity_.integral(tau);
  e.load_work = params_.load_torque * e.load_displacement;
  return e;
}

template class BasicFreeMotion<ExpPoly>;
template class BasicFreeMotion<WideExpPoly>;

}  // namespace backlash_servo
