/**
 * @file driven_mesh.h
 * @brief A compliant mesh's element as the joint has it — the load with its inertia and friction behind the
 *        teeth's spring and damper, across the free play — driven by a prescribed sine, and its describing functions
 *        from the exact periodic steady state (the numerical DF of a compliant element). No ROS dependency.
 *
 * **The element.** The motor's tooth (an infinitely heavy motor) moves as x(t) = ρθ_m = A sin ωt [rad]; the load
 * (J_L, f_L, dry friction T_cL/T_sL; no load torque) is coupled to it through the mesh of docs/model.md Part 3: on the
 * forward flank the penetration is y = x − θ_c − Δ/2, on the backward one y = θ_c − x − Δ/2 (the free play centred on
 * x), and while y > 0 and P > 0 the teeth push the load with P (forward +, backward −); otherwise they pass nothing.
 * `spring_damper`: P = c y + d ẏ; `msl_elastobacklash`: P = c y + d ẏ while d ẏ ≤ c y, 2c y while d ẏ > c y (its two
 * sub-modes, each a linear mode; a contact reached at the flank, ẏ > 0, starts in the second). The state (θ_c, θ̇_c, cos
 * ωt, sin ωt) makes every phase a linear mode with constant input — free flight J_L θ̈_c = −f_L θ̇_c, or contact with the
 * sine's forcing — solved in closed form by LinearMode, whose rigorous crossings locate the events: a flank's
 * penetration rising through 0 (contact), P falling through 0 (release, the torque would pull; y in msl's 2c y
 * sub-mode), after a release inside the flank P rising through 0 again (contact) or y falling through 0 (back in the
 * free play), and msl's sub-mode switch d ẏ − c y crossing 0. The sine's phase is set from the time at each segment's
 * start. **Dry friction** (docs/model.md's rest rule with a compliant mesh): a sliding load gets −T_cL sgn θ̇_c (a
 * constant input) and is watched for θ̇_c reaching 0; at rest it sticks while its holding torque — the mesh torque on
 * it, σP on flank σ, 0 in the free play — lies within [−T_sL, T_sL] (its rows of the mode frozen), else slides in the
 * direction of that torque; a stuck load is watched for the mesh torque leaving the band.
 *
 * **The describing functions** as driven_backlash.h: from rest at the centre, period after period until the state at
 * a period's start repeats (within `tolerance` of Δ and of Aω, the same phase); then over one period (the mean of 16
 * when it does not repeat) N_θ = Θ₁/A from 2¹² samples, and N_T, the torque the teeth pass, from the load's equation
 * Q = J_L θ̈_c + f_L θ̇_c + F: N_T = (−ω² J_L + jω f_L) N_θ + F₁/A, F₁ the dry friction's fundamental integrated
 * exactly over the analysed periods (T_cL·slide while sliding; the holding torque, by Gauss–Legendre, while stuck).
 * With Δ = 0 and d = 0 the element is the linear spring, N_θ = c/(−ω²J_L + jωf_L + c); with damping the never-pull
 * rule keeps it non-linear even at Δ = 0. Tested against both and, with backlash and damping under either law, with
 * and without dry friction, against a brute-force fixed-step integration.
 */
#pragma once

#include "backlash_servo/frequency/driven_backlash.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
/**
 * The compliant element of `params` (backlash ≥ 0, mesh_stiffness > 0, mesh_damping, mesh_law, load inertia, viscous
 * and dry friction) driven by x = A sin ωt, A [rad] > 0, ω [rad/s] > 0, at most `max_periods` periods. Throws
 * InvalidParameterError naming the key for what it does not take: no mesh stiffness, a load torque, a torsional
 * shaft, a non-positive amplitude or frequency.
 */
DrivenBacklash drivenCompliantMesh(const ServoParams& params, double amplitude, double omega, double tolerance = 1e-10,
                                   int max_periods = 500);

/// What drivenCompliantMesh refuses of `params` (InvalidParameterError naming the key), before it drives anything.
void requireDrivableMesh(const ServoParams& params);

/// What drivenElement refuses of `params`, before it drives anything.
void requireDrivable(const ServoParams& params);

/// The joint's own element driven by A sin ωt: the compliant one when mesh_stiffness > 0, else the rigid teeth's
/// (drivenBacklash).
DrivenBacklash drivenElement(const ServoParams& params, double amplitude, double omega);

}  // namespace backlash_servo
