// The rests of a body in a recording, shared by the rigid and the compliant estimators' static friction
// (identification.cpp, identify_mesh.cpp); private to the core.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace backlash_servo
{
/// Calls visit(a, e) for each rest a … e−1 in [begin, end): a run of at least `min_rest` samples over which `angle`
/// stays within `band` [rad] of itself and together(a, k) holds for every sample k of it (runs do not overlap; a run
/// that is too short moves the search on by one sample).
template <class Together, class Visit>
void forEachRest(const std::vector<double>& angle, double band, std::size_t begin, std::size_t end,
                 std::size_t min_rest, Together together, Visit visit)
{
  for (std::size_t a = begin; a < end;)
  {
    std::size_t e = a + 1;
    double lowest = angle[a], highest = angle[a];
    while (e < end && together(a, e) && std::max(highest, angle[e]) - std::min(lowest, angle[e]) <= band)
    {
      lowest = std::min(lowest, angle[e]);
      highest = std::max(highest, angle[e]);
      ++e;
    }
    if (e - a < min_rest)
    {
      ++a;
      continue;
    }
    visit(a, e);
    a = e;
  }
}

}  // namespace backlash_servo
