// What the driven elements (driven_backlash.cpp, driven_mesh.cpp) do alike: drive an element by A sin ωt period by
// period until its state at the period starts repeats, then sample the next period — or, not periodic, the next
// DRIVEN_ANALYSED — at DRIVEN_SAMPLES instants for the fundamentals. Private to the core.
#pragma once

#include <algorithm>
#include <complex>

#include "backlash_servo/model/constants.h"

namespace backlash_servo
{
/// Samples of a period for the fundamentals, and periods averaged when the motion did not repeat.
constexpr int DRIVEN_SAMPLES = 1 << 12, DRIVEN_ANALYSED = 16;

/**
 * Advances `element` (advanceTo(t) [s]) to the starts t = k·period, k = 1 … max_periods, until `repeats(t)` —
 * called at each start, comparing the state there with the one it kept from the previous start — says the motion
 * repeats.
 * Returns the periods run (≤ max_periods); *periodic tells whether it repeated.
 */
template <class Element, class Repeats>
int settlePeriods(Element& element, double period, int max_periods, Repeats&& repeats, bool* periodic)
{
  int k = 1;
  for (; k <= max_periods; ++k)
  {
    const double t = k * period;
    element.advanceTo(t);
    if (repeats(t))
    {
      *periodic = true;
      break;
    }
  }
  return std::min(k, max_periods);
}

/// How many periods the fundamentals are taken over: the settled one, or DRIVEN_ANALYSED when none repeated.
inline int analysedPeriods(bool periodic)
{
  return periodic ? 1 : DRIVEN_ANALYSED;
}

/**
 * Samples the period after `periods` settled ones (DRIVEN_ANALYSED of them when not `periodic`) at DRIVEN_SAMPLES
 * instants each: `sample(rotor)` with the element there and rotor = e^{−jωt} (ωt = 2πk + 2πi/M). Returns the periods
 * analysed; a fundamental is then (2/(M·analysed)) Σ y·rotor.
 */
template <class Element, class Sample>
int samplePeriods(Element& element, double period, int periods, bool periodic, Sample&& sample)
{
  constexpr int M = DRIVEN_SAMPLES;
  const int analysed = analysedPeriods(periodic);
  for (int p = 0; p < analysed; ++p)
  {
    for (int i = 0; i < M; ++i)
    {
      element.advanceTo((periods + p) * period + period * i / M);
      sample(std::polar(1.0, -2.0 * PI * i / M));
    }
  }
  return analysed;
}

}  // namespace backlash_servo
