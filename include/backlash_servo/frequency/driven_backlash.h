/**
 * @file driven_backlash.h
 * @brief The backlash element as the joint has it — rigid teeth with impacts and a load with inertia and friction —
 *        driven by a prescribed sine, and its describing functions from the exact periodic steady state (the numerical
 *        DF of the real element). No ROS dependency.
 *
 * How it is computed and what it guarantees: docs/model.md, Part 4, "The driven backlash element and its numerical
 * describing functions".
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
