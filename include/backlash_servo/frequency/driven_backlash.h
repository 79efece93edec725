/**
 * @file driven_backlash.h
 * @brief The backlash element as the joint has it — rigid teeth with impacts and a load with inertia and friction —
 *        driven by a prescribed sine, and its describing functions from the exact periodic steady state (the numerical
 *        DF of the real element). No ROS dependency.
 *
 * **The element.** The motor's tooth (an infinitely heavy motor) moves as x(t) = ρθ_m = A sin ωt [rad]; the load
 * (J_L, f_L, T_cL, T_sL, the restitution e of the teeth; no load torque: the cycle is symmetric) sits in the free play
 * g = θ_c − x ∈ [0, Δ]:
 * - **free**: J_L θ̈_c = −f_L θ̇_c − T_cL sgn θ̇_c (closed form; a load at rest stays at rest: no torque moves it);
 * - **on a flank**: θ_c = x (g = 0) or x + Δ (g = Δ) while the tooth pushes, i.e. the torque the load needs,
 *   F(t) = J_L ẍ + f_L ẋ + T_cL sgn ẋ, has the flank's sign (≥ 0 forward, ≤ 0 backward); it separates where F changes
 *   sign — F = R sin(ωt + φ) + const between the tooth's reversals, so its zeros are in closed form;
 * - **impacts**: a free load reaching a flank leaves it with θ̇_c = ẋ − e(θ̇_c − ẋ) (the tooth's velocity is not
 *   changed); a chatter of bounces ends on the flank once the speed of arrival is below what an arrival found within
 *   the rounding tolerance ε gives, 4√(ε|F|/J_L), or 1e-10 Aω.
 * A free load's arrival at a flank is located without a step size: on a window the gap's second derivative lies
 * between bounds L ≤ g̈ ≤ U (the load's acceleration is monotone while it is free, the tooth's follows from the sine's
 * range), so g ≥ g_a + ġ_a τ + ½Lτ² and Δ − g ≥ Δ − g_a − ġ_a τ − ½Uτ² — a window where both quadratics stay positive
 * holds no impact; the others are halved until the gap crosses a flank at a window's end by more than rounding
 * (1e-13 (Δ + A)), refined by bisection to the last bit, or the window is shorter than 1e-12 of the period (a graze
 * within that tolerance is not an impact).
 *
 * **The describing functions.** From rest in the middle of the free play the element is driven period after period
 * until the state at a period's start repeats (within `tolerance` of Δ and of Aω, the same phase); over the next
 * period (a response that does not repeat — a subharmonic, a chaotic chatter —: the mean over the next 16) the
 * fundamentals of the load angle and of the torque the teeth pass to the load give
 *   N_θ = Θ₁/A,   N_T = T₁/A,   T₁ = (−ω² J_L + jω f_L) Θ₁ + T_cL S₁,
 * with the first harmonic y₁ of y taken so that y = A sin ωt has y₁ = A (N = (b₁ + j a₁)/A of describing_function.h)
 * and S₁ the fundamental of sgn θ̇_c (the impacts' impulses are in the −ω² J_L Θ₁ term: θ_c is continuous). Fourier
 * sums over 2¹² points of the period (the load angle is continuous with corners: errors O(2⁻²⁴); the sign's jumps:
 * O(2⁻¹²)). With a massless load that friction stops at once and e = 0 the element is the classical hysteresis: N_θ →
 * backlashDescribingFunction(A, Δ).
 */
#pragma once

#include <complex>

#include "backlash_servo/model/params.h"

namespace backlash_servo
{
struct DrivenBacklash
{
  std::complex<double> position;  ///< N_θ: the load angle's fundamental over A [-]
  std::complex<double> torque;    ///< N_T: the fundamental of the torque the teeth pass to the load over A [N·m/rad]
  bool periodic = false;          ///< a periodic steady state was reached (else: the mean over 16 periods)
  int periods = 0;                ///< periods driven before it repeated
  int impacts = 0;                ///< impacts per period analysed
};

/**
 * The element of `params` (its backlash, load inertia and friction, restitution) driven by x = A sin ωt, A
 * [rad] > 0, ω [rad/s] > 0, at most `max_periods` periods. Throws InvalidParameterError for a non-positive amplitude or
 * frequency, no backlash, or a load torque (the element's cycle is then not symmetric).
 */
DrivenBacklash drivenBacklash(const ServoParams& params, double amplitude, double omega, double tolerance = 1e-10,
                              int max_periods = 500);

/// What drivenBacklash refuses of `params` (InvalidParameterError naming the key), before it drives anything.
void requireDrivableBacklash(const ServoParams& params);

}  // namespace backlash_servo
