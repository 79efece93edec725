/**
 * @file maxima.h
 * @brief The benchmarks' positive load maxima and how two lists of them are compared.
 */
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace bench
{
/// A positive maximum of the load: its time [s] and position [rad].
struct Max
{
  double time, position;
};

/// The largest difference of position [rad] over the first min(|a|, |ref|) maxima (their count in *compared);
/// +inf when either list is empty.
inline double maxError(const std::vector<Max>& a, const std::vector<Max>& ref, std::size_t* compared)
{
  const std::size_t n = std::min(a.size(), ref.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < n; ++i)
  {
    worst = std::max(worst, std::fabs(a[i].position - ref[i].position));
  }
  *compared = n;
  return n == 0 ? INFINITY : worst;
}

}  // namespace bench
