#include "backlash_servo/frequency/describing_function.h"

#include <cmath>
#include <functional>

#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/params.h"

namespace backlash_servo
{
namespace
{
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

namespace
{
/// An element's DF as a function of the input amplitude A [rad] alone.
using Df = std::function<std::complex<double>(double)>;

/// The A > a0 with |N(A)| = magnitude (0 < magnitude < 1), by bisection on the monotone |N| (0 at a0, the amplitude
/// below which the element's output does not move).
double amplitudeFor(double magnitude, const Df& df, double a0)
{
  double lo = a0, hi = 2.0 * a0;
  while (std::abs(df(hi)) < magnitude)
  {
    lo = hi;
    hi *= 2.0;
    if (!std::isfinite(hi))
    {
      return hi;
    }
  }
  for (int i = 0; i < 200; ++i)
  {
    const double mid = 0.5 * (lo + hi);
    if (!(mid > lo && mid < hi))
    {
      break;
    }
    (std::abs(df(mid)) < magnitude ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

/// At a frequency: the amplitude the balance's magnitude asks for and the phase mismatch arg N(A) − arg N* (wrapped
/// to (−π, π]); `ok` false where no amplitude fits (|N*| ≥ 1 or 0).
struct Mismatch
{
  bool ok = false;
  double amplitude = 0.0, phase = 0.0;
};
Mismatch mismatch(const std::function<std::complex<double>(double)>& g, const Df& df, double a0, double omega)
{
  Mismatch m;
  const std::complex<double> wanted = -1.0 / g(omega);
  const double magnitude = std::abs(wanted);
  if (!(magnitude > 0.0 && magnitude < 1.0) || !std::isfinite(magnitude))
  {
    return m;
  }
  m.amplitude = amplitudeFor(magnitude, df, a0);
  m.phase = std::arg(df(m.amplitude) / wanted);
  m.ok = std::isfinite(m.amplitude);
  return m;
}

void requireRange(double omega_lo, double omega_hi, int points)
{
  if (!std::isfinite(omega_lo) || !std::isfinite(omega_hi) || !(omega_lo > 0.0) || !(omega_hi > omega_lo) || points < 2)
  {
    throw InvalidParameterError("frequency", "the range " + formatNumber(omega_lo) + " … " + formatNumber(omega_hi) +
                                                 " rad/s must satisfy 0 < low < high, finite, with 2 points or more");
  }
}

/// The harmonic balance G(jω) N(A) = −1 of an element whose |N| rises monotonically from 0 at a0 to 1 (see
/// backlashHarmonicBalance).
std::vector<HarmonicBalance> harmonicBalance(const std::function<std::complex<double>(double)>& g, const Df& df,
                                             double a0, double omega_lo, double omega_hi, int points)
{
  std::vector<HarmonicBalance> out;
  const double ratio = std::pow(omega_hi / omega_lo, 1.0 / (points - 1));
  double w_prev = omega_lo;
  Mismatch prev = mismatch(g, df, a0, w_prev);
  for (int i = 1; i < points; ++i)
  {
    const double w = i == points - 1 ? omega_hi : omega_lo * std::pow(ratio, i);
    const Mismatch here = mismatch(g, df, a0, w);
    // A sign change of the mismatch away from its wrap at ±π is a solution.
    if (prev.ok && here.ok && (prev.phase <= 0.0) != (here.phase <= 0.0) && std::fabs(prev.phase - here.phase) < PI)
    {
      double lo = w_prev, hi = w;
      const bool rising = here.phase > prev.phase;
      for (int k = 0; k < 200; ++k)
      {
        const double mid = std::sqrt(lo * hi);
        if (!(mid > lo && mid < hi))
        {
          break;
        }
        const Mismatch m = mismatch(g, df, a0, mid);
        if (!m.ok)
        {
          break;
        }
        ((m.phase > 0.0) == rising ? hi : lo) = mid;
      }
      const double omega = std::sqrt(lo * hi);
      const Mismatch m = mismatch(g, df, a0, omega);
      if (m.ok)
      {
        HarmonicBalance h;
        h.amplitude = m.amplitude;
        h.frequency = omega;
        // Loeb: F(A, ω) = G(jω)N(A) + 1, central differences.
        const double da = 1e-6 * h.amplitude, dw = 1e-6 * omega;
        const auto f = [&](double a, double w2) { return g(w2) * df(a) + 1.0; };
        const std::complex<double> fa = (f(h.amplitude + da, omega) - f(h.amplitude - da, omega)) / (2.0 * da);
        const std::complex<double> fw = (f(h.amplitude, omega + dw) - f(h.amplitude, omega - dw)) / (2.0 * dw);
        h.stable = fa.real() * fw.imag() - fw.real() * fa.imag() > 0.0;
        out.push_back(h);
      }
    }
    prev = here;
    w_prev = w;
  }
  return out;
}
}  // namespace

std::vector<HarmonicBalance> backlashHarmonicBalance(const std::function<std::complex<double>(double)>& g,
                                                     double backlash, double omega_lo, double omega_hi, int points)
{
  if (!std::isfinite(backlash) || !(backlash > 0.0))
  {
    throw InvalidParameterError("backlash", formatNumber(backlash) + ": must be > 0 and finite [rad]");
  }
  requireRange(omega_lo, omega_hi, points);
  return harmonicBalance(
      g, [backlash](double a) { return backlashDescribingFunction(a, backlash); }, 0.5 * backlash, omega_lo, omega_hi,
      points);
}

std::vector<HarmonicBalance> deadZoneHarmonicBalance(const std::function<std::complex<double>(double)>& g,
                                                     double half_width, double omega_lo, double omega_hi, int points)
{
  if (!std::isfinite(half_width) || !(half_width > 0.0))
  {
    throw InvalidParameterError("half_width", formatNumber(half_width) + ": must be > 0 and finite [rad]");
  }
  requireRange(omega_lo, omega_hi, points);
  return harmonicBalance(
      g, [half_width](double a) { return std::complex<double>(deadZoneDescribingFunction(a, half_width), 0.0); },
      half_width, omega_lo, omega_hi, points);
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
