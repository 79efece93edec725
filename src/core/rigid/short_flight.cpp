#include "backlash_servo/rigid/short_flight.h"
#include "backlash_servo/model/constants.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <type_traits>

#include "numerics/event_search.h"

namespace backlash_servo
{
namespace
{
/// 1/k for k = 0..MAX_ORDER + 1 (0 unused): the series' recurrence divides by the order, the remainder bound by N + 1.
constexpr auto INVERSE = [] {
  std::array<double, ShortFlight::MAX_ORDER + 2> inv{};
  for (int k = 1; k <= ShortFlight::MAX_ORDER + 1; ++k)
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

/**
 * Calls f with std::integral_constant<int, N> for the orders flights mostly have (N = 2 … 6: chatter flights are
 * of order 3–4), else with N = 0 (the order then read at run time). The loops over the orders below take
 * `N ? N : n` as their length, so the compiler unrolls the common ones; the operations and their order are the
 * same either way (bit-identical results).
 */
template <class F>
decltype(auto) withOrder(int n, F&& f)
{
  switch (n)
  {
    case 2:
      return f(std::integral_constant<int, 2>{});
    case 3:
      return f(std::integral_constant<int, 3>{});
    case 4:
      return f(std::integral_constant<int, 4>{});
    case 5:
      return f(std::integral_constant<int, 5>{});
    case 6:
      return f(std::integral_constant<int, 6>{});
    default:
      return f(std::integral_constant<int, 0>{});
  }
}

/// Σ_{k≥1} c_k τ^k: the series' change from its start (no rounding of c_0 in it); order N (0: n ≥ 1 — a flight
/// keeps at least order 2).
template <int N = 0>
inline double increment(const double* c, int n, double tau)
{
  // Horner started at the top coefficient, not at 0·τ + c_N: the same values for a finite τ (0·τ is not folded by
  // the compiler, as τ could be infinite), one multiply-add less on the critical path of every impact.
  const int top = N ? N : n;
  double sum = c[top];
  for (int k = top - 1; k >= 1; --k)
  {
    sum = sum * tau + c[k];
  }
  return sum * tau;
}

/// Value of series c (order N; 0: n) at tau.
template <int N = 0>
inline double evaluate(const double* c, int n, double tau)
{
  return c[0] + increment<N>(c, n, tau);
}

/// The gap of a flight relative to the wall it left, F(τ) = Σ_{k≤n} f_k τ^k (> 0 in the free space), with bounds
/// over [0, T] on what its orders ≥ 3 and the series' remainder add to F'' (higher) and to F' (higher_slope).
struct GapSeries
{
  double f[ShortFlight::MAX_ORDER + 1];
  int n = 0;
  double higher = 0.0, higher_slope = 0.0;

  /// The bounds of the orders ≥ 3 and the remainder (two components in it) over [0, T]: `higher` on |F'' − 2f_2|
  /// and, with `slope` (a crossing), `higher_slope` on |F' − f_1 − 2f_2 τ|; from ||y_N||_D = weighted, T^{N−2},
  /// T^N and M·T (order N, 0: n).
  template <int N = 0>
  void boundHigherOrders(double t_end, double weighted, double t_power_2, double t_power, double mt, bool slope)
  {
    const int top = N ? N : n;
    double tk = t_end;
    for (int k = 3; k <= top; ++k, tk *= t_end)
    {
      higher += k * (k - 1) * std::fabs(f[k]) * tk;
    }
    higher += 2.0 * weighted * t_power_2 * (top * mt + 1.12 * mt * mt);  // 1/(1 − MT) ≤ 1.12
    if (slope)
    {
      // (the remainder's slope: 1.12·||y_N|| M T^N per component)
      tk = t_end * t_end;
      for (int k = 3; k <= top; ++k, tk *= t_end)
      {
        higher_slope += k * std::fabs(f[k]) * tk;
      }
      higher_slope += 2.0 * 1.12 * weighted * t_power * mt / t_end;
    }
  }

  /// F(τ) and F'(τ), order N (0: n).
  template <int N = 0>
  double value(double tau, double* slope) const
  {
    // Horner for F and F' together, its first two steps from 0 written out (as in increment(); n ≥ 2).
    const int top = N ? N : n;
    double d = f[top], v = f[top] * tau + f[top - 1];
    for (int k = top - 2; k >= 1; --k)
    {
      d = d * tau + v;
      v = v * tau + f[k];
    }
    *slope = d * tau + v;
    return v * tau + f[0];
  }

  /**
   * Back to the wall: certified concave on [0, T] (H < −f_2 gives 3f_2 < F'' < f_2 < 0), the rise below the other
   * wall (F'' ≤ 2f_2 + H < 0 bounds F by f_0 + f_1²/(−2(2f_2 + H))) and clear of the wall by more than the
   * rounding of F (its increments
   * are computed directly, so a bounce far below the rounding of the positions — micro-chatter — is resolved as well
   * as a large one: F(τq/2) ≥ f_0 + f_1 τq/2 + 3f_2 τq²/8 = f_0 + f_1 τq/8). The return is the only root past the
   * peak: Newton from a guess past the peak (F' < 0 there) — the quadratic return q = −f_1/f_2 corrected by the
   * cubic term (a Newton step on f_1 + f_2 τ + f_3 τ²) and by the start offset f_0 (the root of f_0 + f_1 τ + f_2 τ²
   * near q is q + δ, δ = f_0/f_1 + f_2 δ²/f_1, to second order); the first step lands at or beyond the root (the
   * tangent lies above F) and must stay in [0, T] with F back beyond the wall there; a step below 1e-8 of τ (error
   * below (1e-8)²·τ) ends the search as soon as it is taken, else monotone steps follow. In chatter the first step
   * is the last: with f_0 (up to the rounding of the positions, against bounces of 64–1000 times that) in the guess,
   * it is off by far less than 1e-8 of τ — one evaluation and one division per impact on the chain from one impact
   * to the next.
   */
  template <int N = 0>
  bool returnTime(double quadratic_return, double t_end, double near, double delta, double rounding, double* out) const
  {
    const double f1 = f[1], f2 = f[2];
    if (!(higher < -f2) || !(f[0] + f1 * f1 / (-2.0 * (2.0 * f2 + higher)) + 4.0 * near < delta) ||
        !(f[0] + 0.125 * f1 * quadratic_return > rounding))
    {
      return false;
    }
    const double f3 = (N ? N : n) >= 3 ? f[3] : 0.0;  // (N ≠ 0 is n: for N = 2, f[3] is not even read)
    const double offset = f[0] / f1;                  // δ to first order [s]
    double x = quadratic_return - f3 * quadratic_return * quadratic_return / (f2 + 2.0 * f3 * quadratic_return) +
               (offset + f2 * offset * offset / f1);
    double slope;
    double fx = value<N>(x, &slope);
    if (!(slope < 0.0) || !(x > 0.5 * quadratic_return))
    {
      return false;
    }
    const double first = fx / slope;
    x -= first;
    if (!(x <= t_end))
    {
      return false;
    }
    fx = value<N>(x, &slope);
    if (!(fx < rounding) || !(slope < 0.0))
    {
      return false;
    }
    if (std::fabs(first) <= 1e-8 * x)
    {
      *out = x;
      return x > 0.5 * quadratic_return;
    }
    for (int it = 0; it < 100; ++it)
    {
      const double step = fx / slope;
      const double candidate = x - step;
      if (!(candidate < x))
      {
        break;
      }
      x = candidate;
      if (step <= 1e-8 * x)
      {
        break;
      }
      fx = value<N>(x, &slope);
      if (!(slope < 0.0))
      {
        break;
      }
    }
    *out = x;
    return x > 0.5 * quadratic_return;
  }

  /**
   * Across to the other wall (F = Δ): F certified increasing on [0, T] (F' ≥ f_1 + 2 min(f_2, 0) T − the bound of
   * the rest > 0, or, leaving from relative rest, F'' ≥ 2f_2 − H > 0) and beyond Δ at T by more than its rounding, so
   * the crossing is the only root of F − Δ in (0, T]: Newton kept inside the shrinking bracket (bisection where a step
   * would leave it), to full precision.
   */
  template <int N = 0>
  bool crossingTime(double t_end, double delta, double rounding, double* out) const
  {
    // Increasing: F' bounded away from 0 on [0, T], or F' ≥ 0 at 0 and F'' > 0 on [0, T] (from relative rest).
    const bool increasing =
        f[1] + 2.0 * std::min(f[2], 0.0) * t_end - higher_slope > 0.0 || (f[1] >= 0.0 && 2.0 * f[2] > higher);
    double slope;
    const double f_end = value<N>(t_end, &slope) - delta;
    if (!increasing || !(f_end > rounding))
    {
      return false;
    }
    double a = 0.0, b = t_end;
    double x = b - f_end / slope;
    for (int it = 0; it < 200; ++it)
    {
      if (!(x > a && x < b))
      {
        x = 0.5 * (a + b);
      }
      const double fx = value<N>(x, &slope) - delta;
      if (fx == 0.0)
      {
        break;
      }
      (fx < 0.0 ? a : b) = x;
      const double next = x - fx / slope;
      if (b - a <= 2.0 * EPS * b)
      {
        x = b;
        break;
      }
      if (std::fabs(next - x) <= 2.0 * EPS * x && next >= a && next <= b)
      {
        x = next;
        break;
      }
      x = next;
    }
    *out = x;
    return x > 0.0 && x <= t_end;
  }
};
}  // namespace

ShortFlight::Model::Model(const ServoParams& p, const MotorInput& input)
    : load_friction(p.load_friction),
      motor_friction(p.motor_friction),
      load_torque(p.load_torque),
      offset(input.offset),
      stiffness(input.stiffness),
      alpha(p.load_friction / p.load_inertia),
      beta(p.motor_friction / p.motor_inertia),
      motor_stiffness(input.stiffness / p.motor_inertia),
      motor_offset(input.offset / p.motor_inertia),
      load_accel(p.load_torque / p.load_inertia),
      rho(p.gear_ratio),
      delta(p.backlash),
      omega_ref(std::max({alpha, beta, std::sqrt(rho * std::fabs(motor_stiffness))})),
      norm(omega_ref > 0.0 ? std::max({omega_ref, alpha, rho * std::fabs(motor_stiffness) / omega_ref + beta}) : 0.0),
      scale_time(omega_ref > 0.0 ? 1.0 / omega_ref : 0.0)
{}

bool ShortFlight::build(const Model& m, const State& s, double horizon)
{
  if (!solve(m, s, horizon, [](auto, double) {}))
  {
    return false;
  }
  model_ = m;
  return true;
}

bool ShortFlight::flyToImpact(const Model& m, const State& s, double horizon, State* end)
{
  return solve(m, s, horizon, [&](auto order, double tau) { evaluateAt<decltype(order)::value>(tau, end); });
}

template <int N>
void ShortFlight::evaluateAt(double tau, State* out) const
{
  out->load_position = evaluate<N>(load_position_, n_, tau);
  out->load_velocity = evaluate<N>(load_velocity_, n_, tau);
  out->motor_position = evaluate<N>(motor_position_, n_, tau);
  out->motor_velocity = evaluate<N>(motor_velocity_, n_, tau);
}

namespace
{
/// The wall a flight starts on (after an impact: within rounding of it): its gap level [rad] and the sign that makes
/// F = sign·(g − level) > 0 in the free space, with the rounding band `near` [rad] of the positions' scale.
struct StartWall
{
  Contact wall = Contact::Forward;
  double level = 0.0, sign = 1.0, near = 0.0, pos_scale = 0.0, g0 = 0.0;
};

/// False mid-gap (not the start of a chatter flight) or where the other wall is within rounding.
inline bool startWall(const ShortFlight::Model& m, const State& s, StartWall* w)
{
  const double rho = m.rho, delta = m.delta;
  const double pos_scale = w->pos_scale = std::fabs(s.load_position) + rho * std::fabs(s.motor_position) + delta;
  // The wall the teeth are on (after an impact: within rounding of it); F = sign·(g − level) > 0 in the free space.
  const double g0 = w->g0 = s.load_position - rho * s.motor_position;
  const double near = w->near = 64.0 * EPS * pos_scale;
  if (std::fabs(g0) <= near)
  {
    w->wall = Contact::Forward;
    w->level = 0.0;
    w->sign = 1.0;
  }
  else if (std::fabs(g0 - delta) <= near)
  {
    w->wall = Contact::Backward;
    w->level = delta;
    w->sign = -1.0;
  }
  else
  {
    return false;  // mid-gap: not the start of a chatter flight
  }
  if (!(delta > 4.0 * near))
  {
    return false;  // the other wall is within rounding
  }
  return true;
}

/// Where the flight ends by its quadratic f0 + f1 τ + f2 τ²: back on the same wall (pressed back, never reaching Δ)
/// or across on the other (its smaller root of = Δ, in the cancellation-free form) [s]; the series is then certified
/// over t_end, 1.5 or 1.25 times that. False when there is no such end within the horizon.
struct FlightSpan
{
  bool returns = false;
  double quadratic_return = 0.0, t_end = 0.0;
};

inline bool flightSpan(double f0, double f1, double f2, double delta, double horizon, FlightSpan* span)
{
  const double disc = f1 * f1 + 4.0 * f2 * (delta - f0);
  const bool returns = span->returns = f2 < 0.0 && !(disc > 0.0);
  if (!returns && !(disc > 0.0))
  {
    return false;
  }
  const double quadratic_return = span->quadratic_return =
      returns ? -f1 / f2 : 2.0 * (delta - f0) / (f1 + std::sqrt(disc));  // [s]
  span->t_end = (returns ? 1.5 : 1.25) * quadratic_return;
  if (!(span->t_end <= horizon))
  {
    return false;
  }
  return true;
}

/**
 * The Taylor coefficients y_k of the flight's state (θ_c, ω_c, θ_m, ω_m), written into the four arrays order by
 * order: y_1 = A y_0 + b, then y_{k+1} = A y_k/(k+1). The latest order is carried in registers (the fields below),
 * the arrays only written: the recurrence — on the path from one impact to the next — does not wait for its own
 * stores to be read back.
 */
struct FlightOrders
{
  double *xc, *vc, *xm, *vm;
  double y_xc, y_vc, y_xm, y_vm;  ///< the latest order
  double minus_alpha, minus_stiffness, beta;

  /// Orders 0 and 1 from the state s.
  template <class Model>
  FlightOrders(const Model& m, const State& s, double* load_position, double* load_velocity, double* motor_position,
               double* motor_velocity)
      : xc(load_position),
        vc(load_velocity),
        xm(motor_position),
        vm(motor_velocity),
        y_xc(s.load_velocity),
        y_vc(m.load_accel - m.alpha * s.load_velocity),
        y_xm(s.motor_velocity),
        y_vm(m.motor_offset - m.motor_stiffness * s.load_position - m.beta * s.motor_velocity),
        minus_alpha(-m.alpha),
        minus_stiffness(-m.motor_stiffness),
        beta(m.beta)
  {
    xc[0] = s.load_position;
    vc[0] = s.load_velocity;
    xm[0] = s.motor_position;
    vm[0] = s.motor_velocity;
    xc[1] = y_xc;
    vc[1] = y_vc;
    xm[1] = y_xm;
    vm[1] = y_vm;
  }

  /// y_{k+1} from y_k (k ≥ 1).
  void next(int k)
  {
    const double inv = INVERSE[k + 1];
    const double xc_next = y_vc * inv;
    const double vc_next = minus_alpha * y_vc * inv;
    const double xm_next = y_vm * inv;
    const double vm_next = (minus_stiffness * y_xc - beta * y_vm) * inv;
    xc[k + 1] = y_xc = xc_next;
    vc[k + 1] = y_vc = vc_next;
    xm[k + 1] = y_xm = xm_next;
    vm[k + 1] = y_vm = vm_next;
  }

  /// The latest order of the gap θ_c − ρθ_m [rad s^-k].
  double gap(double rho) const { return y_xc - rho * y_xm; }

  /// The latest order in the weighted norm ||y||_D = max(|θ_c|, s|ω_c|, ρ|θ_m|, sρ|ω_m|), s = scale_time [s].
  double weighted(double rho, double scale_time) const
  {
    return std::max(std::max(std::fabs(y_xc), rho * std::fabs(y_xm)),
                    scale_time * std::max(std::fabs(y_vc), rho * std::fabs(y_vm)));
  }
};

/// Where the series is cut: order n, ||y_n||_D, T^n and T^{n−2} (T the span certified [s]).
struct SeriesCut
{
  int n = 2;
  double weighted = 0.0, t_power = 0.0, t_power_2 = 1.0;
};

/**
 * The lowest order n ≥ 2 whose remainder on [0, T], R_N ≤ ||y_N|| T^N (MT/(N+1)) / (1 − MT/(N+2)) ≤ 1.03 ||y_N||
 * T^N MT/(N+1) (MT ≤ 0.1, N ≥ 2), is below tol; the orders up to it computed. False past MAX_ORDER.
 */
inline bool cutSeries(FlightOrders* y, double rho, double scale_time, double t_end, double tail_factor, double tol,
                      SeriesCut* cut)
{
  double weighted = 0.0, t_power = t_end * t_end, t_power_2 = 1.0;
  int n = 2;
  for (;; ++n)
  {
    weighted = y->weighted(rho, scale_time);
    if (weighted * t_power * tail_factor * INVERSE[n + 1] <= tol)
    {
      break;
    }
    if (n == ShortFlight::MAX_ORDER)
    {
      return false;
    }
    y->next(n);
    t_power *= t_end;
    t_power_2 *= t_end;
  }
  *cut = {n, weighted, t_power, t_power_2};
  return true;
}

/// The gap relative to the wall, F(τ) = Σ f_k τ^k, orders 0..2 given, the rest from the arrays of y (its order n
/// still in registers), the higher orders bounded over [0, t_end] [s].
template <int N>
inline void fillGap(GapSeries* gap, const FlightOrders& y, const SeriesCut& cut, double f0, double f1, double f2,
                    double sign, double rho, double t_end, double mt, bool slope)
{
  const int n = cut.n;
  const int top = N ? N : n;
  gap->n = n;
  gap->f[0] = f0;
  gap->f[1] = f1;
  gap->f[2] = f2;
  for (int k = 3; k < top; ++k)
  {
    gap->f[k] = sign * (y.xc[k] - rho * y.xm[k]);
  }
  if (top >= 3)
  {
    gap->f[top] = sign * y.gap(rho);
  }
  gap->boundHigherOrders<N>(t_end, cut.weighted, cut.t_power_2, cut.t_power, mt, slope);
}
}  // namespace

template <class AtImpact>
bool ShortFlight::solve(const Model& m, const State& s, double horizon, AtImpact&& at_impact)
{
  if (s.contact != Contact::Apart || !(horizon > 0.0))
  {
    return false;
  }
  const double rho = m.rho;
  const double delta = m.delta;
  StartWall start;
  if (!startWall(m, s, &start))
  {
    return false;
  }
  wall_ = start.wall;
  const double pos_scale = start.pos_scale, g0 = start.g0, near = start.near, level = start.level, sign = start.sign;
  FlightOrders y(m, s, load_position_, load_velocity_, motor_position_, motor_velocity_);
  const double f1 = sign * y.gap(rho);
  y.next(1);
  const double f2 = sign * y.gap(rho);
  const double f0 = sign * (g0 - level);
  if (!(f1 > 0.0) && !(f1 == 0.0 && f2 > 0.0))
  {
    return false;  // not leaving the wall (from relative rest: pulled away)
  }
  FlightSpan span;
  if (!flightSpan(f0, f1, f2, delta, horizon, &span))
  {
    return false;
  }
  const bool returns = span.returns;
  const double quadratic_return = span.quadratic_return, t_end = span.t_end;
  // Norm of A in the weighted norm ||y||_D = max(|θ_c|, s|ω_c|, ρ|θ_m|, sρ|ω_m|), s = 1/ω_ref.
  const double scale_time = m.omega_ref > 0.0 ? m.scale_time : 1e3 * t_end;
  const double mt = (m.omega_ref > 0.0 ? m.norm : 1.0 / scale_time) * t_end;
  if (!(mt <= MAX_NORM_TIME))
  {
    return false;
  }
  // The order: the remainder below 1 % of the rounding of the positions and of the velocities.
  const double vel_scale = std::fabs(s.load_velocity) + rho * std::fabs(s.motor_velocity);
  const double tol = 0.01 * EPS * std::min(pos_scale, scale_time * vel_scale);
  const double tail_factor = 1.03 * mt;
  SeriesCut cut;
  if (!cutSeries(&y, rho, scale_time, t_end, tail_factor, tol, &cut))
  {
    return false;
  }
  const int n = n_ = cut.n;
  const double weighted = cut.weighted;
  const double remainder = weighted * cut.t_power * tail_factor * INVERSE[n + 1];
  const double rounding_base = 8.0 * EPS * (std::fabs(f0) + f1 * t_end + (returns ? 0.0 : delta));
  // The gap series and its bounds are built inside the order dispatch: their loops unroll for the usual orders.
  const bool found = withOrder(n, [&](auto order) {
    constexpr int N = decltype(order)::value;
    GapSeries gap;
    fillGap<N>(&gap, y, cut, f0, f1, f2, sign, rho, t_end, mt, !returns);
    const double rounding = 2.0 * remainder + rounding_base;
    double x = 0.0;
    const bool root = returns ? gap.returnTime<N>(quadratic_return, t_end, near, delta, rounding, &x)
                              : gap.crossingTime<N>(t_end, delta, rounding, &x);
    // A flight shorter than the clock resolves (a few ulps of the start time: teeth at rest to 1e-40 rad/s
    // "bouncing" on rounding) would not advance time: left to the closed form, which sees no impact there.
    if (!root || !(x > 0.0 && x <= horizon) || !(x > 64.0 * EPS * std::fabs(s.time)))
    {
      return false;
    }
    impact_ = x;
    at_impact(order, x);
    return true;
  });
  if (!found)
  {
    return false;
  }
  if (!returns)
  {
    wall_ = wall_ == Contact::Forward ? Contact::Backward : Contact::Forward;
  }
  weighted_ = weighted;
  scale_time_ = scale_time;
  norm_time_ = mt;
  end_ = t_end;
  return true;
}

void ShortFlight::at(double tau, State* out) const
{
  withOrder(n_, [&](auto order) { evaluateAt<decltype(order)::value>(tau, out); });
}

EnergyFlows ShortFlight::energy(double tau) const
{
  double torque[MAX_ORDER + 1];  // T_m = a − k θ_c(τ) [N·m]
  torque[0] = model_.offset - model_.stiffness * load_position_[0];
  for (int k = 1; k <= n_; ++k)
  {
    torque[k] = -model_.stiffness * load_position_[k];
  }
  EnergyFlows e;
  e.input = integrateProduct(torque, motor_velocity_, n_, tau);
  e.motor_friction = model_.motor_friction * integrateProduct(motor_velocity_, motor_velocity_, n_, tau);
  e.load_friction = model_.load_friction * integrateProduct(load_velocity_, load_velocity_, n_, tau);
  e.load_displacement = increment(load_position_, n_, tau);
  e.motor_displacement = increment(motor_position_, n_, tau);
  e.load_work = model_.load_torque * e.load_displacement;
  return e;
}

double ShortFlight::exitTime(double lo, double hi, double horizon) const
{
  // θ_c's only possible extremum: where the monotone ω_c crosses zero (bisection on the series).
  double crit[1];
  int m = 0;
  const double v0 = load_velocity_[0], vh = evaluate(load_velocity_, n_, horizon);
  if ((v0 > 0.0 && vh < 0.0) || (v0 < 0.0 && vh > 0.0))
  {
    crit[m++] =
        bisectChange([&](double tau) { return (evaluate(load_velocity_, n_, tau) > 0.0) == (v0 > 0.0); }, 0.0, horizon);
  }
  return firstExit([&](double tau) { return evaluate(load_position_, n_, tau); }, crit, m, horizon, lo, hi,
                   levelMagnitude(lo, hi));
}

double ShortFlight::restTime(bool motor, double sign, double horizon) const
{
  const double* c = motor ? motor_velocity_ : load_velocity_;
  const double rho = motor ? model_.rho : 1.0;  // the weighted norm holds ρω_m
  // Bounds on [0, h] of the velocity's series tail and of its slope's tail (orders > N), from ||y_{N+j}||_D ≤
  // ||y_N||_D M^j N!/(N+j)! and |ω| ≤ ||y||_D/(s·ρ): Σ_j ... ≤ 1.03·||y_N|| h^N Mh/(N+1) and ≤ 1.12·||y_N|| M h^N.
  const double norm = norm_time_ / end_;  // M [1/s]
  const double h = horizon, mh = norm * h;
  double h_n = 1.0;
  for (int k = 0; k < n_; ++k)
  {
    h_n *= h;
  }
  const double unit = weighted_ / (scale_time_ * rho);
  const double tail = 1.03 * unit * h_n * mh / (n_ + 1);
  const double slope_tail = 1.12 * unit * norm * h_n;
  double spread = tail, slope_spread = slope_tail, hk = 1.0;  // Σ_{k≥1}|c_k|h^k, Σ_{k≥2} k|c_k|h^{k−1}
  for (int k = 1; k <= n_; ++k)
  {
    spread += std::fabs(c[k]) * hk * h;
    if (k >= 2)
    {
      slope_spread += k * std::fabs(c[k]) * hk;
    }
    hk *= h;
  }
  if (sign * c[0] > spread)
  {
    return INF;  // stays away from zero
  }
  if (!(std::fabs(c[1]) > slope_spread))
  {
    return std::numeric_limits<double>::quiet_NaN();  // not certified monotone
  }
  const double rounding = 8.0 * EPS * (std::fabs(c[0]) + spread);
  auto v = [&](double tau) { return sign * evaluate(c, n_, tau); };
  if (!(v(h) < -rounding))
  {
    return INF;
  }
  if (!(v(0.0) > 0.0))
  {
    return std::numeric_limits<double>::quiet_NaN();  // already at or below zero: the closed form's rule decides
  }
  return bisectChange([&](double tau) { return v(tau) > 0.0; }, 0.0, h);
}

}  // namespace backlash_servo
