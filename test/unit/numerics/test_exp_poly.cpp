// Exponential polynomials: evaluation, calculus and exact root isolation, checked against direct formulas.
#include <gtest/gtest.h>

#include <cmath>

#include "backlash_servo/numerics/exp_poly.h"

using namespace backlash_servo;

TEST(ExpPoly, CalculusMatchesDirectFormulas)
{
  // f = 2 + 3τ e^{-τ} − τ² e^{-2τ}
  const ExpPoly f = ExpPoly::constant(2.0) + ExpPoly::monomial(3.0, 1, -1.0) + ExpPoly::monomial(-1.0, 2, -2.0);
  for (double t : {0.0, 0.3, 1.7, 5.0})
  {
    const double direct = 2.0 + 3.0 * t * std::exp(-t) - t * t * std::exp(-2.0 * t);
    EXPECT_NEAR(f(t), direct, 1e-15);
    const double deriv = 3.0 * (1.0 - t) * std::exp(-t) - (2.0 * t - 2.0 * t * t) * std::exp(-2.0 * t);
    EXPECT_NEAR(f.derivative()(t), deriv, 1e-14);
  }
  // ∫_0^T by composite Simpson with many panels.
  for (double upper : {1e-6, 0.5, 3.0, 40.0})
  {
    const int n = 20000;
    const double h = upper / n;
    double s = f(0.0) + f(upper);
    for (int i = 1; i < n; ++i)
    {
      s += (i % 2 ? 4.0 : 2.0) * f(i * h);
    }
    EXPECT_NEAR(f.integral(upper), s * h / 3.0, 1e-10 * std::max(1.0, upper)) << upper;
    const ExpPoly a = f.antiderivative();
    EXPECT_NEAR(a(upper) - a(0.0), f.integral(upper), 1e-12 * std::max(1.0, upper));
  }
}

TEST(ExpPoly, FirstOrderSolutionSatisfiesTheOde)
{
  const ExpPoly f = ExpPoly::constant(1.5) + ExpPoly::monomial(2.0, 1, -0.7) + ExpPoly::monomial(1.0, 0, -3.0);
  for (double s : {0.0, 0.7, 3.0, 1.2})  // includes both resonances
  {
    const ExpPoly y = f.solveFirstOrder(s);
    for (double t : {0.0, 0.5, 2.0})
    {
      EXPECT_NEAR(y.derivative()(t) + s * y(t), f(t), 1e-12) << "s=" << s << " t=" << t;
    }
  }
}

TEST(ExpPoly, FindsEveryRootOfAPolynomialTimesExponentials)
{
  // (τ−1)(τ−2)(τ−3) e^{-τ/2}: three simple roots; (τ−1)(τ−2) has two.
  const ExpPoly cubic = ExpPoly::monomial(-6.0, 0, -0.5) + ExpPoly::monomial(11.0, 1, -0.5) +
                        ExpPoly::monomial(-6.0, 2, -0.5) + ExpPoly::monomial(1.0, 3, -0.5);
  double r[EXP_POLY_MAX_ROOTS];
  ASSERT_EQ(cubic.signChangeRoots(0.0, 10.0, r), 3);
  EXPECT_NEAR(r[0], 1.0, 1e-13);
  EXPECT_NEAR(r[1], 2.0, 1e-13);
  EXPECT_NEAR(r[2], 3.0, 1e-13);
  EXPECT_EQ(cubic.signChangeRoots(1.5, 2.5, r), 1);
}

TEST(ExpPoly, GrazingDipBetweenCoarseSamplesIsFound)
{
  // g(τ) = 1 − e^{-τ} − ... a bump that dips 1e-9 below zero for a few microseconds near τ = 2:
  // g = (τ − 2)² − 1e-9·(1 + tiny), roots at 2 ± 3.16e-5. Sampling at any step > 1e-4 would miss it.
  const double depth = 1e-9;
  const ExpPoly g = ExpPoly::constant(4.0 - depth) + ExpPoly::monomial(-4.0, 1, 0.0) + ExpPoly::monomial(1.0, 2, 0.0);
  double r[EXP_POLY_MAX_ROOTS];
  ASSERT_EQ(g.signChangeRoots(0.0, 100.0, r), 2);
  // A grazing root is ill-conditioned (slope 2√depth): rounding 1e-15 in f moves it by ~1e-11.
  EXPECT_NEAR(r[0], 2.0 - std::sqrt(depth), 1e-10);
  EXPECT_NEAR(r[1], 2.0 + std::sqrt(depth), 1e-10);
  // Same with exponentials mixed in: e^{-τ}·((τ−2)² − depth) + 0·... still two roots.
  const ExpPoly h = g * ExpPoly::monomial(1.0, 0, -1.0);
  ASSERT_EQ(h.signChangeRoots(0.0, 100.0, r), 2);
  EXPECT_NEAR(r[0], 2.0 - std::sqrt(depth), 1e-10);
}

TEST(ExpPoly, SumOfExponentialsRootsAgreeWithBruteForce)
{
  // Random-ish sums of three exponential polynomials; count sign changes on a very fine grid and compare.
  unsigned seed = 12345;
  auto rnd = [&]() {
    seed = seed * 1103515245u + 12345u;
    return ((seed >> 8) & 0xFFFF) / 65535.0 * 2.0 - 1.0;
  };
  for (int trial = 0; trial < 200; ++trial)
  {
    ExpPoly f = ExpPoly::monomial(rnd(), 0, 0.0) + ExpPoly::monomial(rnd(), 1, 0.0) +
                ExpPoly::monomial(rnd() * 3.0, 0, -1.0 - rnd() * 0.5) + ExpPoly::monomial(rnd() * 3.0, 1, -2.5) +
                ExpPoly::monomial(rnd(), 2, -4.0);
    const double upper = 6.0;
    const int n = 60000;
    int brute = 0;
    double prev = f(0.0);
    for (int i = 1; i <= n; ++i)
    {
      const double v = f(upper * i / n);
      if ((v < 0.0) != (prev < 0.0) && v != 0.0 && prev != 0.0)
      {
        ++brute;
      }
      prev = v;
    }
    double r[EXP_POLY_MAX_ROOTS];
    const int exact = f.signChangeRoots(0.0, upper, r);
    EXPECT_EQ(exact, brute) << "trial " << trial;
    for (int i = 0; i < exact; ++i)
    {
      EXPECT_NEAR(f(r[i]), 0.0, 1e-12);
    }
  }
}
