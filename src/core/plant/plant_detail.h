// Private to the core: what the rigid plant's files share (plant.cpp: segments and the run loop; plant_impacts.cpp:
// impacts and chatter; plant_rest.cpp: dry friction and the rest rule).
#pragma once

#include <cmath>
#include <limits>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
namespace plant_detail
{
/// Apart mode: impacts are searched this far ahead per segment [natural periods] (fastest on the benchmarks).
constexpr double FREE_SEARCH_PERIODS = 0.5;
/// Contact mode: separations and maxima are searched this far ahead per segment [natural periods].
constexpr double CONTACT_SEARCH_PERIODS = 1.0;

/// Apart, the load alone under its viscous friction and a constant torque T [N·m] (the load torque): J_L ω̇ + f_L ω = T,
/// so ω relaxes monotonically to T/f_L and turns from + to − at most once — a maximum of θ_c inside the flight — at
/// τ* = (v0 J_L/(−T))·log1p(x)/x, x = v0 f_L/(−T) (→ v0 J_L/(−T) without friction). τ* [s] if in (0, horizon], else
/// +inf.
inline double loadTurnaround(const ServoParams& p, double v0, double horizon)
{
  const double t = p.load_torque;
  if (!((v0 > 0.0 && t < 0.0) || (v0 < 0.0 && t > 0.0)))
  {
    return INFINITY;
  }
  const double x = std::fabs(v0) * p.load_friction / std::fabs(t);
  const double tau = std::fabs(v0) * p.load_inertia / std::fabs(t) * (x > 0.0 ? std::log1p(x) / x : 1.0);
  return tau > 0.0 && tau <= horizon ? tau : INFINITY;
}
}  // namespace plant_detail
}  // namespace backlash_servo
