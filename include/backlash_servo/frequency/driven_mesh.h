/**
 * @file driven_mesh.h
 * @brief A compliant mesh's element as the joint has it — the load with its inertia and friction behind the
 *        teeth's spring and damper, across the free play — driven by a prescribed sine, and its describing functions
 *        from the exact periodic steady state (the numerical DF of a compliant element). No ROS dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "The driven compliant element".
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
