/**
 * @file describing_function.h
 * @brief Classical describing functions (DF) of the backlash element, for the harmonic-balance prediction of limit
 *        cycles (G(jω) N(A) = −1) beside the exact simulation. No ROS dependency.
 *
 * A DF is the complex gain of the fundamental: for the input x(t) = A sin ωt, the output's first Fourier harmonic is
 * b₁ sin ωt + a₁ cos ωt and N(A) = (b₁ + j a₁)/A. Amplitudes are those of the element's input about its centre.
 *
 * **Backlash as hysteresis** (the play operator; a friction-controlled load that stops where the driving tooth leaves
 * it — Tustin; Chestnut & Mayer; Gelb & Vander Velde #48): the output follows the input shifted by d = Δ/2 while the
 * input pushes one flank, and stands still across the free play. With r = d/A (A > d):
 *   N_R = ½ + (1/π)[asin(1 − 2r) + 2(1 − 2r)√(r(1 − r))],   N_I = −(4/π) r(1 − r),
 * N = 0 for A ≤ d (the output never moves). E.g. A = 2d: N = ½ − j/π. The lag N_I < 0 is what makes the backlash
 * destabilising.
 *
 * **Dead zone** (a compliant mesh without backlash pre-load: the penetration, hence the mesh spring's torque c·y, is
 * zero within ±δ and grows with unit slope beyond): real, with s = δ/A (A > δ):
 *   N = 1 − (2/π)[asin s + s√(1 − s²)],   N = 0 for A ≤ δ.
 */
#pragma once

#include <complex>

namespace backlash_servo
{
/// The classical DF of backlash as hysteresis: input amplitude A [rad] about the input's centre, full backlash Δ
/// [rad] (d = Δ/2). Throws InvalidParameterError naming `amplitude` or `backlash` for a negative or non-finite value.
std::complex<double> backlashDescribingFunction(double amplitude, double backlash);

/// The DF of a unit-slope dead zone of half-width δ [rad] at input amplitude A [rad]. Throws InvalidParameterError
/// naming `amplitude` or `half_width` for a negative or non-finite value.
double deadZoneDescribingFunction(double amplitude, double half_width);

}  // namespace backlash_servo
