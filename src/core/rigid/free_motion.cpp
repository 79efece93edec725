// The apart mode (modes.h: BasicFreeMotion): the bodies apart in the free play, each under its own torques.
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/rigid/modes.h"
#include "numerics/event_search.h"
#include "numerics/gauss_legendre.h"
#include "rigid/mode_rounding.h"

namespace backlash_servo
{
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
    const double bound = mode_rounding::combinedBound(load_position_, 1.0, motor_position_, params_.gear_ratio, q);
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
    if (fq < -mode_rounding::roundingBound(v, q))
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
