/**
 * @file identify_mesh.h
 * @brief A joint with a compliant mesh identified from a recording of its own motion: the start of a fit for teeth that
 *        are springs (mesh_stiffness > 0) — the bodies, the mesh's stiffness and damping, the backlash between its
 *        flanks, the static friction — by linear least squares, from the data alone. No ROS dependency.
 *
 * Recording, derivatives and smoothing as in identification.h; g = θ_c − ρθ_m the gap, ġ its central difference.
 *
 * **The bodies.** Whatever the mesh transmits is internal to the joint: ρ × the load's equation added to the motor's
 * eliminates it, so at every sample where both bodies move (the sign of each velocity the same over the stencil)
 *   ū = J_m α_m + f_m ω_m + T_cm sgn ω_m + ρ (J_L α_c + f_L ω_c + T_cL sgn ω_c − T_ext),
 * contact or free play alike — one fit for the seven body parameters over the whole recording (the free play tells the
 * inertias apart: in a stiff contact α_c ≈ ρα_m). A load moving one way only leaves T_cL and T_ext as one constant,
 * split with the settings' load torque as in identification.h.
 *
 * **The mesh** (`mesh_law: spring_damper`, model.md). The load's equation gives the torque the mesh transmits,
 * τ = J_L α_c + f_L ω_c + T_cL sgn ω_c − T_ext. Past the forward flank (g < g₀) τ = c (g₀ − g) − d ġ, past the backward
 * one (g > g₀ + Δ) τ = −c (g − g₀ − Δ) − d ġ, so on the samples where τ clearly pushes (|τ| above a tenth of its
 * typical peak — the 99th percentile of |τ| — over the sample, the difference stencil and the filter's support, its
 * sign naming the flank) τ = −c g − d ġ + b_f [forward] + b_b [backward], one fit for c, d and the flanks: g₀ = b_f / c
 * (the zero offset), Δ = (b_b − b_f) / c, their standard errors by the fit's covariance carried through (first order).
 *
 * **Static friction from the rests.** With a compliant mesh each body sticks on its own: a run of minimumRest()
 * samples over which its angle stays within the contact band is a rest, and the net torque on it at the samples inside
 * — |u_k − ρτ_k| on the motor, |τ_k + T_ext| on the load, τ_k from the gap by the law above — was held by its static
 * band (a lower bound on T_s); at the first sample after the rest it had broken away (an upper bound). The mesh's
 * torque changes within the interval of a breakaway (it follows the other body), so the bounds may cross by that
 * change: the level is then their middle, their distance its scatter (RestBounds otherwise). With measured angles (a
 * contact band given) the filter blurs the instant of a breakaway, while the mesh's torque moves fast: only the lower
 * bound is kept (the level "at least"), from the samples of a rest clear of its ends by the filter's support.
 *
 * **What the samples must resolve.** Differences see the contact only when its natural frequency √(c/μ) (μ the
 * reduced inertia, model.md) is well below the sample rate — about a tenth of the sampling frequency in rad/s,
 * ω_s = 2π/h; a stiffer mesh looks rigid to the data (a contact shorter than a few samples is an impact), and is
 * identified as rigid teeth with a restitution (identification.h; the rigid limit in model.md links the two).
 */
#pragma once

#include "backlash_servo/identification/identification.h"

namespace backlash_servo
{
/**
 * The initial estimates of a joint with a compliant mesh (InitialEstimates::mesh_stiffness and mesh_damping set; the
 * restitution has no meaning here). Throws InvalidParameterError naming what is missing: the checks of
 * samplePeriod(), too few samples with both bodies moving, a mesh pressed on one flank only (the recording needs
 * contact on both), or a mesh stiffness that does not come out positive (the contact is not resolved by the samples).
 */
InitialEstimates estimateCompliantInitial(const Recording& data, const IdentificationSettings& settings);

}  // namespace backlash_servo
