// Private to the core: the matrix-vector products the linear modes' files share (linear_mode.cpp,
// linear_mode_crossings.cpp).
#pragma once

#include "numerics/mode_basis.h"

namespace backlash_servo
{
namespace mode_detail
{
/// a·x, plus u where given (plain loops: at these orders Eigen's general product costs more in dispatch than in
/// arithmetic). The product is summed before u is added, as Eigen does: near an equilibrium the two cancel, and the
/// event search's windows depend on how the rounding of that difference falls (adding u first made a stiff case halve
/// ten times as often).
inline ModeVector product(const ModeMatrix& a, const ModeVector& x, const ModeVector* u = nullptr)
{
  const Eigen::Index n = x.size();
  ModeVector y(n);
  for (Eigen::Index i = 0; i < n; ++i)
  {
    double sum = 0.0;
    for (Eigen::Index j = 0; j < n; ++j)
    {
      sum += a(i, j) * x(j);
    }
    y(i) = u != nullptr ? sum + (*u)(i) : sum;
  }
  return y;
}

/// a·x + u.
inline ModeVector affine(const ModeMatrix& a, const ModeVector& x, const ModeVector& u)
{
  return product(a, x, &u);
}
}  // namespace mode_detail
}  // namespace backlash_servo
