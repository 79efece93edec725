#include "numerics/dft.h"

#include <cstdint>
#include <stdexcept>
#include <string>

#include "backlash_servo/model/constants.h"

namespace backlash_servo
{
namespace
{
bool isPowerOfTwo(std::size_t n)
{
  return n != 0 && (n & (n - 1)) == 0;
}
}  // namespace

Dft::Dft(std::size_t n) : n_(n), m_(1)
{
  if (n == 0)
  {
    throw std::invalid_argument("Dft: the length must be at least 1");
  }
  const bool direct = isPowerOfTwo(n);
  while (m_ < (direct ? n : 2 * n - 1))
  {
    m_ *= 2;
  }
  twiddle_.resize(m_ / 2);
  for (std::size_t k = 0; k < m_ / 2; ++k)
  {
    twiddle_[k] = std::polar(1.0, -TWO_PI * static_cast<double>(k) / static_cast<double>(m_));
  }
  if (direct)
  {
    return;
  }
  // Bluestein: jk = (j² + k² − (k − j)²)/2, so X_k = w_k Σ_j (x_j w_j) conj(w_{k−j}), w_j = e^{−iπ j²/N} — a
  // convolution, done by radix-2 transforms of length M ≥ 2N − 1. j² is reduced mod 2N in integers (exact angles).
  chirp_.resize(n);
  for (std::size_t j = 0; j < n; ++j)
  {
    const std::uint64_t square = (static_cast<std::uint64_t>(j) * j) % (2 * static_cast<std::uint64_t>(n));
    chirp_[j] = std::polar(1.0, -PI * static_cast<double>(square) / static_cast<double>(n));
  }
  chirp_dft_.assign(m_, 0.0);
  chirp_dft_[0] = std::conj(chirp_[0]);
  for (std::size_t j = 1; j < n; ++j)
  {
    chirp_dft_[j] = chirp_dft_[m_ - j] = std::conj(chirp_[j]);
  }
  powerOfTwo(&chirp_dft_, false);
}

void Dft::powerOfTwo(std::vector<std::complex<double>>* data, bool inverse) const
{
  std::vector<std::complex<double>>& a = *data;
  const std::size_t m = a.size();
  for (std::size_t i = 1, j = 0; i < m; ++i)  // bit reversal
  {
    std::size_t bit = m >> 1;
    for (; j & bit; bit >>= 1)
    {
      j ^= bit;
    }
    j ^= bit;
    if (i < j)
    {
      std::swap(a[i], a[j]);
    }
  }
  for (std::size_t len = 2; len <= m; len *= 2)
  {
    const std::size_t stride = m / len;
    for (std::size_t start = 0; start < m; start += len)
    {
      for (std::size_t k = 0; k < len / 2; ++k)
      {
        const std::complex<double> w = inverse ? std::conj(twiddle_[k * stride]) : twiddle_[k * stride];
        const std::complex<double> odd = w * a[start + k + len / 2];
        a[start + k + len / 2] = a[start + k] - odd;
        a[start + k] += odd;
      }
    }
  }
}

std::vector<std::complex<double>> Dft::transform(const std::vector<std::complex<double>>& x) const
{
  if (x.size() != n_)
  {
    throw std::invalid_argument("Dft: a sequence of " + std::to_string(x.size()) + " samples given to a transform of " +
                                std::to_string(n_));
  }
  if (chirp_.empty())
  {
    std::vector<std::complex<double>> a = x;
    powerOfTwo(&a, false);
    return a;
  }
  std::vector<std::complex<double>> a(m_, 0.0);
  for (std::size_t j = 0; j < n_; ++j)
  {
    a[j] = x[j] * chirp_[j];
  }
  powerOfTwo(&a, false);
  for (std::size_t k = 0; k < m_; ++k)
  {
    a[k] *= chirp_dft_[k];
  }
  powerOfTwo(&a, true);
  std::vector<std::complex<double>> out(n_);
  const double scale = 1.0 / static_cast<double>(m_);
  for (std::size_t k = 0; k < n_; ++k)
  {
    out[k] = a[k] * chirp_[k] * scale;
  }
  return out;
}

std::vector<std::complex<double>> Dft::realLines(const std::vector<double>& x) const
{
  std::vector<std::complex<double>> full = transform(std::vector<std::complex<double>>(x.begin(), x.end()));
  full.resize(n_ / 2 + 1);
  return full;
}

}  // namespace backlash_servo
