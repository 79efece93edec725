/**
 * @file describing_function.h
 * @brief Classical describing functions (DF) of the backlash element — hysteresis (the play operator, half-width
 *        d = Δ/2 [rad]) and dead zone (half-width δ [rad]) — for the harmonic-balance prediction of limit cycles
 *        (G(jω) N(A) = −1) beside the exact simulation. N(A) = (b₁ + j a₁)/A, the complex gain of the fundamental for
 *        the input A sin ωt about the element's centre [rad]; N = 0 while A does not exceed the half-width. The closed
 *        forms and their sources: docs/describing_function.md, "Conventions". No ROS dependency.
 */
#pragma once

#include <complex>
#include <functional>
#include <vector>

namespace backlash_servo
{
/// The classical DF of backlash as hysteresis: input amplitude A [rad] about the input's centre, full backlash Δ
/// [rad] (d = Δ/2). Throws InvalidParameterError naming `amplitude` or `backlash` for a negative or non-finite value.
std::complex<double> backlashDescribingFunction(double amplitude, double backlash);

/// A solution of the harmonic balance: a predicted limit cycle.
struct HarmonicBalance
{
  double amplitude = 0.0;  ///< A, the fundamental's amplitude of the backlash element's input about its centre [rad]
  double frequency = 0.0;  ///< ω [rad/s]
  bool stable = false;     ///< Loeb's criterion: a small growth of A makes the loop's gain at the cycle fall below 1
};

/**
 * The solutions of G(jω) N(A) = −1 for the backlash DF (backlashDescribingFunction) with ω in [omega_lo, omega_hi]
 * [rad/s]: `g(ω)` is the loop's linear part as the element sees it (from the element's output back to its input,
 * sign included so that the loop closes with −1). Method: for each ω of a log grid (`points` of them) the DF value
 * the balance needs, N* = −1/G(jω), fixes A by the DF's magnitude (|N(A)| rises monotonically from 0 to 1); the
 * remaining phase mismatch arg N(A) − arg N* changes sign at each solution, which is refined by bisection in ω.
 * Stability (Loeb): with F = G N + 1 = U + jV, stable when ∂U/∂A ∂V/∂ω − ∂U/∂ω ∂V/∂A > 0 (central differences).
 * Throws InvalidParameterError naming `backlash` or `frequency` for bad input.
 */
std::vector<HarmonicBalance> backlashHarmonicBalance(const std::function<std::complex<double>(double)>& g,
                                                     double backlash, double omega_lo, double omega_hi,
                                                     int points = 2000);

/// The DF of a unit-slope dead zone of half-width δ [rad] at input amplitude A [rad]. Throws InvalidParameterError
/// naming `amplitude` or `half_width` for a negative or non-finite value.
double deadZoneDescribingFunction(double amplitude, double half_width);

/// The solutions of G(jω) N(A) = −1 for the dead zone's DF (deadZoneDescribingFunction, half-width δ [rad]), found as
/// backlashHarmonicBalance finds them: N is real, so they lie where G(jω) is real and ≤ −1. Throws
/// InvalidParameterError naming `half_width` or `frequency` for bad input.
std::vector<HarmonicBalance> deadZoneHarmonicBalance(const std::function<std::complex<double>(double)>& g,
                                                     double half_width, double omega_lo, double omega_hi,
                                                     int points = 2000);

}  // namespace backlash_servo
