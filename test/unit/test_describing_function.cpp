// The classical describing functions (describing_function.h) against the first Fourier harmonic of the elements'
// outputs computed here by brute force: the play operator (backlash as hysteresis) and the dead zone driven by
// A sin θ over a period sampled densely, after a warm-up period.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>

#include "backlash_servo/describing_function.h"
#include "backlash_servo/params.h"

namespace
{
using namespace backlash_servo;

constexpr double PI = 3.14159265358979323846;
constexpr int SAMPLES = 1 << 18;

/// (b₁ + j a₁)/A of the output of `element` (called in time order) for the input A sin θ, over its second period.
template <class Element>
std::complex<double> firstHarmonic(double amplitude, Element element)
{
  double b1 = 0.0, a1 = 0.0;
  for (int period = 0; period < 2; ++period)
  {
    for (int k = 0; k < SAMPLES; ++k)
    {
      const double theta = 2.0 * PI * k / SAMPLES;
      const double y = element(amplitude * std::sin(theta));
      if (period == 1)
      {
        b1 += y * std::sin(theta);
        a1 += y * std::cos(theta);
      }
    }
  }
  return std::complex<double>(b1, a1) * (2.0 / SAMPLES) / amplitude;
}

TEST(DescribingFunction, BacklashIsThePlayOperatorsFundamental)
{
  const double backlash = 0.3, d = 0.5 * backlash;
  for (double ratio : {1.001, 1.05, 1.3, 2.0, 3.7, 10.0, 200.0})
  {
    SCOPED_TRACE(ratio);
    const double a = ratio * d;
    double centre = 0.0;  // the output: the load's position, moved only by a flank
    const std::complex<double> brute = firstHarmonic(a, [&](double x) {
      if (x - centre > d)
      {
        centre = x - d;
      }
      else if (x - centre < -d)
      {
        centre = x + d;
      }
      return centre;
    });
    const std::complex<double> n = backlashDescribingFunction(a, backlash);
    EXPECT_NEAR(n.real(), brute.real(), 1e-7);
    EXPECT_NEAR(n.imag(), brute.imag(), 1e-7);
    EXPECT_LT(n.imag(), 0.0);  // a lag
  }
  // A = 2d: N = ½ − j/π exactly; within the free play nothing moves; far beyond it the element is a unit gain.
  const std::complex<double> two_d = backlashDescribingFunction(2.0 * d, backlash);
  EXPECT_NEAR(two_d.real(), 0.5, 1e-15);
  EXPECT_NEAR(two_d.imag(), -1.0 / PI, 1e-15);
  EXPECT_EQ(backlashDescribingFunction(d, backlash), 0.0);
  EXPECT_EQ(backlashDescribingFunction(0.5 * d, backlash), 0.0);
  EXPECT_NEAR(std::abs(backlashDescribingFunction(1e6 * d, backlash) - 1.0), 0.0, 1e-5);
  EXPECT_EQ(backlashDescribingFunction(1.0, 0.0), 1.0);  // no backlash: the identity
}

TEST(DescribingFunction, DeadZoneIsItsFundamental)
{
  const double delta = 0.15;
  for (double ratio : {1.001, 1.05, 1.3, 2.0, 3.7, 10.0, 200.0})
  {
    SCOPED_TRACE(ratio);
    const double a = ratio * delta;
    const std::complex<double> brute = firstHarmonic(a, [&](double x) {
      return x > delta ? x - delta : x < -delta ? x + delta : 0.0;
    });
    EXPECT_NEAR(deadZoneDescribingFunction(a, delta), brute.real(), 1e-7);
    EXPECT_NEAR(brute.imag(), 0.0, 1e-9);  // a static, odd element: no phase
  }
  EXPECT_EQ(deadZoneDescribingFunction(delta, delta), 0.0);
}

TEST(DescribingFunction, BadInputIsNamed)
{
  const auto field = [](auto call) {
    try
    {
      call();
    }
    catch (const InvalidParameterError& e)
    {
      return e.field();
    }
    return std::string("(none)");
  };
  EXPECT_EQ(field([] { backlashDescribingFunction(-1.0, 0.3); }), "amplitude");
  EXPECT_EQ(field([] { backlashDescribingFunction(1.0, NAN); }), "backlash");
  EXPECT_EQ(field([] { deadZoneDescribingFunction(INFINITY, 0.1); }), "amplitude");
  EXPECT_EQ(field([] { deadZoneDescribingFunction(1.0, -0.1); }), "half_width");
}

}  // namespace
