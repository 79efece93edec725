/**
 * @file baselines.h
 * @brief What users would write instead of backlash_servo, for the benchmark only (never used by the product):
 *        the same hybrid model integrated numerically, with event handling done the usual ways.
 *
 *  - FixedStepRk4: the thesis' own method — classical RK4 with a fixed step, contact/impact/maxima tested only at
 *    step ends (no event location; an impact is applied at the first step end past the wall).
 *  - OdeintDense: Boost.Odeint's dense-output Dormand–Prince 5(4) with tight tolerances; events are bracketed by
 *    sign changes at step ends and refined by bisection on the dense output (a careful C++ user's approach).
 * Both use a velocity threshold for sticking (1e-7 rad/s), as such codes do.
 */
#pragma once

#include <array>
#include <cmath>
#include <vector>

#include <boost/numeric/odeint.hpp>

#include "backlash_servo/model/params.h"
#include "maxima.h"

namespace bench
{
using Vec = std::array<double, 4>;  // θ_c, ω_c, θ_m, ω_m

struct Outcome
{
  std::vector<Max> maxima;
  long events = 0;  // impacts + separations + maxima located
  long steps = 0;
};

/// The hybrid model shared by the baselines: modes, right-hand side, mesh torque, impact map.
class Model
{
 public:
  Model(const backlash_servo::ServoParams& p, double command) : p_(p), command_(command) {}
  int mode = 0;  // 0 forward contact, 1 backward contact, 2 apart

  double wallGap() const { return mode == 1 ? p_.backlash : 0.0; }
  double gap(const Vec& x) const { return x[0] - p_.gear_ratio * x[2]; }
  double motorTorque(const Vec& x) const { return p_.gain * (command_ - x[0]); }
  double contactAcc(const Vec& x) const
  {
    return (p_.gear_ratio * motorTorque(x) - p_.totalFriction() * x[1]) / p_.totalInertia();
  }
  double meshTorque(const Vec& x) const { return p_.load_inertia * contactAcc(x) + p_.load_friction * x[1]; }

  void rhs(const Vec& x, Vec& d) const
  {
    if (mode != 2)
    {
      const double a = contactAcc(x);
      d = {x[1], a, x[1] / p_.gear_ratio, a / p_.gear_ratio};
      return;
    }
    d = {x[1], -p_.load_friction * x[1] / p_.load_inertia, x[3],
         (motorTorque(x) - p_.motor_friction * x[3]) / p_.motor_inertia};
  }

  /// Contact still valid? (mesh torque presses into the wall)
  bool contactHolds(const Vec& x) const { return mode == 0 ? meshTorque(x) >= 0.0 : meshTorque(x) <= 0.0; }

  /// Applies the impact at wall w (0 or 1) and decides the next mode. Returns the load velocity before.
  double impact(Vec& x, int w) const
  {
    const double rho = p_.gear_ratio, jm = p_.motor_inertia, jl = p_.load_inertia;
    double e = p_.restitution;
    x[2] = (x[0] - (w == 1 ? p_.backlash : 0.0)) / rho;
    const double v = x[1], u = rho * x[3] - v;
    if (e * std::fabs(u) < 1e-7)
    {
      e = 0.0;
    }
    x[1] = v + jm * (1.0 + e) * u / (jm + rho * rho * jl);
    x[3] = (x[1] - e * u) / rho;
    return v;
  }

  void settle(Vec& x, int w)
  {
    mode = w;
    if (!contactHolds(x))
    {
      mode = 2;
    }
    else
    {
      x[3] = x[1] / p_.gear_ratio;
    }
  }

  const backlash_servo::ServoParams& params() const { return p_; }

 private:
  backlash_servo::ServoParams p_;
  double command_;
};

/// The thesis' method: fixed-step RK4, checks at step ends only.
inline Outcome fixedStepRk4(const backlash_servo::ServoParams& p, double command, double duration, double dt)
{
  Model m(p, command);
  Vec x{0, 0, 0, 0};
  Outcome out;
  const long n = static_cast<long>(std::llround(duration / dt));
  double prev_v = 0.0;
  for (long i = 1; i <= n; ++i)
  {
    Vec k1, k2, k3, k4, s;
    m.rhs(x, k1);
    for (int j = 0; j < 4; ++j)
      s[j] = x[j] + 0.5 * dt * k1[j];
    m.rhs(s, k2);
    for (int j = 0; j < 4; ++j)
      s[j] = x[j] + 0.5 * dt * k2[j];
    m.rhs(s, k3);
    for (int j = 0; j < 4; ++j)
      s[j] = x[j] + dt * k3[j];
    m.rhs(s, k4);
    const double before = x[0];
    for (int j = 0; j < 4; ++j)
      x[j] += dt / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
    ++out.steps;
    const double t = i * dt;
    if (m.mode != 2)
    {
      x[2] = (x[0] - m.wallGap()) / p.gear_ratio;
      if (!m.contactHolds(x))
      {
        m.mode = 2;
        ++out.events;
      }
    }
    else
    {
      const double g = m.gap(x);
      if (g < 0.0 || g > p.backlash)
      {
        const int w = g < 0.0 ? 0 : 1;
        const double v_before = m.impact(x, w);
        m.mode = 2;
        if (std::fabs(p.gear_ratio * x[3] - x[1]) < 1e-7)
        {
          m.settle(x, w);
        }
        ++out.events;
        if (v_before > 0.0 && x[1] <= 0.0 && x[0] > command)
        {
          out.maxima.push_back({t, x[0]});
          ++out.events;
        }
      }
    }
    if (prev_v > 0.0 && x[1] <= 0.0 && std::max(before, x[0]) > command &&
        (out.maxima.empty() || out.maxima.back().time != t))
    {
      out.maxima.push_back({before > x[0] ? t - dt : t, std::max(before, x[0])});
      ++out.events;
    }
    prev_v = x[1];
  }
  return out;
}

/// Boost.Odeint dense-output Dopri5 with events bracketed at step ends and bisected on the dense output.
inline Outcome odeintDense(const backlash_servo::ServoParams& p, double command, double duration, double tol)
{
  namespace oi = boost::numeric::odeint;
  Model m(p, command);
  Vec x{0, 0, 0, 0};
  Outcome out;
  double t = 0.0;
  auto system = [&m](const Vec& s, Vec& d, double) { m.rhs(s, d); };
  while (t < duration)
  {
    auto stepper = oi::make_dense_output(tol, tol, oi::runge_kutta_dopri5<Vec>());
    stepper.initialize(x, t, 1e-3);
    bool restarted = false;
    while (!restarted && stepper.current_time() < duration)
    {
      const double t0 = stepper.current_time();
      const Vec x0 = stepper.current_state();
      stepper.do_step(system);
      ++out.steps;
      const double t1 = std::min(stepper.current_time(), duration);
      Vec x1;
      stepper.calc_state(t1, x1);
      // Event functions: separation (mesh torque), walls (gap), maximum (velocity).
      auto eventValue = [&](int kind, const Vec& s) {
        if (kind == 0)
          return m.mode == 0 ? m.meshTorque(s) : -m.meshTorque(s);
        if (kind == 1)
          return m.gap(s);
        if (kind == 2)
          return p.backlash - m.gap(s);
        return s[1];
      };
      double first = t1;
      int which = -1;
      for (int kind = 0; kind < 4; ++kind)
      {
        if ((kind == 0 && m.mode == 2) || (kind != 0 && kind != 3 && m.mode != 2))
        {
          continue;
        }
        const double a0 = eventValue(kind, x0), a1 = eventValue(kind, x1);
        double lo = t0, hi = t1;
        if (kind == 1 || kind == 2)
        {
          // A wall is crossed if the gap ends beyond it. Starting on the wall (just after a bounce), a whole tiny
          // bounce can fit in one step: find a point inside where the gap is back in the interior first.
          if (!(a1 < 0.0))
          {
            continue;
          }
          if (a0 <= 0.0)  // on the wall (or a rounding past it) at the start
          {
            bool inside = false;
            for (int k = 1; k < 64 && !inside; ++k)
            {
              const double tk = t0 + (t1 - t0) * k / 64.0;
              Vec s;
              stepper.calc_state(tk, s);
              if (eventValue(kind, s) > 0.0)
              {
                lo = tk;
                inside = true;
              }
            }
            if (!inside)
            {
              hi = t0;  // moved straight into the wall: the impact is at the start
            }
          }
        }
        else if (!(a0 > 0.0 && a1 <= 0.0))
        {
          continue;
        }
        for (int it = 0; it < 200 && hi - lo > 1e-15 * std::max(1.0, hi); ++it)
        {
          const double mid = 0.5 * (lo + hi);
          Vec s;
          stepper.calc_state(mid, s);
          (eventValue(kind, s) > 0.0 ? lo : hi) = mid;
        }
        if (hi < first || (hi == first && which == 3))
        {
          first = hi;
          which = kind;
        }
      }
      if (which < 0)
      {
        x = x1;
        t = t1;
        continue;
      }
      stepper.calc_state(first, x);
      t = first;
      ++out.events;
      if (which == 3)
      {
        if (x[0] > command)
          out.maxima.push_back({t, x[0]});
        // Continue from the event without restarting (maximum does not change the mode).
        stepper.initialize(x, t, std::max(1e-9, t1 - t));
        continue;
      }
      if (which == 0)
      {
        m.mode = 2;
      }
      else
      {
        const int w = which == 1 ? 0 : 1;
        const double v_before = m.impact(x, w);
        m.mode = 2;
        if (std::fabs(p.gear_ratio * x[3] - x[1]) < 1e-7)
        {
          m.settle(x, w);
        }
        if (v_before > 0.0 && x[1] <= 0.0 && x[0] > command)
        {
          out.maxima.push_back({t, x[0]});
          ++out.events;
        }
      }
      restarted = true;
    }
    if (!restarted)
    {
      break;
    }
  }
  return out;
}

}  // namespace bench
