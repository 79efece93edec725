// Event location shared by the closed-form motions (modes.cpp, stuck_motion.cpp); private to the core.
#pragma once

#include <cmath>
#include <limits>

#include "backlash_servo/model/constants.h"

namespace backlash_servo
{
/**
 * Bisects [a, b] to full precision for the point where `before(τ)` stops holding (it holds at a, not at b, and
 * changes once in between): returns the last upper end, where it does not hold.
 */
template <class Before>
double bisectChange(const Before& before, double a, double b)
{
  for (int it = 0; it < 200 && b - a > 2.0 * EPS * b; ++it)
  {
    const double mid = 0.5 * (a + b);
    (before(mid) ? a : b) = mid;
  }
  return b;
}

/**
 * First τ in (0, horizon] where θ(τ) leaves [lo, hi] by more than its rounding, 64 ε (|θ| + magnitude), given the
 * critical points crit[0..m) of θ in (0, horizon) (θ is monotone between them): the piece where it happens is
 * bisected to full precision. +inf if none. magnitude: the size of the numbers θ is computed from (e.g. the levels).
 */
template <class Theta>
double firstExit(const Theta& theta, const double* crit, int m, double horizon, double lo, double hi, double magnitude)
{
  double p = 0.0;
  for (int i = 0; i <= m; ++i)
  {
    const double q = i < m ? crit[i] : horizon;
    const double xq = theta(q);
    const double bound = 64.0 * EPS * (std::fabs(xq) + magnitude);
    const bool above = xq > hi + bound;
    if (above || xq < lo - bound)
    {
      const double level = above ? hi : lo;
      return bisectChange(
          [&](double tau) {
            const double x = theta(tau);
            return !(above ? x > level : x < level);
          },
          p, q);
    }
    p = q;
  }
  return std::numeric_limits<double>::infinity();
}

/// The larger finite magnitude of two levels (0 for infinite ones): the rounding scale of an exit test.
inline double levelMagnitude(double lo, double hi)
{
  return std::fmax(std::isfinite(lo) ? std::fabs(lo) : 0.0, std::isfinite(hi) ? std::fabs(hi) : 0.0);
}

}  // namespace backlash_servo
