#include "backlash_servo/identification/measured_angles.h"
#include "backlash_servo/model/constants.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace backlash_servo
{
namespace
{
/// Third differences alternating at least this much (white noise: −3/4, smooth motion: near +1) are noise.
constexpr double NOISE_CORRELATION = -0.3;
/// The smoothing [samples] of measured angles: the least and the widest tried.
constexpr int CLASSIFYING_SMOOTHING = 2;
constexpr int WIDEST_CLASSIFYING = 32;

double median(std::vector<double> v)
{
  if (v.empty())
  {
    return 0.0;
  }
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Whether every sample is a whole number of counts of an N-count encoder (to 1e-6 of a count).
bool onGrid(const std::vector<double>& angle, double counts)
{
  const double per = counts / TWO_PI;
  return counts > 0.0 && std::all_of(angle.begin(), angle.end(),
                                     [per](double x) { return std::fabs(x * per - std::round(x * per)) <= 1e-6; });
}

/// The resolution the samples' smallest step suggests, when every sample lies on its grid (0: none).
double gridOf(const std::vector<double>& angle)
{
  double step = INFINITY;
  for (std::size_t k = 1; k < angle.size(); ++k)
  {
    const double d = std::fabs(angle[k] - angle[k - 1]);
    if (d > 0.0)
    {
      step = std::min(step, d);
    }
  }
  if (!std::isfinite(step))
  {
    return 0.0;
  }
  const double counts = std::round(TWO_PI / step);
  return counts >= 2.0 && onGrid(angle, counts) ? counts : 0.0;
}

}  // namespace

AngleMeasurement recogniseAngle(const std::vector<double>& angle, double stated)
{
  AngleMeasurement m;
  m.resolution = stated > 0.0 && onGrid(angle, stated) ? stated : gridOf(angle);
  // Third differences where the angle moves (a body at rest on a count reads no noise).
  std::vector<double> d3;
  d3.reserve(angle.size());
  for (std::size_t k = 3; k < angle.size(); ++k)
  {
    if (angle[k] != angle[k - 1] || angle[k - 1] != angle[k - 2] || angle[k - 2] != angle[k - 3])
    {
      d3.push_back(angle[k] - 3.0 * angle[k - 1] + 3.0 * angle[k - 2] - angle[k - 3]);
    }
  }
  std::vector<double> magnitude(d3.size());
  std::transform(d3.begin(), d3.end(), magnitude.begin(), [](double x) { return std::fabs(x); });
  const double sigma = 1.4826 * median(magnitude) / std::sqrt(20.0);
  // Lag-one correlation of the typical third differences (impacts and breakaways, beyond 5σ, left out).
  double sxy = 0.0, sxx = 0.0;
  const double limit = 5.0 * std::sqrt(20.0) * sigma;
  for (std::size_t i = 1; i < d3.size(); ++i)
  {
    if (std::fabs(d3[i]) <= limit && std::fabs(d3[i - 1]) <= limit)
    {
      sxy += d3[i] * d3[i - 1];
      sxx += d3[i] * d3[i];
    }
  }
  const bool noisy = sxx > 0.0 && sxy / sxx < NOISE_CORRELATION;
  if (m.resolution > 0.0 || noisy)
  {
    // At least a count's uniform spread on a grid.
    m.noise = std::max(sigma, m.resolution > 0.0 ? TWO_PI / (m.resolution * std::sqrt(12.0)) : 0.0);
  }
  return m;
}

MeasuredAngles recogniseMeasurement(const Recording& data, const IdentificationSettings& s)
{
  MeasuredAngles out;
  out.motor = recogniseAngle(data.motor_position, s.motor_encoder_resolution);
  out.load = recogniseAngle(data.load_position, s.load_encoder_resolution);
  out.smoothing = s.smoothing;
  out.contact_band = s.contact_band;
  const bool measured = out.motor.measured() || out.load.measured();
  out.integrated = s.smoothing == 0 && measured;
  if (!measured || s.contact_band > 0.0)
  {
    return out;  // exact angles, or the band given (the smoothing as given)
  }
  out.from_data = true;
  samplePeriod(data, s);  // (checks the recording)
  const double rho = s.gear_ratio;
  // The band: half a count of each angle on a grid (a body at rest reads one count), four standard deviations of
  // the filtered noise of the others.
  const auto count = [](const AngleMeasurement& a) { return a.resolution > 0.0 ? TWO_PI / a.resolution : 0.0; };
  const auto noise = [](const AngleMeasurement& a) { return a.resolution > 0.0 ? 0.0 : a.noise; };
  const double half_count = 0.5 * (count(out.load) + rho * count(out.motor));
  const double sigma = std::hypot(noise(out.load), rho * noise(out.motor));
  const auto bandFor = [&](int r) { return half_count + 4.0 * sigma * std::sqrt(2.0 / (3.0 * (2.0 * r + 1.0))); };
  // The filter classifies the phases and signs the velocity (the equations are integrated, not differentiated): the
  // least of 2, 4, … 32 samples whose band resolves the flanks (four bands apart), so that short flights survive.
  if (s.smoothing > 0)
  {
    // The filtered derivatives (a smoothing given): samples in contact within two counts of the gap, so that a
    // creeping body's count steps stay inside.
    out.contact_band = 3.0 * half_count + bandFor(s.smoothing);
    return out;
  }
  for (int r = CLASSIFYING_SMOOTHING; r <= WIDEST_CLASSIFYING; r *= 2)
  {
    out.smoothing = r;
    out.contact_band = bandFor(r);
    const std::vector<double> load = smoothedSignal(data.load_position, r),
                              motor = smoothedSignal(data.motor_position, r);
    std::vector<double> gap(load.size());
    for (std::size_t k = 0; k < gap.size(); ++k)
    {
      gap[k] = load[k] - rho * motor[k];
    }
    const Flanks flanks = locateFlanks(gap, static_cast<std::size_t>(2 * r + 2), out.contact_band);
    if (flanks.backward - flanks.forward > 4.0 * out.contact_band)
    {
      break;
    }
  }
  return out;
}

std::string MeasuredAngles::summary() const
{
  const auto angle = [](const char* name, const AngleMeasurement& a) {
    char buf[160];
    if (!a.measured())
    {
      std::snprintf(buf, sizeof buf, "%s angle exact", name);
    }
    else if (a.resolution > 0.0)
    {
      std::snprintf(buf, sizeof buf, "%s angle on a %.0f-count grid, noise %.3g rad", name, a.resolution, a.noise);
    }
    else
    {
      std::snprintf(buf, sizeof buf, "%s angle noisy (no count grid), noise %.3g rad", name, a.noise);
    }
    return std::string(buf);
  };
  char tail[160];
  std::snprintf(tail, sizeof tail, "; smoothing %d samples, contact band %.3g rad%s", smoothing, contact_band,
                from_data                             ? " (from the data)"
                : contact_band > 0.0 || smoothing > 0 ? " (as given)"
                                                      : "");
  return angle("motor", motor) + ", " + angle("load", load) + tail;
}

}  // namespace backlash_servo
