#include "backlash_servo/simulation/limit_cycle.h"

#include <algorithm>
#include <cmath>

namespace backlash_servo
{
const char* toString(Verdict v)
{
  switch (v)
  {
    case Verdict::LimitCycle:
      return "limit_cycle";
    case Verdict::Converged:
      return "converged";
    case Verdict::Irregular:
      return "irregular_oscillation";
    case Verdict::Diverged:
      return "diverged";
    default:
      return "undecided";
  }
}

LimitCycleDetector::LimitCycleDetector(double command, double scale, double centre)
    : command_(command), centre_(std::isnan(centre) ? command : centre), scale_(scale)
{}

bool LimitCycleDetector::oscillating() const
{
  return status_.verdict == Verdict::LimitCycle || status_.verdict == Verdict::Irregular;
}

namespace
{
/// Appends m to list unless it is the same hump as the last (closer than min_spacing [s]: the higher is kept).
bool record(std::vector<Maximum>& list, const Maximum& m, double min_spacing)
{
  if (!list.empty() && m.time - list.back().time < min_spacing)
  {
    if (m.position > list.back().position)
    {
      list.back() = m;  // the same hump: keep its top (the verdict is not re-judged on it)
    }
    return false;
  }
  list.push_back(m);
  return true;
}
}  // namespace

void LimitCycleDetector::addMaximum(const Maximum& m)
{
  if (centre_ != command_ && m.position - command_ > ZERO_FRACTION * scale_)
  {
    record(reported_, m, min_spacing_);
  }
  if (m.position - centre_ > ZERO_FRACTION * scale_ && record(maxima_, m, min_spacing_))
  {
    update();
  }
}

void LimitCycleDetector::markStuck()
{
  if (status_.verdict != Verdict::Converged)
  {
    status_ = LimitCycleReport();
    status_.verdict = Verdict::Converged;
  }
}

void LimitCycleDetector::markAtRest()
{
  if (status_.verdict == Verdict::Undecided)
  {
    status_ = LimitCycleReport();
    status_.verdict = Verdict::Converged;
  }
}

namespace
{
/// Aitken Δ² estimate of the limit of s0, s1, s2 (s0 newest).
double aitken(double s0, double s1, double s2)
{
  const double d1 = s0 - s1;
  const double d2 = s1 - s2;
  return d1 == d2 ? s0 : s0 - d1 * d1 / (d1 - d2);
}
}  // namespace

double LimitCycleDetector::deviation(int i) const
{
  return maxima_[i].position - centre_;
}

bool LimitCycleDetector::pinnedCycle(int n, double offset)
{
  auto x = [&](int i) { return deviation(i); };
  // A limit cycle of multiplicity k: in every phase of the k-periodic sequence the Aitken estimates of the fixed
  // point from three successive windows agree to FIXED_POINT_TOLERANCE, and the maxima are close to it (so the
  // map is in its linear regime, where Aitken's extrapolation is exact to second order).
  // Phase k − 1 looks back 4k maxima from maxima_[n − k]: n ≥ 5k keeps every look-back inside the maxima.
  for (int k = 1; k <= MAX_MULTIPLICITY && n >= 5 * k; ++k)
  {
    bool pinned = true;
    double error = 0.0;
    for (int phase = 0; phase < k && pinned; ++phase)
    {
      const int i = n - 1 - phase;
      const double s0 = x(i), s1 = x(i - k), s2 = x(i - 2 * k), s3 = x(i - 3 * k), s4 = x(i - 4 * k);
      const double fixed = aitken(s0, s1, s2);
      const double tol = FIXED_POINT_TOLERANCE * fixed;
      pinned = fixed > 10.0 * ZERO_FRACTION * scale_ && std::fabs(fixed - aitken(s1, s2, s3)) <= tol &&
               std::fabs(fixed - aitken(s2, s3, s4)) <= tol && std::fabs(s0 - s1) <= 1e-3 * fixed;
      error = std::max(error, fixed);
    }
    // The period converges like the maxima do: extrapolate the last three same-phase intervals the same way. A
    // cycle has a period near its latest interval; intervals shrinking towards 0 are maxima accumulating at an
    // instant (a load settling by a Zeno series of bounces), not a cycle.
    auto interval = [&](int j) { return maxima_[n - 1 - j * k].time - maxima_[n - 1 - (j + 1) * k].time; };
    const double period = pinned ? aitken(interval(0), interval(1), interval(2)) : 0.0;
    if (pinned && period > 0.5 * interval(0))
    {
      status_.verdict = Verdict::LimitCycle;
      status_.error = error + offset;
      status_.period = period;
      status_.multiplicity = k;
      return true;
    }
  }
  return false;
}

bool LimitCycleDetector::geometricDecay(int n)
{
  auto x = [&](int i) { return deviation(i); };
  // Convergence: steady geometric decay whose extrapolated limit is (near) zero, twice in a row. This extrapolates
  // the Poincaré map of a loop that is linear in each mode, where a geometric decay goes on to the equilibrium. Under
  // dry friction it is not (extrapolate_decay_ off): a decay can stall into stick–slip hunting, so there convergence
  // needs the state itself (at rest, stuck for ever, or quiet), and the run goes on until it shows.
  if (n >= 4 && extrapolate_decay_)
  {
    const double s0 = x(n - 1), s1 = x(n - 2), s2 = x(n - 3), s3 = x(n - 4);
    const double r1 = (s0 - s1) / (s1 - s2);
    const double r2 = (s1 - s2) / (s2 - s3);
    const bool decaying = s0 < s1 && s1 < s2 && s2 < s3 && r1 > 0.0 && r1 < 1.0 && r2 > 0.0 && r2 < 1.0 &&
                          std::fabs(r1 - r2) <= 0.1 * r1 && aitken(s0, s1, s2) <= 1e-3 * s0;
    decay_votes_ = decaying ? decay_votes_ + 1 : 0;
    if (decay_votes_ >= 2)
    {
      status_ = LimitCycleReport();
      status_.verdict = Verdict::Converged;
      return true;
    }
  }
  return false;
}

bool LimitCycleDetector::quasiPeriodic(int n, double offset)
{
  auto x = [&](int i) { return deviation(i); };
  // Quasi-periodic: the maxima wander inside a narrow band that no longer shrinks (sampled, quantised or stick–slip
  // loops whose period is not a whole number of samples). A pattern of k maxima per period (k bands: stick–slip
  // hunting that slips in several steps) is k such bands, one per phase, each read from every k-th maximum; the
  // period is then that of the whole pattern (the time between same-phase maxima).
  const int b = BAND_WINDOW;
  for (int k = 1; bands_ && k <= MAX_MULTIPLICITY && n >= 2 * b * k; ++k)
  {
    // Window of b same-phase maxima: the j-th is maxima_[last − (b − 1 − j)·k], oldest first.
    auto window = [&](int last, double* lo, double* hi, double* mean, int* turns) {
      auto at = [&](int j) { return x(last - (b - 1 - j) * k); };
      *lo = at(0);
      *hi = at(0);
      *mean = 0.0;
      *turns = 0;
      for (int j = 0; j < b; ++j)
      {
        *lo = std::min(*lo, at(j));
        *hi = std::max(*hi, at(j));
        *mean += at(j) / b;
        if (j >= 2 && (at(j) - at(j - 1)) * (at(j - 1) - at(j - 2)) < 0.0)
        {
          ++*turns;
        }
      }
    };
    bool all = true;
    double top = 0.0, top_low = 0.0;
    for (int phase = 0; phase < k && all; ++phase)
    {
      const int last = n - 1 - phase;
      double lo_a, hi_a, mean_a, lo_b, hi_b, mean_b;
      int turns_a, turns_b;
      window(last - b * k, &lo_a, &hi_a, &mean_a, &turns_a);
      window(last, &lo_b, &hi_b, &mean_b, &turns_b);
      const bool narrow = mean_b > 10.0 * ZERO_FRACTION * scale_ && hi_a - lo_a <= BAND_FRACTION * mean_a &&
                          hi_b - lo_b <= BAND_FRACTION * mean_b;
      const bool settled_band = hi_b - lo_b >= 0.5 * (hi_a - lo_a) && std::fabs(mean_b - mean_a) <= hi_a - lo_a &&
                                turns_b >= 2 && turns_a >= 2;
      all = narrow && settled_band;
      if (phase == 0 || hi_b > top)
      {
        top = hi_b;
        top_low = lo_b;
      }
    }
    if (all)
    {
      status_.verdict = Verdict::LimitCycle;
      status_.quasi_periodic = true;
      status_.error = top + offset;
      status_.band_low = top_low + offset;
      status_.band_high = top + offset;
      status_.period = (maxima_[n - 1].time - maxima_[n - 1 - (b - 1) * k].time) / (b - 1);
      status_.multiplicity = k;
      return true;
    }
  }
  return false;
}

void LimitCycleDetector::irregular(int n, double offset)
{
  auto x = [&](int i) { return deviation(i); };
  // Irregular: the latest window of maxima neither settled nor decays relative to the window before it.
  const int w = IRREGULAR_WINDOW;
  if (n >= 2 * w)
  {
    double mean_a = 0.0, mean_b = 0.0, min_b = x(n - 1), max_b = 0.0;
    int turns = 0;  // sign changes of successive differences: a monotone (slow) approach has none
    for (int i = 0; i < w; ++i)
    {
      mean_a += x(n - 2 * w + i) / w;
      mean_b += x(n - w + i) / w;
      min_b = std::min(min_b, x(n - w + i));
      max_b = std::max(max_b, x(n - w + i));
      if (i >= 2 && (x(n - w + i) - x(n - w + i - 1)) * (x(n - w + i - 1) - x(n - w + i - 2)) < 0.0)
      {
        ++turns;
      }
    }
    if (mean_b >= 0.99 * mean_a && min_b >= 0.5 * mean_a && turns >= w / 4)
    {
      status_.verdict = Verdict::Irregular;
      status_.error = max_b + offset;
      status_.period = (maxima_[n - 1].time - maxima_[n - w].time) / (w - 1);
      status_.multiplicity = 0;
    }
  }
}

void LimitCycleDetector::update()
{
  const int n = static_cast<int>(maxima_.size());
  const double offset = centre_ - command_;  // reported errors are from θ_R
  if (n >= 3)
  {
    status_.extrapolated = aitken(deviation(n - 1), deviation(n - 2), deviation(n - 3)) + offset;
  }
  if (status_.verdict != Verdict::Undecided)
  {
    return;
  }
  if (pinnedCycle(n, offset) || geometricDecay(n) || quasiPeriodic(n, offset))
  {
    return;
  }
  irregular(n, offset);
}

}  // namespace backlash_servo
