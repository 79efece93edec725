#include "backlash_servo/describing_function.h"

#include <cmath>

#include "backlash_servo/params.h"

namespace backlash_servo
{
namespace
{
constexpr double PI = 3.14159265358979323846;

void requireLength(const char* key, double value)
{
  if (!std::isfinite(value) || value < 0.0)
  {
    throw InvalidParameterError(key, formatNumber(value) + ": must be a finite length ≥ 0 [rad]");
  }
}
}  // namespace

std::complex<double> backlashDescribingFunction(double amplitude, double backlash)
{
  requireLength("amplitude", amplitude);
  requireLength("backlash", backlash);
  const double d = 0.5 * backlash;
  if (!(amplitude > d))
  {
    return 0.0;
  }
  const double r = d / amplitude, m = 1.0 - 2.0 * r;
  const double real = 0.5 + (std::asin(m) + 2.0 * m * std::sqrt(r * (1.0 - r))) / PI;
  const double imag = -4.0 / PI * r * (1.0 - r);
  return {real, imag};
}

double deadZoneDescribingFunction(double amplitude, double half_width)
{
  requireLength("amplitude", amplitude);
  requireLength("half_width", half_width);
  if (!(amplitude > half_width))
  {
    return 0.0;
  }
  const double s = half_width / amplitude;
  return 1.0 - 2.0 / PI * (std::asin(s) + s * std::sqrt(1.0 - s * s));
}

}  // namespace backlash_servo
