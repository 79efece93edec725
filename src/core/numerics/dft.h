/**
 * @file dft.h
 * @brief The discrete Fourier transform X_k = Σ_j x_j e^{−2πi jk/N} (k = 0 … N−1) of any length N ≥ 1 in O(N log N):
 *        radix 2 when N is a power of two, Bluestein's chirp-z convolution otherwise (a maximum-length sequence's
 *        2ⁿ − 1 samples may be prime). Deterministic; the error is a few ε·log N of the sequence's size. Built once per
 *        length; transforms are const and may run on several threads at once.
 */
#pragma once

#include <complex>
#include <cstddef>
#include <vector>

namespace backlash_servo
{
class Dft
{
 public:
  explicit Dft(std::size_t n);

  std::size_t size() const { return n_; }
  /// X_0 … X_{N−1} of x (length N).
  std::vector<std::complex<double>> transform(const std::vector<std::complex<double>>& x) const;
  /// X_0 … X_{N/2} of a real x (length N): the lines a real sequence has (the rest are their conjugates).
  std::vector<std::complex<double>> realLines(const std::vector<double>& x) const;

 private:
  /// In place, a.size() == m_ (a power of two); inverse: e^{+2πi jk/M}, unscaled.
  void powerOfTwo(std::vector<std::complex<double>>* a, bool inverse) const;

  std::size_t n_;
  std::size_t m_;                                ///< the radix-2 length: N, or ≥ 2N − 1 for Bluestein
  std::vector<std::complex<double>> twiddle_;    ///< e^{−2πi k/M}, k < M/2
  std::vector<std::complex<double>> chirp_;      ///< e^{−iπ j²/N}, j < N (Bluestein only)
  std::vector<std::complex<double>> chirp_dft_;  ///< the radix-2 DFT of the conjugate chirp, wrapped (Bluestein)
};

}  // namespace backlash_servo
