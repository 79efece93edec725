#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>
#include <vector>

#include "numerics/dft.h"

namespace
{
using backlash_servo::Dft;
using Complex = std::complex<double>;

/// The DFT by its definition, summed in long double with the angle of each term reduced exactly (jk mod N).
std::vector<Complex> definition(const std::vector<Complex>& x)
{
  const std::size_t n = x.size();
  const long double two_pi = 6.283185307179586476925286766559005768L;
  std::vector<Complex> out(n);
  for (std::size_t k = 0; k < n; ++k)
  {
    long double re = 0.0L, im = 0.0L;
    for (std::size_t j = 0; j < n; ++j)
    {
      const long double angle = -two_pi * static_cast<long double>((j * k) % n) / static_cast<long double>(n);
      re += x[j].real() * std::cos(angle) - x[j].imag() * std::sin(angle);
      im += x[j].real() * std::sin(angle) + x[j].imag() * std::cos(angle);
    }
    out[k] = Complex(static_cast<double>(re), static_cast<double>(im));
  }
  return out;
}

std::vector<Complex> randomSequence(std::size_t n, unsigned seed)
{
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<Complex> x(n);
  for (Complex& v : x)
  {
    v = Complex(normal(rng), normal(rng));
  }
  return x;
}
}  // namespace

TEST(Dft, EqualsItsDefinitionForEveryKindOfLength)
{
  // Powers of two (radix 2), primes and maximum-length sequences' 2ⁿ − 1 (Bluestein), and the smallest lengths.
  for (std::size_t n :
       {1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u, 15u, 16u, 17u, 31u, 100u, 127u, 256u, 1000u, 1023u, 2048u, 2053u})
  {
    const std::vector<Complex> x = randomSequence(n, static_cast<unsigned>(n));
    const std::vector<Complex> fast = Dft(n).transform(x), exact = definition(x);
    double scale = 0.0, error = 0.0;
    for (std::size_t k = 0; k < n; ++k)
    {
      scale = std::max(scale, std::abs(exact[k]));
      error = std::max(error, std::abs(fast[k] - exact[k]));
    }
    // (ε log₂ N of the size: far below the 1e-12 allowed, far above what a wrong index or sign would leave.)
    EXPECT_LT(error, 1e-13 * scale) << "N = " << n;
  }
}

TEST(Dft, RealLinesAreTheFirstHalfOfTheTransform)
{
  // A real cosine on line 3 of 1023 samples: N/2 on lines 3 and N − 3, nothing elsewhere; the real form returns
  // lines 0 … 511.
  const std::size_t n = 1023;
  std::vector<double> x(n);
  for (std::size_t j = 0; j < n; ++j)
  {
    x[j] = std::cos(6.283185307179586 * 3.0 * static_cast<double>(j) / static_cast<double>(n));
  }
  const std::vector<Complex> lines = Dft(n).realLines(x);
  ASSERT_EQ(lines.size(), n / 2 + 1);
  for (std::size_t k = 0; k < lines.size(); ++k)
  {
    EXPECT_NEAR(std::abs(lines[k]), k == 3 ? n / 2.0 : 0.0, 1e-10) << "line " << k;
  }
}

TEST(Dft, RefusesAnEmptyTransformAndAWrongLength)
{
  EXPECT_THROW(Dft(0), std::invalid_argument);
  EXPECT_THROW(Dft(8).transform(std::vector<Complex>(7)), std::invalid_argument);
}
