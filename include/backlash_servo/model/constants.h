/**
 * @file constants.h
 * @brief The numeric constants of the core, declared once: π and 2π [rad], the double's machine epsilon (the relative
 *        rounding unit) and infinity. No ROS dependency.
 */
#pragma once

#include <limits>

namespace backlash_servo
{
constexpr double PI = 3.14159265358979323846;                   ///< [rad]
constexpr double TWO_PI = 2.0 * PI;                             ///< [rad], exact: doubling does not round
constexpr double EPS = std::numeric_limits<double>::epsilon();  ///< the relative rounding unit of a double
constexpr double INF = std::numeric_limits<double>::infinity();
}  // namespace backlash_servo
