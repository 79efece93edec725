#include "backlash_servo/identification/identification.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <numeric>
#include <tuple>
#include <variant>

#include "backlash_servo/identification/measured_angles.h"
#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/model/params.h"
#include "identification/least_squares.h"
#include "identification/phase_regression.h"
#include "identification/rest_runs.h"

namespace backlash_servo
{
namespace
{
/// Samples on each side of a sample whose gap must stay in its phase (the difference stencil, and one more).
constexpr int STENCIL = 2;
/// The shortest sample period a recording may have [s] (below it the differences' h² underflows the angles).
constexpr double MIN_SAMPLE_PERIOD = 1e-9;
/// Measured angles: an inertia or a Coulomb level with a standard error above this fraction of itself is not
/// identified (at two standard errors an inertia within 5 %, a Coulomb level within 10 %).
constexpr double LOOSEST_INERTIA = 0.025;
/// Measured angles: the backlash with a standard error above this fraction of itself is not identified.
constexpr double LOOSEST_BACKLASH = 0.05;
/// Measured angles: the fewest samples of the teeth driving on a flank for it to count as reached.
constexpr std::size_t FEWEST_DRIVEN = 100;
/// Measured angles: the fewest pieces of a phase whose cluster-robust standard errors are trusted.
constexpr std::size_t FEWEST_PIECES = 20;
constexpr double LOOSEST_LEVEL = 0.05;
/// How far a step may differ from the typical one, relative to it: the torque is taken as held over each step.
constexpr double UNIFORM_STEP = 1e-3;

/// The median of the samples (the upper middle one of an even count).
double median(std::vector<double> v)
{
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// The standard deviation [rad/s] of the noise in a body's velocity (central difference of the filtered angle at
/// period h [s]) from the angle's noise σ [rad] (measured_angles.h).
double velocityNoise(double noise, const IdentificationSettings& s, double h)
{
  // The filter's kernel (a unit impulse filtered), differenced: its norm carries white noise through.
  const std::size_t r = static_cast<std::size_t>(std::max(s.smoothing, 0)), width = 4 * r + 3;
  std::vector<double> impulse(2 * width + 1, 0.0);
  impulse[width] = 1.0;
  const std::vector<double> kernel = smoothedSignal(impulse, s.smoothing);
  double norm = 0.0;
  for (std::size_t k = 1; k + 1 < kernel.size(); ++k)
  {
    const double d = 0.5 * (kernel[k + 1] - kernel[k - 1]);
    norm += d * d;
  }
  return noise * std::sqrt(norm) / h;
}

/**
 * Measured angles: the bodies' parameters from the equations integrated twice over stretches of one phase
 * (phase_regression.h) — stretches of samples in one phase with the motor moving, less `trim` samples at each end
 * (where the filtered gap's phase is blurred), cut into pieces of 0.2 s. A phase without enough rows leaves its
 * parameters not identifiable (the reason in out->not_identifiable); both without: nothing to estimate (thrown).
 */
/// The stretches of one phase and one direction of motion, `trim` samples cut at each end (the filter's reach);
/// true when the contact moved both ways.
bool phaseStretches(const std::vector<int>& phase, const std::vector<std::size_t>& stills,
                    const std::vector<double>& sign, std::size_t trim, Stretches* apart_out, Stretches* contact_out)
{
  const std::size_t n = phase.size();
  Stretches &apart = *apart_out, &contact = *contact_out;
  bool forward = false, backward = false;  // contact motion each way
  std::size_t k = 0;
  while (k < n)
  {
    const auto usable = [&](std::size_t i) { return phase[i] != 2 && stills[i + 1] == stills[i]; };
    if (!usable(k))
    {
      ++k;
      continue;
    }
    std::size_t end = k;
    while (end < n && usable(end) && phase[end] == phase[k] && sign[end] == sign[k])
    {
      ++end;
    }
    if (end - k > 2 * trim)
    {
      (phase[k] == 0 ? apart : contact).emplace_back(k + trim, end - trim);
      if (phase[k] != 0)
      {
        (sign[k] > 0.0 ? forward : backward) = true;
      }
    }
    k = end;
  }
  return forward && backward;
}

/// What the pair's sums are, for the reason of a split not made: J_m + ρ²J_L, f_m + ρ²f_L, T_cm + ρT_cL with their
/// standard errors (with both phases the pair's sums from the split, the parts' errors combined as if independent;
/// without stretches apart the motor's columns carry them).
std::string pairSums(const BodiesFit& f, double rho, bool load_torque_given, double known_load)
{
  // (with both phases the pair's sums from the split; without stretches apart the motor's columns carry them)
  const bool both = f.apart_rows > 0;
  // (each with its standard error; with both phases the two parts' errors combined as if independent)
  const auto sum = [&](int j, double factor, const char* unit) {
    const double value = f.p(j) + (both ? factor * f.p(j + 3) : 0.0);
    const double error = both ? std::hypot(f.se(j), factor * f.se(j + 3)) : f.se(j);
    return formatNumber(value) + " ± " + formatNumber(error) + unit;
  };
  return f.contact_rows > 0
             ? "; the pair gives J_m + ρ²J_L = " + sum(0, rho * rho, " kg·m²") +
                   ", f_m + ρ²f_L = " + sum(1, rho * rho, " N·m·s/rad") + ", T_cm + ρT_cL = " + sum(2, rho, " N·m") +
                   (load_torque_given
                        ? " (the contact went one way: the load torque taken as " + formatNumber(known_load) + " N·m)"
                        : "")
             : "";
}

/// How well parameter j of the fit (fitBodies' order) is known: an inertia to LOOSEST_INERTIA, a friction level to
/// LOOSEST_LEVEL of itself, not held at 0 by the constraint; else the reason, in words ("" when it is).
std::string looseness(const BodiesFit& f, int j)
{
  const double value = f.p(j), error = f.se(j);
  const bool inertia = j % 3 == 0;
  const char* unit = inertia ? " kg·m²" : j % 3 == 1 ? " N·m·s/rad" : " N·m";
  if (f.at_bound[static_cast<std::size_t>(j)])
  {
    return "the fit holds it at 0 (it came out below): the recording does not tell it from zero";
  }
  const double loosest = inertia ? LOOSEST_INERTIA : LOOSEST_LEVEL;
  if (!(error <= loosest * value))
  {
    return "the recording gives " + formatNumber(value) + " ± " + formatNumber(error) + unit + ", not within ±" +
           formatNumber(100.0 * loosest) + " %";
  }
  return "";
}

/**
 * A stated motor inertia checks the stretches read apart: fitted freely, they must give it back (within four standard
 * errors or 5 %), else they do not move the motor alone (samples in contact among them) and the frictions are not
 * split. Returns the reason, or "" when they agree.
 */
std::string disagreesWithKnownInertia(const BodiesFit& free_fit, double known)
{
  const double j = free_fit.p(0), se = free_fit.se(0);
  if (!std::isfinite(j) || std::fabs(j - known) <= std::max(4.0 * se, 0.05 * known))
  {
    return "";
  }
  return "the stretches read apart do not move the motor as its stated inertia (" + formatNumber(known) +
         " kg·m²) says — fitted freely they give " + formatNumber(j) + " ± " + formatNumber(se) +
         " kg·m², so samples in contact are among them";
}

/**
 * Why the motor alone does not split the pair's sums ("" when it does): no stretch apart or in contact, too few
 * stretches apart, its inertia not resolved — or, with a known motor inertia `known` [kg·m²] (NaN: none), the
 * stretches apart disagreeing with it (`free_fit`: the fit with J_m free).
 */
std::string whyNotSplit(const BodiesFit& f, double known, const std::function<BodiesFit()>& free_fit)
{
  if (f.apart_rows == 0 || f.contact_rows == 0)
  {
    return f.apart_rows == 0 ? "the teeth were never seen apart with the motor moving"
                             : "the teeth were never seen in contact with the joint moving";
  }
  if (f.apart_pieces < FEWEST_PIECES)
  {
    return "the motor alone is seen in " + std::to_string(f.apart_pieces) + " stretches apart only (at least " +
           std::to_string(FEWEST_PIECES) + " make its standard errors trustworthy)";
  }
  if (std::isfinite(known))
  {
    return disagreesWithKnownInertia(free_fit(), known);
  }
  const std::string why = looseness(f, 0);
  return why.empty() ? "" : "the motor alone is not resolved (its inertia: " + why + ")";
}

void bodiesFromIntegrals(const Recording& d, const IdentificationSettings& s, const std::vector<int>& phase,
                         const std::vector<double>& velocity, const std::vector<std::size_t>& stills, std::size_t trim,
                         const AngleMeasurement& motor, InitialEstimates* out)
{
  const std::size_t n = d.time.size();
  const double h = (d.time.back() - d.time.front()) / static_cast<double>(n - 1), rho = s.gear_ratio;
  std::vector<double> sign(n);
  std::transform(velocity.begin(), velocity.end(), sign.begin(), [](double w) {
    return w > 0.0 ? 1.0 : w < 0.0 ? -1.0 : 0.0;
  });
  Stretches apart, contact;
  const bool both_ways = phaseStretches(phase, stills, sign, trim, &apart, &contact);
  const std::size_t piece = std::max<std::size_t>(10, static_cast<std::size_t>(0.2 / h));
  const PhaseRows a = integratedRows(d, sign, apart, piece, 0);
  const PhaseRows c = integratedRows(d, sign, contact, piece, a.cluster.empty() ? 0 : a.cluster.back() + 1);
  // Contact one way only: the load torque is not told from the Coulomb friction; the settings' (or 0) holds it.
  const double known_load = both_ways ? NAN : std::isfinite(s.load_torque_fallback) ? s.load_torque_fallback : 0.0;
  const BodiesFit f = fitBodies(a, c, rho, known_load, {s.known_motor_inertia, s.known_load_inertia}, motor.noise,
                                motor.resolution == 0.0);
  out->apart_samples = f.apart_rows;
  out->contact_samples = f.contact_rows;
  out->apart_rms_residual = f.apart_rms;
  out->contact_rms_residual = f.contact_rms;
  if (f.apart_rows == 0 && f.contact_rows == 0)
  {
    for (const char* key : {"motor_inertia", "motor_friction", "motor_coulomb_friction", "load_inertia",
                            "load_friction", "load_coulomb_friction", "load_torque"})
    {
      out->not_identifiable[key] =
          "no stretch of steady motion in one phase: the bodies need motion with the teeth in contact and the motor "
          "crossing the free play (backlash_identify --experiment designs such an excitation)";
    }
    return;
  }
  const char* const keys[7] = {"motor_inertia", "motor_friction", "motor_coulomb_friction",
                               "load_inertia",  "load_friction",  "load_coulomb_friction",
                               "load_torque"};
  Estimate* fields[7] = {&out->motor_inertia, &out->motor_friction, &out->motor_coulomb_friction,
                         &out->load_inertia,  &out->load_friction,  &out->load_coulomb_friction,
                         &out->load_torque};
  for (int j = 0; j < 7; ++j)
  {
    *fields[j] = {f.p(j), f.se(j)};
  }
  out->load_torque_given = f.contact_rows > 0 && !both_ways;
  if (f.swamped)
  {
    for (int j = 0; j < 7; ++j)
    {
      out->not_identifiable[keys[j]] =
          "the angles' noise swamps the motion within the stretches of one phase (corrected for it, the equations "
          "determine nothing): finer or less noisy encoders, or larger motions, are needed";
      *fields[j] = {NAN, NAN};
    }
    return;
  }
  const std::string unsplit = whyNotSplit(f, s.known_motor_inertia, [&] {
    return fitBodies(a, c, rho, known_load, {NAN, s.known_load_inertia}, motor.noise, motor.resolution == 0.0);
  });
  // (a known inertia splits the pair's: then only the frictions wait for the motor alone)
  const bool known_inertia[6] = {std::isfinite(s.known_motor_inertia), false, false,
                                 std::isfinite(s.known_load_inertia),  false, false};
  const bool inertia_split = known_inertia[0] || known_inertia[3];
  if (!unsplit.empty())
  {
    const std::string sums = pairSums(f, rho, out->load_torque_given, known_load);
    for (int j = f.apart_rows > 0 && f.contact_rows == 0 ? 3 : 0; j < 6; ++j)
    {
      if (inertia_split && j % 3 == 0)
      {
        continue;
      }
      out->not_identifiable[keys[j]] = unsplit + (j >= 3 || f.contact_rows == 0 ? sums : "");
      *fields[j] = {NAN, NAN};
    }
  }
  for (int j = 0; j < 6; ++j)
  {
    if (known_inertia[j])
    {
      continue;  // (stated in the prior: held, not estimated)
    }
    if (out->not_identifiable.count(keys[j]) == 0)
    {
      if (const std::string why = looseness(f, j); !why.empty())
      {
        // (a loose value stays in the estimates, for the replays; it is reported as not identified)
        out->not_identifiable[keys[j]] = why;
      }
    }
  }
  if (out->load_torque_given)
  {
    out->load_torque = {known_load, NAN};
  }
}

/// The half-sample mode (Bickel and Frühwirth): the sorted samples' half of least range, halved again until two or
/// three remain, whose mean it is — where the samples crowd, unmoved by a one-sided tail.
double halfSampleMode(std::vector<double> v)
{
  std::sort(v.begin(), v.end());
  std::size_t a = 0, b = v.size();
  while (b - a > 3)
  {
    const std::size_t half = (b - a + 1) / 2;
    std::size_t best = a;
    for (std::size_t i = a; i + half <= b; ++i)
    {
      if (v[i + half - 1] - v[i] < v[best + half - 1] - v[best])
      {
        best = i;
      }
    }
    a = best;
    b = best + half;
  }
  double sum = 0.0;
  for (std::size_t i = a; i < b; ++i)
  {
    sum += v[i];
  }
  return sum / static_cast<double>(b - a);
}

/// How the samples on a flank spread: σ by their median absolute deviation, and how far their median leans from their
/// mode (the samples of short flights and rebounds beside a flank pull the one, not the other) [rad].
struct FlankSpread
{
  double sigma = 0.0, lean = 0.0;
};

FlankSpread flankSpread(const std::vector<double>& flank)
{
  const double centre = median(flank);
  std::vector<double> deviation(flank.size());
  std::transform(flank.begin(), flank.end(), deviation.begin(), [centre](double g) { return std::fabs(g - centre); });
  return {1.4826 * median(deviation), centre - halfSampleMode(flank)};
}

/// The samples in runs on a flank (phase ±1, one flank per run) longer than 2·trim + 6 (what a stretch keeps of
/// them): the teeth held on that flank, not the gap turning there in flight.
std::vector<bool> drivenMask(const std::vector<int>& phase, std::size_t trim)
{
  std::vector<bool> driven(phase.size(), false);
  std::size_t first = 0;
  for (std::size_t k = 0; k <= phase.size(); ++k)
  {
    const bool on = k < phase.size() && (phase[k] == 1 || phase[k] == -1);
    if (on && k > first && phase[k] == phase[first])
    {
      continue;
    }
    if (k > first && (phase[first] == 1 || phase[first] == -1) && k - first > 2 * trim + 6)
    {
      std::fill(driven.begin() + static_cast<long>(first), driven.begin() + static_cast<long>(k), true);
    }
    first = k;
  }
  return driven;
}

/// The phases read at the load's count edges (edgePhases).
struct EdgePhases
{
  bool resolved = false;                 ///< the edges' gaps fall in two clusters a backlash apart
  double forward = 0.0, backward = 0.0;  ///< the clusters [rad]
  Estimate backlash;                     ///< [rad]
  std::vector<int> phase;                ///< +1 / −1 on a flank between two edges there, else 2 (unknown)
};

/**
 * A load angle on a coarse count grid and a fine motor angle: at each change of the load's count (an edge, between
 * samples k − 1 and k) the load is on the boundary between the two counts, so the gap there is the boundary less ρ
 * times the motor's angle at the interval's middle — known to the motor's resolution and its motion over half a
 * sample, however coarse the load's counts (the encoder's rounding convention shifts every edge alike). In contact
 * these gaps crowd at the two flanks; the backlash is the distance between their modes. Between two consecutive edges
 * on one flank, the motor moving one way all along, the teeth are taken to be in contact there. (Flights are not
 * resolved this way: no sample is apart.)
 */
EdgePhases edgePhases(const Recording& d, const IdentificationSettings& s, const std::vector<double>& velocity,
                      double still, const AngleMeasurement& motor, const AngleMeasurement& load)
{
  EdgePhases out;
  const std::size_t n = d.time.size();
  if (!(load.resolution > 0.0))
  {
    return out;  // (noisy load angles have no clean edges)
  }
  const double q = 6.283185307179586 / load.resolution, rho = s.gear_ratio;
  std::vector<std::size_t> at;
  std::vector<double> gaps, motion;
  for (std::size_t k = 1; k < n; ++k)
  {
    const double step = d.load_position[k] - d.load_position[k - 1];
    if (step != 0.0 && std::fabs(step) < 1.5 * q)
    {
      at.push_back(k);
      gaps.push_back(0.5 * (d.load_position[k] + d.load_position[k - 1]) -
                     0.5 * rho * (d.motor_position[k] + d.motor_position[k - 1]));
      motion.push_back(0.5 * rho * std::fabs(d.motor_position[k] - d.motor_position[k - 1]));
    }
  }
  if (gaps.size() < 40)
  {
    return out;
  }
  // The band: two standard deviations of an edge's gap — the crossing's instant uniform in its interval, so the
  // motor's typical motion over half a sample m gives σ = m/√3 — and a count of the motor referred to the load. The
  // flanks are resolved three bands apart (each cluster spans ±m, 0.87 of a band).
  const double band = 2.0 * median(motion) / std::sqrt(3.0) + rho * std::sqrt(12.0) * motor.noise;
  const Flanks flanks = locateFlanks(gaps, 0, band);
  if (!(flanks.backward - flanks.forward > 3.0 * band))
  {
    return out;
  }
  std::vector<double> on_forward, on_backward;
  std::vector<int> side(gaps.size(), 2);
  for (std::size_t i = 0; i < gaps.size(); ++i)
  {
    side[i] = std::fabs(gaps[i] - flanks.forward) <= band ? 1 : std::fabs(gaps[i] - flanks.backward) <= band ? -1 : 2;
    (side[i] == 1 ? on_forward : on_backward).push_back(gaps[i]);
    if (side[i] == 2)
    {
      on_backward.pop_back();
    }
  }
  if (on_forward.size() < 20 || on_backward.size() < 20)
  {
    return out;
  }
  out.resolved = true;
  out.forward = halfSampleMode(on_forward);
  out.backward = halfSampleMode(on_backward);
  // The error: each mode's scatter over its edges (the crossing's instant is uniform in its interval: no bias), how
  // far its median leans from it (teeth that chatter on a flank skew its edges into the play).
  double variance = 0.0;
  for (const std::vector<double>* flank : {&on_forward, &on_backward})
  {
    const FlankSpread spread = flankSpread(*flank);
    variance += 1.5708 * spread.sigma * spread.sigma / static_cast<double>(flank->size()) + spread.lean * spread.lean;
  }
  // (and how far each mode lies from where the extreme crowd of edges was found)
  variance += (out.forward - flanks.forward) * (out.forward - flanks.forward) +
              (out.backward - flanks.backward) * (out.backward - flanks.backward);
  out.backlash = {out.backward - out.forward, std::sqrt(variance)};
  out.phase.assign(n, 2);
  for (std::size_t i = 0; i + 1 < at.size(); ++i)
  {
    if (side[i] == 2 || side[i] != side[i + 1])
    {
      continue;
    }
    bool one_way = true;
    for (std::size_t k = at[i]; k < at[i + 1] && one_way; ++k)
    {
      one_way = std::fabs(velocity[k]) > still && (velocity[k] > 0.0) == (velocity[at[i]] > 0.0);
    }
    if (one_way)
    {
      std::fill(out.phase.begin() + static_cast<long>(at[i]), out.phase.begin() + static_cast<long>(at[i + 1]),
                side[i]);
    }
  }
  return out;
}

/// The centred mean over 2r + 1 samples (the samples within r of an end keep their value: they are never used).
std::vector<double> centredMean(const std::vector<double>& x, std::size_t r)
{
  if (r == 0)
  {
    return x;
  }
  std::vector<double> sum(x.size() + 1, 0.0), out = x;
  for (std::size_t i = 0; i < x.size(); ++i)
  {
    sum[i + 1] = sum[i] + x[i];
  }
  for (std::size_t k = r; k + r < x.size(); ++k)
  {
    out[k] = (sum[k + r + 1] - sum[k - r]) / static_cast<double>(2 * r + 1);
  }
  return out;
}

}  // namespace

Flanks locateFlanks(const std::vector<double>& gap, std::size_t edge, double band)
{
  if (!(band > 0.0))
  {
    const auto [lo, hi] = std::minmax_element(gap.begin(), gap.end());
    return {*lo, *hi};
  }
  const std::size_t skip = std::min(edge, gap.size() / 4);
  std::vector<double> sorted(gap.begin() + static_cast<long>(skip), gap.end() - static_cast<long>(skip));
  std::sort(sorted.begin(), sorted.end());
  const std::size_t enough = std::max<std::size_t>(20, sorted.size() / 1000);
  const auto median = [&sorted](std::size_t a, std::size_t b) { return sorted[a + (b - a) / 2]; };
  Flanks out{sorted.front(), sorted.back()};
  for (std::size_t i = 0; i < sorted.size(); ++i)
  {
    const std::size_t j = static_cast<std::size_t>(
        std::upper_bound(sorted.begin() + static_cast<long>(i), sorted.end(), sorted[i] + 2.0 * band) - sorted.begin());
    if (j - i >= enough)
    {
      out.forward = median(i, j);
      break;
    }
  }
  for (std::size_t i = sorted.size(); i-- > 0;)
  {
    const std::size_t j = static_cast<std::size_t>(
        std::lower_bound(sorted.begin(), sorted.begin() + static_cast<long>(i) + 1, sorted[i] - 2.0 * band) -
        sorted.begin());
    if (i + 1 - j >= enough)
    {
      out.backward = median(j, i + 1);
      break;
    }
  }
  return out;
}

double replayGain(const ServoParams& p)
{
  const double j = p.totalInertia();
  const double omega =
      std::clamp(std::max(1.0, 2.0 * p.totalFriction() / j), 10.0 * NATURAL_FREQUENCY_MIN, 0.1 * NATURAL_FREQUENCY_MAX);
  return omega * omega * j / p.gear_ratio;
}

std::size_t minimumRest(const IdentificationSettings& s, double h)
{
  constexpr std::size_t MIN_REST = 10;
  constexpr double MEASURED_REST = 0.2;  // [s]
  const std::size_t r = static_cast<std::size_t>(std::max(s.smoothing, 0));
  return std::max({MIN_REST, 4 * r + 5, s.contact_band > 0.0 ? static_cast<std::size_t>(MEASURED_REST / h) : 0});
}

std::vector<double> smoothedSignal(const std::vector<double>& x, int r)
{
  const std::size_t w = static_cast<std::size_t>(std::max(r, 0));
  return centredMean(centredMean(x, w), w);
}

double samplePeriod(const Recording& d, const IdentificationSettings& s)
{
  const std::size_t n = d.time.size();
  requireThat(n >= 50, "data", "needs at least 50 samples (got " + std::to_string(n) + ")");
  requireThat(d.motor_torque.size() == n && d.motor_position.size() == n && d.load_position.size() == n, "data",
              "the columns time, motor_torque, motor_position and load_position must have equal lengths");
  requireThat(std::isfinite(s.gear_ratio) && s.gear_ratio > 0.0, "gear_ratio",
              "must be known and > 0 (give it in the prior)");
  const double h = (d.time.back() - d.time.front()) / static_cast<double>(n - 1);
  requireThat(h > 0.0 && std::isfinite(h), "time", "must increase");
  requireThat(h >= MIN_SAMPLE_PERIOD, "time",
              "the samples are " + formatNumber(h) + " s apart, below 1 ns: is the time column in seconds?");
  for (std::size_t k = 0; k < n; ++k)
  {
    requireThat(std::isfinite(d.time[k]) && std::isfinite(d.motor_torque[k]) && std::isfinite(d.motor_position[k]) &&
                    std::isfinite(d.load_position[k]),
                "data", "row " + std::to_string(k + 1) + " has a value that is not a finite number");
  }
  // Uniform in time: every step within UNIFORM_STEP of the typical (median) one — a clock's jitter and the rounding of
  // Unix-epoch stamps (2.4e-7 s at 1.7e9 s) pass, a sample lost or doubled does not, and is named by its row.
  std::vector<double> steps(n - 1);
  for (std::size_t k = 1; k < n; ++k)
  {
    steps[k - 1] = d.time[k] - d.time[k - 1];
  }
  const double typical = median(steps);
  const auto shown = [](double x, int digits) {
    char text[40];
    std::snprintf(text, sizeof text, "%.*g", digits, x);
    return std::string(text);
  };
  for (std::size_t k = 1; k < n; ++k)
  {
    requireThat(std::fabs(steps[k - 1] - typical) <= UNIFORM_STEP * typical, "time",
                "samples must be uniform in time: row " + std::to_string(k + 1) + " (t = " + shown(d.time[k], 15) +
                    " s) is " + shown(steps[k - 1], 3) + " s after the one before, the typical step is " +
                    shown(typical, 3) + " s (a sample lost or doubled?)");
  }
  requireThat(s.smoothing >= 0 && s.smoothing <= 100000, "smoothing", "must be in [0, 100000] samples");
  requireThat(n > 8 * static_cast<std::size_t>(s.smoothing) + 50, "smoothing",
              "is too wide for a recording of " + std::to_string(n) + " samples");
  return h;
}

BodyMotion differentiate(const std::vector<double>& angle, double h, int smoothing)
{
  const std::size_t n = angle.size();
  BodyMotion b;
  b.angle = smoothedSignal(angle, smoothing);
  b.velocity.assign(n, 0.0);
  b.acceleration.assign(n, 0.0);
  b.sign.assign(n, 0.0);
  for (std::size_t k = 1; k + 1 < n; ++k)
  {
    b.velocity[k] = (b.angle[k + 1] - b.angle[k - 1]) / (2.0 * h);
    b.acceleration[k] = (b.angle[k + 1] - 2.0 * b.angle[k] + b.angle[k - 1]) / (h * h);
    b.sign[k] = b.velocity[k] > 0.0 ? 1.0 : b.velocity[k] < 0.0 ? -1.0 : 0.0;
  }
  b.sign = smoothedSignal(b.sign, smoothing);
  return b;
}

std::vector<double> meanTorque(const Recording& d, int smoothing)
{
  std::vector<double> u(d.motor_torque.size(), 0.0);
  for (std::size_t k = 1; k < u.size(); ++k)
  {
    u[k] = 0.5 * (d.motor_torque[k - 1] + d.motor_torque[k]);
  }
  return smoothedSignal(u, smoothing);
}

Estimate RestBounds::level() const
{
  if (low < 0.0)
  {
    return Estimate{NAN, NAN};  // no rest
  }
  if (!std::isfinite(high))
  {
    return Estimate{low, NAN};  // never seen breaking away: at least this
  }
  if (low > high)
  {
    return Estimate{NAN, NAN};  // held above a level that broke it away: noise, not friction — not determined
  }
  return Estimate{0.5 * (low + high), (high - low) / std::sqrt(12.0)};
}

std::map<std::string, Estimate> InitialEstimates::byKey() const
{
  std::map<std::string, Estimate> out = {{"backlash", backlash},
                                         {"motor_inertia", motor_inertia},
                                         {"load_inertia", load_inertia},
                                         {"motor_friction", motor_friction},
                                         {"load_friction", load_friction},
                                         {"motor_coulomb_friction", motor_coulomb_friction},
                                         {"load_coulomb_friction", load_coulomb_friction},
                                         {"motor_static_friction", motor_static_friction},
                                         {"load_static_friction", load_static_friction},
                                         {"load_torque", load_torque}};
  if (std::isfinite(mesh_stiffness.value))
  {
    out["mesh_stiffness"] = mesh_stiffness;
    out["mesh_damping"] = mesh_damping;
  }
  return out;
}

ServoParams withEstimates(ServoParams joint, const std::map<std::string, Estimate>& estimates)
{
  for (const auto& [key, x] : estimates)
  {
    const ParamSpec* spec = findParam(key);
    if (!spec || !std::isfinite(x.value))
    {
      continue;
    }
    // Levels below zero (friction, the mesh's stiffness and damping) are zero within their scatter.
    const bool level = spec->range.lower == 0.0 && key != "restitution";
    joint.*std::get<double ServoParams::*>(spec->field) = level ? std::max(0.0, x.value) : x.value;
  }
  joint.motor_static_friction = std::max(joint.motor_static_friction, joint.motor_coulomb_friction);
  joint.load_static_friction = std::max(joint.load_static_friction, joint.load_coulomb_friction);
  return joint;
}

namespace
{
/// What each sample of a recording is: the gap θ_c − ρθ_m, the flanks where it dwells, and each sample's phase (0
/// apart, +1 on the forward flank, −1 on the backward flank, 2 mixed or unknown), with what decided them.
struct Phases
{
  std::vector<double> gap;          ///< of the angles as the equations read them (filtered when integrated) [rad]
  Flanks flanks;                    ///< where the gap dwells [rad]
  double range = 0.0;               ///< the gap's span between the flanks [rad]
  double band = 0.0, margin = 0.0;  ///< contact: within band of a flank; apart: clear of both by margin [rad]
  BodyMotion motor;                 ///< the motor's filtered angle and its differences
  double still = 0.0;               ///< [rad/s]: slower is standing
  AngleMeasurement motor_seen, load_seen;  ///< each angle's count grid and noise (integrated equations)
  EdgePhases edges;  ///< the phases read at the load's count edges, where the gap does not resolve
  std::vector<int> phase;
  std::size_t reach = 0;                     ///< samples a phase must hold on each side (stencil and filter)
  std::vector<std::size_t> changes, stills;  ///< prefix counts of phase changes and of standing samples
};

/// The range max − min of the samples.
double span(const std::vector<double>& x)
{
  const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
  return *hi - *lo;
}

Phases readPhases(const Recording& d, const IdentificationSettings& s, double h)
{
  const std::size_t n = d.time.size();
  const double rho = s.gear_ratio;
  Phases p;
  // The gap as recorded; integrated equations classify by the gap of the filtered angles (quantisation and noise
  // averaged out) and find the flanks where it dwells.
  const bool measured = s.contact_band > 0.0;
  // Integrated equations: each angle's count grid and noise, recognised once (measured_angles.h).
  if (s.integrated)
  {
    p.motor_seen = recogniseAngle(d.motor_position, s.motor_encoder_resolution);
    p.load_seen = recogniseAngle(d.load_position, s.load_encoder_resolution);
  }
  const int filter = s.integrated ? s.smoothing : 0;
  const std::vector<double> load_angle = smoothedSignal(d.load_position, filter),
                            motor_angle = smoothedSignal(d.motor_position, filter);
  p.gap.resize(n);
  for (std::size_t k = 0; k < n; ++k)
  {
    p.gap[k] = load_angle[k] - rho * motor_angle[k];
  }
  p.flanks = locateFlanks(p.gap, 2 * static_cast<std::size_t>(filter) + STENCIL, s.integrated ? s.contact_band : 0.0);
  const double lo = p.flanks.forward, hi = p.flanks.backward;
  p.range = hi - lo;
  p.band = measured ? s.contact_band : 1e-8 * p.range;
  // Apart means clear of both flanks: a chatter of short flights (a few µrad) between samples is neither phase. On
  // measured angles the band already holds the gap's spread on a flank.
  p.margin = s.integrated ? p.band : std::max(1e-3 * p.range, 4.0 * p.band);
  // Derivatives (every term of the equations filtered by the same F: differences commute with it, D²(Fθ) = F(D²θ)
  // against Fū and F sgn ω — quantisation and noise averaged out, the equations unchanged).
  p.motor = differentiate(d.motor_position, h, s.smoothing);
  double fastest = 0.0;
  for (double w : p.motor.velocity)
  {
    fastest = std::max(fastest, std::fabs(w));
  }
  // Measured angles: a body reads as moving only beyond four times the velocity's noise after the filter, and a
  // sample whose filter reaches a standstill is left out (the friction there is the static band's, not ±T_c).
  p.still = std::max(s.still_speed > 0.0 ? s.still_speed : 1e-6 * fastest,
                     s.integrated ? 4.0 * velocityNoise(p.motor_seen.noise, s, h) : 0.0);
  // A free play the gap does not resolve may show at the load's count edges (a coarse load encoder, a fine motor's).
  const bool resolved = p.range > 2.0 * (p.band + p.margin);
  if (s.integrated && !resolved)
  {
    p.edges = edgePhases(d, s, p.motor.velocity, p.still, p.motor_seen, p.load_seen);
  }
  requireThat((resolved && p.range > 0.0) || p.edges.resolved, "data",
              measured
                  ? "the free play is not resolved by the gap θ_c − ρθ_m: its flanks lie " + formatNumber(p.range) +
                        " rad apart, under four times the gap's measurement band (" + formatNumber(p.band) +
                        " rad, from the encoders' counts and noise), while the load moved over " +
                        formatNumber(span(d.load_position)) +
                        " rad — either the free play is smaller than that (finer or less noisy encoders resolve it) "
                        "or the teeth never left one flank (a load torque or friction holding them there: reversals "
                        "that carry the motor across the free play, as backlash_identify --experiment designs, show "
                        "it); nothing is estimated without the phases"
                  : "the gap θ_c − ρθ_m never spans the backlash: the recording needs reversals that carry the motor "
                    "across the free play to both flanks");
  p.phase = p.edges.resolved ? p.edges.phase : std::vector<int>(n, 0);
  for (std::size_t k = 0; k < n && !p.edges.resolved; ++k)
  {
    const double df = p.gap[k] - lo, db = hi - p.gap[k];
    p.phase[k] = std::fabs(df) <= p.band ? 1 : std::fabs(db) <= p.band ? -1 : (df > p.margin && db > p.margin) ? 0 : 2;
    if (s.integrated && p.phase[k] == 0)
    {
      // The recorded gap too: an impact between samples shows as one sample's dip to a flank, which the filter
      // hides (the teeth bounced: apart on both sides, but the motor's speed jumped).
      const double raw = d.load_position[k] - rho * d.motor_position[k];
      p.phase[k] = raw - lo > p.margin && hi - raw > p.margin ? 0 : 2;
    }
  }
  // A sample's phase must hold over the filter's support and the difference stencil.
  p.reach = STENCIL + 2 * static_cast<std::size_t>(s.smoothing);
  p.changes.assign(n + 1, 0);
  for (std::size_t k = 1; k < n; ++k)
  {
    p.changes[k + 1] = p.changes[k] + (p.phase[k] != p.phase[k - 1] ? 1 : 0);
  }
  p.stills.assign(n + 1, 0);
  for (std::size_t k = 0; k < n; ++k)
  {
    p.stills[k + 1] = p.stills[k] + (std::fabs(p.motor.velocity[k]) <= p.still ? 1 : 0);
  }
  return p;
}

/// Exact angles: the bodies' equations at each sample whose phase holds over its stencil (derivatives by
/// differences), one least-squares fit a phase.
void bodiesFromDerivatives(const Recording& d, const IdentificationSettings& s, const Phases& p, InitialEstimates* out)
{
  const std::size_t n = d.time.size(), reach = p.reach;
  const double rho = s.gear_ratio, lo = p.flanks.forward, hi = p.flanks.backward;
  const bool measured = s.contact_band > 0.0;
  const std::vector<double>&wm = p.motor.velocity, &am = p.motor.acceleration, &sg = p.motor.sign;
  const std::vector<double> ubar = meanTorque(d, s.smoothing);
  std::vector<std::size_t> contact, apart;
  for (std::size_t k = reach; k + reach < n; ++k)
  {
    const bool same = p.changes[k + reach + 1] == p.changes[k - reach + 1];
    const bool moving = p.stills[k + 1] == p.stills[k];
    if (!same || p.phase[k] == 2 || !moving)
    {
      continue;
    }
    (p.phase[k] == 0 ? apart : contact).push_back(k);
  }
  out->contact_samples = contact.size();
  out->apart_samples = apart.size();
  if (contact.size() < 20)
  {
    // The gap near the flanks but never held within the band: teeth that give (or angles coarser than the band).
    std::size_t near = 0;
    for (std::size_t k = 0; k < n; ++k)
    {
      near += std::min(p.gap[k] - lo, hi - p.gap[k]) <= 0.05 * p.range ? 1 : 0;
    }
    requireThat(
        near < n / 10, "data",
        "the gap θ_c − ρθ_m keeps moving near the flanks while the motor drives the load (never within the contact "
        "band of " +
            formatNumber(p.band) +
            " rad): the mesh looks compliant — give a prior with mesh_stiffness > 0 (a guess) to identify a "
            "compliant mesh — or, for measured angles, a contact band of their resolution");
  }
  requireThat(contact.size() >= 20, "data",
              "too few samples with the teeth in contact and moving (" + std::to_string(contact.size()) +
                  "): the recording needs motion while the motor drives the load");
  requireThat(apart.size() >= 20, "data",
              "too few samples with the teeth apart and the motor moving (" + std::to_string(apart.size()) +
                  "): the recording needs the motor to cross the free play");
  // Contact: ū = J α + F ω + C sgn ω + b.
  Eigen::MatrixXd xc(static_cast<Eigen::Index>(contact.size()), 4);
  Eigen::VectorXd yc(static_cast<Eigen::Index>(contact.size()));
  bool both_ways = false;
  for (std::size_t i = 0; i < contact.size(); ++i)
  {
    const std::size_t k = contact[i];
    both_ways = both_ways || (wm[k] > 0.0) != (wm[contact[0]] > 0.0);
    xc.row(static_cast<Eigen::Index>(i)) << am[k], wm[k], sg[k], 1.0;
    yc(static_cast<Eigen::Index>(i)) = ubar[k];
  }
  // Contact motion one way only: the Coulomb term and the load torque are one constant, split with the load torque
  // given (then not estimated).
  const bool known_load = !both_ways && std::isfinite(s.load_torque_fallback);
  requireThat(both_ways || known_load, "data",
              "in contact the joint moved one way only: Coulomb friction and the load torque cannot be told apart (the "
              "recording needs contact motion in both directions, or give the load torque)");
  if (known_load)
  {
    xc.col(3).setZero();
    yc.array() += rho * s.load_torque_fallback;  // ū − b, b = −ρT_ext
    xc.conservativeResize(Eigen::NoChange, 3);
  }
  // Apart: ū = J_m α + f_m ω + T_cm sgn ω.
  Eigen::MatrixXd xa(static_cast<Eigen::Index>(apart.size()), 3);
  Eigen::VectorXd ya(static_cast<Eigen::Index>(apart.size()));
  for (std::size_t i = 0; i < apart.size(); ++i)
  {
    const std::size_t k = apart[i];
    xa.row(static_cast<Eigen::Index>(i)) << am[k], wm[k], sg[k];
    ya(static_cast<Eigen::Index>(i)) = ubar[k];
  }
  std::size_t contact_kept = 0, apart_kept = 0;
  const LeastSquaresFit c = leastSquares(xc, yc, &contact_kept), a = leastSquares(xa, ya, &apart_kept);
  out->contact_samples = contact_kept;
  out->apart_samples = apart_kept;
  const auto combined = [](double x, double y) { return std::sqrt(x * x + y * y); };
  out->motor_inertia = {a.p(0), a.se(0)};
  out->motor_friction = {a.p(1), a.se(1)};
  out->motor_coulomb_friction = {a.p(2), a.se(2)};
  out->load_inertia = {(c.p(0) - a.p(0)) / (rho * rho), combined(c.se(0), a.se(0)) / (rho * rho)};
  out->load_friction = {(c.p(1) - a.p(1)) / (rho * rho), combined(c.se(1), a.se(1)) / (rho * rho)};
  out->load_coulomb_friction = {(c.p(2) - a.p(2)) / rho, combined(c.se(2), a.se(2)) / rho};
  out->load_torque = known_load ? Estimate{s.load_torque_fallback, NAN} : Estimate{-c.p(3) / rho, c.se(3) / rho};
  // A level that came out below zero by more than two standard errors is not what the data say of it, but a sign
  // that the model does not fit these samples (noise the filter left, a phase misread, an excitation that does not
  // tell the terms apart). Exact angles: a level a hair below zero is zero, and the model takes it so — a hair is a
  // torque (the term at the motor shaft, at the motion's rms) under 0.5 % of the recorded torque's rms.
  const auto rms = [](const std::vector<double>& v) {
    return std::sqrt(std::inner_product(v.begin(), v.end(), v.begin(), 0.0) / static_cast<double>(v.size()));
  };
  const double u_rms = rms(d.motor_torque), w_rms = rms(wm), a_rms = rms(am);
  const double at_motor[6] = {a_rms, rho * rho * a_rms, w_rms, rho * rho * w_rms, 1.0, rho};
  int term = 0;
  for (const auto& [key, x] :
       {std::make_pair("motor_inertia", out->motor_inertia), std::make_pair("load_inertia", out->load_inertia),
        std::make_pair("motor_friction", out->motor_friction), std::make_pair("load_friction", out->load_friction),
        std::make_pair("motor_coulomb_friction", out->motor_coulomb_friction),
        std::make_pair("load_coulomb_friction", out->load_coulomb_friction)})
  {
    const bool hair = !measured && -x.value * at_motor[term++] < 0.005 * u_rms;
    if (x.value < -2.0 * x.standard_error && !hair)
    {
      out->not_identifiable[key] = "it came out negative (" + formatNumber(x.value) + " ± " +
                                   formatNumber(x.standard_error) + "): these samples do not fit the model";
    }
  }
  out->load_torque_given = known_load;
  out->contact_rms_residual = c.rms;
  out->apart_rms_residual = a.rms;
}

/// The samples of the teeth driving on one flank: the filtered gap at each [rad], where each episode (a run of
/// consecutive samples) begins in it, and how many distinct counts each encoder read there.
struct FlankSamples
{
  std::vector<double> gap;
  std::vector<std::size_t> episodes;
  std::size_t motor_counts = 0, load_counts = 0;
};

/// The number of distinct values of `angle` over the samples `at` (counts of an encoder on a grid).
std::size_t distinctCounts(const std::vector<double>& angle, const std::vector<std::size_t>& at)
{
  std::vector<double> seen;
  seen.reserve(at.size());
  for (std::size_t k : at)
  {
    seen.push_back(angle[k]);
  }
  std::sort(seen.begin(), seen.end());
  return static_cast<std::size_t>(std::unique(seen.begin(), seen.end()) - seen.begin());
}

/// The driven samples on the flank `side` (+1 forward, −1 backward) of the filtered gap.
FlankSamples flankSamples(const Recording& d, const Phases& p, const std::vector<bool>& driven, int side,
                          std::size_t trim)
{
  FlankSamples out;
  std::vector<std::size_t> at;
  const std::size_t n = p.gap.size();
  for (std::size_t a = 0; a < n;)
  {
    if (!(driven[a] && p.phase[a] == side))
    {
      ++a;
      continue;
    }
    std::size_t b = a;
    while (b < n && driven[b] && p.phase[b] == side)
    {
      ++b;
    }
    // (the filter reaches into the flights on either side of an episode for `trim` samples at its ends)
    if (b - a > 2 * trim)
    {
      out.episodes.push_back(out.gap.size());
      for (std::size_t k = a + trim; k < b - trim; ++k)
      {
        at.push_back(k);
        out.gap.push_back(p.gap[k]);
      }
    }
    a = b;
  }
  out.motor_counts = distinctCounts(d.motor_position, at);
  out.load_counts = distinctCounts(d.load_position, at);
  return out;
}

/// The fewest episodes on a flank whose scatter measures the error of where the teeth meet there.
constexpr std::size_t FEWEST_EPISODES = 8;
/// How far the filtered gap on a flank may scatter beyond what the encoders' noise explains while the samples there
/// are taken as contact alone (more: chatter or flights within the band, which lean the crowd into the play).
constexpr double CONTACT_SCATTER = 1.5;

/// The standard deviation [rad] of the filtered gap's noise: each angle's σ through the smoothing filter (a box of
/// L = 2r + 1 samples applied twice: Σw² = (2L² + 1)/(3L³)); infinite when the angles' noise is not known.
double filteredGapNoise(const AngleMeasurement& motor, const AngleMeasurement& load, const IdentificationSettings& s)
{
  const double raw = std::hypot(load.noise, s.gear_ratio * motor.noise);
  const double l = 2.0 * std::max(s.smoothing, 0) + 1.0;
  return raw > 0.0 ? raw * std::sqrt((2.0 * l * l + 1.0) / (3.0 * l * l * l)) : INF;
}

/**
 * The variance [rad²] of a flank's position `centre` (the mode of its samples' filtered gap). With enough episodes
 * of the teeth on it and a scatter the encoders' noise explains, their means' scatter about the centre over their
 * number (cluster-robust: the noise within an episode, the quantisation of where it ran and a mode leaning from them
 * all count, each episode once); else each
 * sample's scatter σ, the median's 1.2533 σ/√n_eff (n_eff the samples over the filter's width 4r + 1) and its lean
 * from the mode. A count grid without noise adds a count's uniform spread q/√12 over √(distinct counts read there):
 * a reading's rounding is a fixed function of the angle, averaged only over the counts visited.
 */
double flankVariance(const FlankSamples& f, double centre, const AngleMeasurement& motor, const AngleMeasurement& load,
                     const IdentificationSettings& s)
{
  double variance = 0.0;
  const std::size_t m = f.episodes.size();
  const FlankSpread spread = flankSpread(f.gap);
  if (m >= FEWEST_EPISODES && spread.sigma <= CONTACT_SCATTER * filteredGapNoise(motor, load, s))
  {
    std::vector<double> means(m);
    for (std::size_t i = 0; i < m; ++i)
    {
      const auto first = f.gap.begin() + static_cast<long>(f.episodes[i]);
      const auto last = i + 1 < m ? f.gap.begin() + static_cast<long>(f.episodes[i + 1]) : f.gap.end();
      means[i] = std::accumulate(first, last, 0.0) / static_cast<double>(last - first);
    }
    const double mean = std::accumulate(means.begin(), means.end(), 0.0) / static_cast<double>(m);
    double sum = 0.0;
    for (double x : means)
    {
      sum += (x - mean) * (x - mean);
    }
    // (the episodes' mean and the samples' mode part where flights within the band lean the crowd into the play)
    variance = sum / static_cast<double>(m * (m - 1)) + (centre - mean) * (centre - mean);
  }
  else
  {
    const double width = 4.0 * std::max(s.smoothing, 0) + 1.0;
    // The median's scatter, and one sample's scatter for where the crowd's centre lies (the filtered gap's noise is
    // not symmetric about a flank the teeth bounce off: no narrower claim is made).
    variance = spread.lean * spread.lean +
               spread.sigma * spread.sigma * (1.0 + 1.5708 * width / static_cast<double>(f.gap.size()));
  }
  for (const auto& [seen, factor, counts] :
       {std::make_tuple(load, 1.0, f.load_counts), std::make_tuple(motor, s.gear_ratio, f.motor_counts)})
  {
    if (seen.resolution > 0.0)
    {
      const double q = factor * TWO_PI / seen.resolution;
      variance += q * q / (12.0 * static_cast<double>(std::max<std::size_t>(counts, 1)));
    }
  }
  return variance;
}

/// Measured angles: a flank the teeth never drove on (the gap only turned there, in flight) is no flank — its samples
/// become no phase (2) and the backlash is only bounded by the gap's range. Returns the flank so dropped ("forward",
/// "backward") or "".
std::string dropUndrivenFlanks(const std::vector<bool>& driven, std::vector<int>* phase)
{
  std::string unreached;
  for (const int flank : {1, -1})
  {
    std::size_t count = 0;
    for (std::size_t k = 0; k < phase->size(); ++k)
    {
      count += driven[k] && (*phase)[k] == flank ? 1 : 0;
    }
    if (count < FEWEST_DRIVEN)
    {
      unreached = flank == 1 ? "forward" : "backward";
      std::replace(phase->begin(), phase->end(), flank, 2);
    }
  }
  return unreached;
}

/// The backlash and the zero offset from the gaps on each flank (their medians; with integrated equations, where the
/// samples crowd), with what the recording cannot give said in `out->not_identifiable`.
void locateBacklash(const Recording& d, const IdentificationSettings& s, const Phases& p,
                    const std::vector<bool>& driven, std::size_t trim, const std::string& unreached,
                    InitialEstimates* out)
{
  const std::size_t n = p.gap.size();
  // The backlash between the flanks' typical gaps (medians over the samples in contact on each: quantisation and
  // noise at the extremes do not widen it); the zero offset likewise.
  // (integrated equations: the gap while the teeth drive the load on a flank, not where it turns in flight)
  std::vector<double> on_forward, on_backward;
  for (std::size_t k = 0; k < n; ++k)
  {
    if (s.integrated && !driven[k])
    {
      continue;
    }
    if (p.phase[k] == 1)
    {
      on_forward.push_back(p.gap[k]);
    }
    else if (p.phase[k] == -1)
    {
      on_backward.push_back(p.gap[k]);
    }
  }
  if (!on_forward.empty() && !on_backward.empty())
  {
    out->zero_offset = median(on_forward);
    out->backlash = {median(on_backward) - out->zero_offset, p.band};
    if (s.integrated)
    {
      // Where the samples on a flank crowd (its mode): the medians lean into the play, as the band also holds the
      // samples of short flights and small rebounds beside the flank.
      const FlankSamples forward = flankSamples(d, p, driven, 1, trim), backward = flankSamples(d, p, driven, -1, trim);
      out->zero_offset = halfSampleMode(forward.gap);
      const double backward_mode = halfSampleMode(backward.gap);
      // (and how far each mode lies from where the gap's extreme crowd was found: a gap that hovers beside a flank
      // moves the one but not the other)
      const double variance = flankVariance(forward, out->zero_offset, p.motor_seen, p.load_seen, s) +
                              flankVariance(backward, backward_mode, p.motor_seen, p.load_seen, s);
      out->backlash = {
          backward_mode - out->zero_offset,
          std::hypot(std::sqrt(variance), out->zero_offset - p.flanks.forward, backward_mode - p.flanks.backward)};
    }
  }
  else
  {
    out->backlash = {p.range, p.band};
  }
  if (p.edges.resolved)
  {
    out->zero_offset = p.edges.forward;
    out->backlash = p.edges.backlash;
    out->phases_from_edges = true;
  }
  if (s.integrated && unreached.empty() && !(out->backlash.standard_error <= LOOSEST_BACKLASH * out->backlash.value))
  {
    out->not_identifiable["backlash"] = "the recording gives " + formatNumber(out->backlash.value) + " ± " +
                                        formatNumber(out->backlash.standard_error) + " rad, not within ±" +
                                        formatNumber(100.0 * LOOSEST_BACKLASH) +
                                        " % (the flanks' gaps are spread by noise or a load hovering beside them)";
  }
  if (!unreached.empty())
  {
    out->not_identifiable["backlash"] = "the teeth never drove on the " + unreached +
                                        " flank (the gap only turned there): the backlash is at least " +
                                        formatNumber(p.range) + " rad, the gap's range";
    out->backlash = {NAN, NAN};
  }
  // The phases follow from the flanks: where these are not located to the backlash's ±5 %, samples read apart may be
  // in contact and the split between the bodies is not trusted (the pair's sums, from the samples on a flank, stay).
  if (s.integrated && out->not_identifiable.count("backlash") && !out->not_identifiable.count("motor_inertia"))
  {
    for (const char* key : {"motor_inertia", "motor_friction", "motor_coulomb_friction", "load_inertia",
                            "load_friction", "load_coulomb_friction"})
    {
      out->not_identifiable[key] =
          "the flanks are not located well enough to tell the teeth apart from in contact (the backlash is not "
          "identified), so the split between the bodies is not trusted";
    }
  }
}

/// Static friction from the rests of the recording (`out->load_torque` estimated first).
void staticFromRests(const Recording& d, const IdentificationSettings& s, double h, const Phases& p,
                     InitialEstimates* out)
{
  const std::size_t n = d.time.size(), r = static_cast<std::size_t>(s.smoothing);
  const double rho = s.gear_ratio;
  const auto combined = [](double x, double y) { return std::sqrt(x * x + y * y); };
  // Static friction from the rests: over a sample interval [t_k, t_k+1) the torque u_k is held, so a body at rest
  // over it was held by its static band (|net| ≤ T_s: a lower bound) and the interval where it broke away had
  // |net| > T_s (an upper bound). Teeth apart: the motor alone, net u_k; teeth on a flank: the pair, net u_k + ρT_ext
  // against T_sm + ρT_sL. A rest is a run of at least minimumRest() samples, in one phase, over which the
  // (filtered) motor angle stays within the contact band: a velocity reversal passes through slow motion too, but
  // leaves the band (½α t² grows). The filter F starts moving 2r samples before the body does, so the
  // breakaway interval is the one after the run's last sample, plus 2r.
  const std::size_t min_rest = minimumRest(s, h);
  RestBounds motor_alone, pair;
  const double text = out->load_torque.value;
  const auto net = [&](std::size_t k, int in) { return std::fabs(d.motor_torque[k] + (in == 0 ? 0.0 : rho * text)); };
  // (A run in one phase, never the mixed one.)
  const auto together = [&p](std::size_t a, std::size_t k) { return p.phase[a] != 2 && p.phase[k] == p.phase[a]; };
  forEachRest(p.motor.angle, p.band, p.reach, n - p.reach - 1, min_rest, together, [&](std::size_t a, std::size_t b) {
    RestBounds& bound = p.phase[a] == 0 ? motor_alone : pair;
    for (std::size_t k = a; k + 1 < b; ++k)  // the intervals inside the run
    {
      bound.low = std::max(bound.low, net(k, p.phase[a]));
    }
    // The interval from the run's last sample broke it away (on a flank the pair must still be there after it: a
    // motor breaking away from the load alone has a lower threshold).
    const std::size_t away = b - 1 + 2 * r;
    if (away + p.reach + 1 < n && p.phase[b] == p.phase[a] && p.phase[away] == p.phase[a] &&
        p.phase[away + 1] == p.phase[a])
    {
      bound.high = std::min(bound.high, net(away, p.phase[a]));
    }
  });
  out->motor_static_friction = motor_alone.level();
  const Estimate combined_static = pair.level();
  if (std::isfinite(out->motor_static_friction.value) && std::isfinite(combined_static.value))
  {
    out->load_static_friction = {
        (combined_static.value - out->motor_static_friction.value) / rho,
        combined(combined_static.standard_error, out->motor_static_friction.standard_error) / rho};
  }
}
}  // namespace

InitialEstimates estimateInitial(const Recording& d, const IdentificationSettings& s)
{
  const double h = samplePeriod(d, s);
  const bool measured = s.contact_band > 0.0;
  const std::size_t r = static_cast<std::size_t>(s.smoothing);
  Phases p = readPhases(d, s, h);
  InitialEstimates out;
  out.zero_offset = p.flanks.forward;
  // (a stretch's trimmed ends: where the filter reaches across a change of phase)
  const std::size_t trim = 2 * r + 2;
  const std::vector<bool> driven = drivenMask(p.phase, trim);
  const std::string unreached =
      measured && s.integrated && !p.edges.resolved ? dropUndrivenFlanks(driven, &p.phase) : std::string();
  if (measured && s.integrated)
  {
    bodiesFromIntegrals(d, s, p.phase, p.motor.velocity, p.stills, trim, p.motor_seen, &out);
  }
  else
  {
    bodiesFromDerivatives(d, s, p, &out);
  }
  locateBacklash(d, s, p, driven, trim, unreached, &out);
  staticFromRests(d, s, h, p, &out);
  // Nothing at all: say what the recording lacks (the backlash's reason and the bodies').
  const bool nothing = out.not_identifiable.count("backlash") && out.not_identifiable.count("motor_inertia") &&
                       out.not_identifiable.count("load_inertia") &&
                       out.not_identifiable.count("motor_coulomb_friction") &&
                       out.not_identifiable.count("load_coulomb_friction");
  if (nothing)
  {
    throw InvalidParameterError(
        "data", "nothing can be estimated from this recording — the backlash: " + out.not_identifiable.at("backlash") +
                    "; the bodies: " + out.not_identifiable.at("motor_inertia"));
  }
  return out;
}

std::vector<ProfileSegment> identificationExperiment(const ServoParams& params, double duration, double travel,
                                                     double dither_amplitude, double dither_frequency)
{
  requireThat(std::isfinite(dither_amplitude) && dither_amplitude >= 0.0, "dither", "the amplitude must be >= 0 rad");
  requireThat(dither_amplitude == 0.0 || (std::isfinite(dither_frequency) && dither_frequency > 0.0), "dither",
              "the frequency must be > 0 Hz");
  requireThat(std::isfinite(duration) && duration > 0.0, "duration", "must be > 0 s");
  requireThat(params.backlash > 0.0, "backlash",
              "the prior's backlash is 0 (rigid teeth): give a guess of it, from which the experiment's travel (three "
              "backlashes at least) and its reversals are designed");
  requireThat(std::isfinite(travel) && travel >= 3.0 * params.backlash, "travel",
              "must be at least three times the backlash (" + formatNumber(3.0 * params.backlash) +
                  " rad): every reversal must carry the motor across the free play (got " + formatNumber(travel) + ")");
  // (the command stays within the set-point's range)
  param("command").check(travel);
  const double wn = params.naturalFrequency(), pi = 3.14159265358979323846;
  const double fractions[3] = {1.0 / 8.0, 1.0 / 3.0, 1.0 / 1.5}, amplitudes[3] = {1.0, 1.0, 0.5};
  std::vector<ProfileSegment> out;
  for (int i = 0; i < 3; ++i)
  {
    ProfileSegment s;
    s.kind = ProfileSegment::Kind::Sine;
    s.time = duration * i / 3.0;
    s.duration = duration / 3.0;
    s.amplitude = travel * amplitudes[i];
    s.frequency = fractions[i] * wn / (2.0 * pi);  // [Hz]
    s.dither_amplitude = dither_amplitude;
    s.dither_frequency = dither_amplitude > 0.0 ? dither_frequency : 0.0;
    out.push_back(s);
  }
  return out;
}

}  // namespace backlash_servo
