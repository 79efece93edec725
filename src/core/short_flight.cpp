#include "backlash_servo/short_flight.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "event_search.h"

namespace backlash_servo
{
namespace
{
constexpr double EPS = std::numeric_limits<double>::epsilon();

/// 1/k for k = 0..MAX_ORDER (0 unused): the series' recurrence divides by the order.
constexpr auto INVERSE = [] {
  std::array<double, ShortFlight::MAX_ORDER + 1> inv{};
  for (int k = 1; k <= ShortFlight::MAX_ORDER; ++k)
  {
    inv[k] = 1.0 / k;
  }
  return inv;
}();

/// ∫_0^τ a(t) b(t) dt for two series of order n: the product's coefficients integrated term by term.
double integrateProduct(const double* a, const double* b, int n, double tau)
{
  double sum = 0.0;
  for (int m = 2 * n; m >= 0; --m)
  {
    double c = 0.0;
    for (int i = std::max(0, m - n); i <= std::min(m, n); ++i)
    {
      c += a[i] * b[m - i];
    }
    sum = sum * tau + c / (m + 1);
  }
  return sum * tau;
}

/// Σ_{k≥1} c_k τ^k: the series' change from its start (no rounding of c_0 in it).
double increment(const double* c, int n, double tau)
{
  double sum = 0.0;
  for (int k = n; k >= 1; --k)
  {
    sum = sum * tau + c[k];
  }
  return sum * tau;
}
}  // namespace

double ShortFlight::evaluate(const double* c, double tau) const
{
  return c[0] + increment(c, n_, tau);
}

bool ShortFlight::build(const ServoParams& p, const MotorInput& input, const State& s, double horizon)
{
  if (s.contact != Contact::Apart || !(horizon > 0.0))
  {
    return false;
  }
  const double rho = p.gear_ratio;
  const double delta = p.backlash;
  const double alpha = p.load_friction / p.load_inertia;
  const double beta = p.motor_friction / p.motor_inertia;
  const double stiffness = input.stiffness / p.motor_inertia;  // k/J_m [1/s²]
  const double pos_scale = std::fabs(s.load_position) + rho * std::fabs(s.motor_position) + delta;
  // The wall the teeth are on (after an impact: within rounding of it); F = sign·(g − level) > 0 in the free space.
  const double g0 = s.load_position - rho * s.motor_position;
  const double near = 64.0 * EPS * pos_scale;
  double level, sign;
  if (std::fabs(g0) <= near)
  {
    wall_ = Contact::Forward;
    level = 0.0;
    sign = 1.0;
  }
  else if (std::fabs(g0 - delta) <= near)
  {
    wall_ = Contact::Backward;
    level = delta;
    sign = -1.0;
  }
  else
  {
    return false;  // mid-gap: not the start of a chatter flight
  }
  if (!(delta > 4.0 * near))
  {
    return false;  // the other wall is within rounding
  }
  // Orders 0..2 (y_1 = A y_0 + b, then y_{k+1} = A y_k/(k+1)).
  double* xc = load_position_;
  double* vc = load_velocity_;
  double* xm = motor_position_;
  double* vm = motor_velocity_;
  xc[0] = s.load_position;
  vc[0] = s.load_velocity;
  xm[0] = s.motor_position;
  vm[0] = s.motor_velocity;
  xc[1] = vc[0];
  vc[1] = p.load_torque / p.load_inertia - alpha * vc[0];
  xm[1] = vm[0];
  vm[1] = input.torque(xc[0]) / p.motor_inertia - beta * vm[0];
  auto next = [&](int k) {  // y_{k+1} from y_k, k ≥ 1
    const double inv = INVERSE[k + 1];
    xc[k + 1] = vc[k] * inv;
    vc[k + 1] = -alpha * vc[k] * inv;
    xm[k + 1] = vm[k] * inv;
    vm[k + 1] = (-stiffness * xc[k] - beta * vm[k]) * inv;
  };
  next(1);
  const double f1 = sign * (xc[1] - rho * xm[1]);
  const double f2 = sign * (xc[2] - rho * xm[2]);
  if (!(f1 > 0.0 && f2 < 0.0))
  {
    return false;  // not leaving the wall, or nothing presses the teeth back
  }
  const double quadratic_return = -f1 / f2;  // root of f1 τ + f2 τ² [s]
  const double t_end = 1.5 * quadratic_return;
  if (!(t_end <= horizon))
  {
    return false;
  }
  // Norm of A in the weighted norm ||y||_D = max(|θ_c|, s|ω_c|, ρ|θ_m|, sρ|ω_m|), s = 1/ω_ref.
  const double omega_ref = std::max({alpha, beta, std::sqrt(rho * std::fabs(stiffness))});
  const double scale_time = omega_ref > 0.0 ? 1.0 / omega_ref : 1e3 * t_end;
  const double norm = std::max({1.0 / scale_time, alpha, scale_time * rho * std::fabs(stiffness) + beta});
  const double mt = norm * t_end;
  if (!(mt <= MAX_NORM_TIME))
  {
    return false;
  }
  // Order: the remainder on [0, T] below 1 % of the rounding of the positions and of the velocities.
  const double vel_scale = std::fabs(s.load_velocity) + rho * std::fabs(s.motor_velocity);
  const double tol = 0.01 * EPS * std::min(pos_scale, scale_time * vel_scale);
  double weighted = 0.0, t_power = t_end * t_end;  // ||y_N||_D, T^N
  int n = 2;
  for (;; ++n)
  {
    weighted = std::max(
        {std::fabs(xc[n]), scale_time * std::fabs(vc[n]), rho * std::fabs(xm[n]), scale_time * rho * std::fabs(vm[n])});
    if (weighted * t_power * (mt / (n + 1)) / (1.0 - mt / (n + 2)) <= tol)
    {
      break;
    }
    if (n == MAX_ORDER)
    {
      return false;
    }
    next(n);
    t_power *= t_end;
  }
  n_ = n;
  const double remainder = weighted * t_power * (mt / (n + 1)) / (1.0 - mt / (n + 2));
  // The gap relative to the wall, F(τ) = Σ f_k τ^k (+ remainder ≤ 2R: two components in it).
  double f[MAX_ORDER + 1];
  f[0] = sign * (g0 - level);
  for (int k = 1; k <= n; ++k)
  {
    f[k] = sign * (xc[k] - rho * xm[k]);
  }
  // Concave on [0, T]: |Σ_{k≥3} k(k−1) f_k τ^{k−2}| plus the remainder's second derivative below −f'' (= −2 f_2).
  double higher = 0.0, tk = t_end;
  for (int k = 3; k <= n; ++k, tk *= t_end)
  {
    higher += k * (k - 1) * std::fabs(f[k]) * tk;
  }
  higher += 2.0 * weighted * (t_power / (t_end * t_end)) * (n * mt + mt * mt / (1.0 - mt));
  if (!(higher < -f2))
  {
    return false;
  }
  auto value = [&](double tau, double* slope) {
    double v = 0.0, d = 0.0;
    for (int k = n; k >= 1; --k)
    {
      d = d * tau + v;
      v = v * tau + f[k];
    }
    *slope = d * tau + v;
    return v * tau + f[0];
  };
  // The rise stays below the other wall (the tangent at 0 bounds a concave F); the gap rises above the wall and is
  // back beyond it at T, both by more than the rounding of F (its increments are computed directly, so a bounce far
  // below the rounding of the positions — micro-chatter — is resolved as well as a large one).
  const double rounding = 2.0 * remainder + 8.0 * EPS * (std::fabs(f[0]) + f1 * t_end);
  double slope;
  if (!(f[0] + f1 * t_end + 4.0 * near < delta) || !(value(0.5 * quadratic_return, &slope) > rounding))
  {
    return false;
  }
  // Newton from the quadratic return (past the peak, which is near half of it): for a concave F decreasing there,
  // the first step lands at or beyond the root (the tangent lies above F), and from there the iterates fall
  // monotonically to it. The first step must stay within [0, T], where F is certified concave, and the gap must be
  // back beyond the wall there (a root exists between the peak and it).
  double x = quadratic_return;
  double fx = value(x, &slope);
  if (!(slope < 0.0))
  {
    return false;
  }
  x -= fx / slope;
  fx = value(x, &slope);
  if (!(x <= t_end) || !(fx < rounding))
  {
    return false;
  }
  for (int it = 0; it < 100; ++it)
  {
    const double step = fx / slope;
    const double candidate = x - step;
    if (!(candidate < x) || !(slope < 0.0))
    {
      break;
    }
    x = candidate;
    fx = value(x, &slope);
  }
  if (!(x > 0.5 * quadratic_return && x <= horizon))
  {
    return false;
  }
  impact_ = x;
  params_ = p;
  input_ = input;
  return true;
}

void ShortFlight::at(double tau, State* out) const
{
  out->load_position = evaluate(load_position_, tau);
  out->load_velocity = evaluate(load_velocity_, tau);
  out->motor_position = evaluate(motor_position_, tau);
  out->motor_velocity = evaluate(motor_velocity_, tau);
}

EnergyFlows ShortFlight::energy(double tau) const
{
  double torque[MAX_ORDER + 1];  // T_m = a − k θ_c(τ) [N·m]
  torque[0] = input_.torque(load_position_[0]);
  for (int k = 1; k <= n_; ++k)
  {
    torque[k] = -input_.stiffness * load_position_[k];
  }
  EnergyFlows e;
  e.input = integrateProduct(torque, motor_velocity_, n_, tau);
  e.motor_friction = params_.motor_friction * integrateProduct(motor_velocity_, motor_velocity_, n_, tau);
  e.load_friction = params_.load_friction * integrateProduct(load_velocity_, load_velocity_, n_, tau);
  e.load_displacement = increment(load_position_, n_, tau);
  e.motor_displacement = increment(motor_position_, n_, tau);
  e.load_work = params_.load_torque * e.load_displacement;
  return e;
}

double ShortFlight::exitTime(double lo, double hi, double horizon) const
{
  // θ_c's only possible extremum: where the monotone ω_c crosses zero (bisection on the series).
  double crit[1];
  int m = 0;
  const double v0 = load_velocity_[0], vh = evaluate(load_velocity_, horizon);
  if ((v0 > 0.0 && vh < 0.0) || (v0 < 0.0 && vh > 0.0))
  {
    double a = 0.0, b = horizon;
    for (int it = 0; it < 200 && b - a > 2.0 * EPS * b; ++it)
    {
      const double mid = 0.5 * (a + b);
      ((evaluate(load_velocity_, mid) > 0.0) == (v0 > 0.0) ? a : b) = mid;
    }
    crit[m++] = b;
  }
  return firstExit([&](double tau) { return evaluate(load_position_, tau); }, crit, m, horizon, lo, hi,
                   levelMagnitude(lo, hi));
}

}  // namespace backlash_servo
