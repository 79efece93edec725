// Private to the core: small helpers the compliant joint's files share (compliant_joint.cpp, compliant_rest.cpp,
// compliant_energy.cpp, rigid_teeth_modes.cpp).
#pragma once

#include <cmath>
#include <limits>

#include "compliant/compliant_joint.h"
#include "numerics/linear_mode.h"

namespace backlash_servo
{
namespace compliant_detail
{
/// The mode presses (or enters) the forward flank.
inline bool isForward(MeshMode m)
{
  return m == MeshMode::Forward || m == MeshMode::ForwardK2;
}
/// msl_elastobacklash's 2c·y sub-mode.
inline bool isK2(MeshMode m)
{
  return m == MeshMode::ForwardK2 || m == MeshMode::BackwardK2;
}

/// What rounding can do to an output w·x + w₀ of a state x whose entries are known to their last bits (the angles or
/// speeds it is the difference of).
/// (Templated: a state held as Eigen::VectorXd is read in place, not copied into a ModeVector.)
template <class W, class X>
double roundingOf(const Eigen::MatrixBase<W>& w, double w0, const Eigen::MatrixBase<X>& x)
{
  return 64.0 * std::numeric_limits<double>::epsilon() * (w.cwiseAbs().dot(x.cwiseAbs()) + std::fabs(w0));
}
}  // namespace compliant_detail
}  // namespace backlash_servo
