/**
 * @file mode_rounding.h
 * @brief Rounding bounds of the modes' closed forms (contact and free motion): what a computed value of an
 *        exponential polynomial may be off by [its unit], so an event search never takes rounding for a crossing.
 */
#pragma once

#include <cmath>
#include <limits>

namespace backlash_servo
{
namespace mode_rounding
{
/// Rounding bound of f(τ), including that of its value (merging like terms can cancel, hiding the magnitudes the
/// rounding came from).
template <class Poly>
double roundingBound(const Poly& f, double tau)
{
  double b = 0.0;
  const double v = f.evaluate(tau, &b);
  return b + 16.0 * std::numeric_limits<double>::epsilon() * std::fabs(v);
}

/// Rounding bound of a·f(τ) + b·g(τ) from the bounds of its parts.
template <class Poly>
double combinedBound(const Poly& f, double a, const Poly& g, double b, double tau)
{
  return std::fabs(a) * roundingBound(f, tau) + std::fabs(b) * roundingBound(g, tau);
}
}  // namespace mode_rounding
}  // namespace backlash_servo
