#include "backlash_servo/measured_angles.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace backlash_servo
{
namespace
{
constexpr double TWO_PI = 6.283185307179586;
/// Third differences alternating at least this much (white noise: −3/4, smooth motion: near +1) are noise.
constexpr double NOISE_CORRELATION = -0.3;
/// The smoothing [samples] of measured angles.
constexpr int CLASSIFYING_SMOOTHING = 2;

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
  // The filter classifies the phases and signs the velocity (the equations are integrated, not differentiated):
  // r = 2 brings the moving gap's noise 4σ_g√(2/(3(2r + 1))) below a still count's half-width √3σ_g.
  if (s.smoothing == 0)
  {
    out.smoothing = CLASSIFYING_SMOOTHING;
  }
  // The band: a count's half-width still, four filtered standard deviations moving.
  const double sigma_g = std::hypot(out.load.noise, rho * out.motor.noise);
  const double filtered = sigma_g * std::sqrt(2.0 / (3.0 * (2.0 * out.smoothing + 1.0)));
  out.contact_band = std::sqrt(3.0) * sigma_g + 4.0 * filtered;
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
