#include "backlash_servo/identification/replay_windows.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <tuple>
#include <utility>

#include "backlash_servo/simulation/simulator.h"

namespace backlash_servo
{
namespace
{
/// Measured angles: the samples on each side of an anchor its parabola is fitted over.
constexpr std::size_t ANCHOR_REACH = 8;

/// The value and slope at sample k of the least-squares parabola through x over [k − m, k + m] (period h [s]).
std::pair<double, double> localParabola(const std::vector<double>& x, std::size_t k, std::size_t m, double h)
{
  if (m == 0 || k + m >= x.size())
  {
    return {x[k], 0.0};
  }
  // Centred, τ = (i − k): the parabola's odd part gives the slope, its even part the value.
  double s2 = 0.0, s4 = 0.0, y0 = 0.0, y1 = 0.0, y2 = 0.0;
  const double count = static_cast<double>(2 * m + 1);
  for (std::size_t i = k - m; i <= k + m; ++i)
  {
    const double tau = static_cast<double>(i) - static_cast<double>(k);
    s2 += tau * tau;
    s4 += tau * tau * tau * tau;
    y0 += x[i];
    y1 += tau * x[i];
    y2 += tau * tau * x[i];
  }
  const double c = (count * y2 - s2 * y0) / (count * s4 - s2 * s2);  // curvature term
  const double a = (y0 - c * s2) / count;
  return {a, y1 / s2 / h};
}

}  // namespace

ReplayWindows::ReplayWindows(const Recording& data, const IdentificationSettings& settings, double zero_offset,
                             std::vector<std::size_t> starts, std::size_t length)
    : data_(data),
      rho_(settings.gear_ratio),
      band_(settings.contact_band),
      zero_offset_(zero_offset),
      starts_(std::move(starts)),
      length_(length)
{
  const std::size_t n = data.time.size();
  if (starts_.empty() || length_ == 0)
  {
    throw InvalidParameterError("data", "no window to replay (the recording is too short for one)");
  }
  for (std::size_t k0 : starts_)
  {
    if (k0 < 1 || k0 + length_ + 1 >= n)
    {
      throw InvalidParameterError("data", "a replay window (sample " + std::to_string(k0) + ", " +
                                              std::to_string(length_) + " samples) does not fit in the recording");
    }
  }
  const double h = (data.time.back() - data.time.front()) / static_cast<double>(n - 1);
  const std::size_t half = minimumRest(settings, h) / 2;
  const std::vector<double> motor = smoothedSignal(data.motor_position, settings.smoothing),
                            load = smoothedSignal(data.load_position, settings.smoothing);
  for (std::size_t k0 : starts_)
  {
    Anchor a;
    a.time = data.time[k0];
    // As measured (a filtered angle is blurred across an impact); the filtered signals serve the still test only.
    a.motor_position = data.motor_position[k0];
    a.load_position = data.load_position[k0];
    a.motor_velocity = (data.motor_position[k0 + 1] - data.motor_position[k0 - 1]) / (2.0 * h);
    a.load_velocity = (data.load_position[k0 + 1] - data.load_position[k0 - 1]) / (2.0 * h);
    if (settings.integrated)
    {
      // Measured angles: each angle and its speed from a parabola fitted over the samples around the anchor (the
      // raw angle's noise would set the replay off by as much).
      const std::size_t reach = std::min<std::size_t>(ANCHOR_REACH, k0);
      std::tie(a.motor_position, a.motor_velocity) = localParabola(data.motor_position, k0, reach, h);
      std::tie(a.load_position, a.load_velocity) = localParabola(data.load_position, k0, reach, h);
    }
    a.gap = a.load_position - rho_ * a.motor_position - zero_offset_;
    // A body at rest over the anchor's stencil starts at rest, uncorrected: with static friction above the Coulomb
    // level a body at rest and one creeping at 1e-12 rad/s part ways (the one sticks, the other slides on).
    // (At rest: within the contact band over a rest's length centred on the anchor — identification.h.)
    const auto still = [&](const std::vector<double>& x) {
      const double tolerance =
          settings.contact_band > 0.0 ? settings.contact_band : 1e-12 * std::max(1.0, std::fabs(x[k0]));
      const std::size_t lo = k0 >= half ? k0 - half : 0, hi = std::min(n - 1, k0 + half);
      const auto [least, most] =
          std::minmax_element(x.begin() + static_cast<long>(lo), x.begin() + static_cast<long>(hi) + 1);
      return *most - *least <= tolerance;
    };
    a.motor_still = still(motor);
    a.load_still = still(load);
    if (a.motor_still)
    {
      a.motor_velocity = 0.0;
    }
    if (a.load_still)
    {
      a.load_velocity = 0.0;
    }
    anchors_.push_back(a);
  }
}

std::vector<std::size_t> ReplayWindows::beforeImpacts(const Recording& d, double rho, double zero_offset, double delta,
                                                      std::size_t length, std::size_t lead, std::size_t count)
{
  const std::size_t n = d.time.size();
  const double margin = 1e-3 * delta;
  const auto gapOf = [&](std::size_t k) { return d.load_position[k] - rho * d.motor_position[k] - zero_offset; };
  const auto clear = [&](std::size_t k) { return gapOf(k) > margin && gapOf(k) < delta - margin; };
  std::vector<std::size_t> starts;
  for (std::size_t k = lead + 1; k + length + 1 < n; ++k)
  {
    if (clear(k - 1) && !clear(k) && clear(k - lead))
    {
      starts.push_back(k - lead);
      k += length;  // (windows do not overlap)
    }
  }
  if (starts.size() <= count)
  {
    return starts;
  }
  std::vector<std::size_t> chosen;
  for (std::size_t i = 0; i < count; ++i)
  {
    chosen.push_back(starts[i * starts.size() / count]);
  }
  return chosen;
}

std::vector<std::size_t> ReplayWindows::spread(std::size_t samples, std::size_t length, std::size_t count)
{
  std::vector<std::size_t> starts;
  if (samples < length + 3 || count == 0)
  {
    return starts;
  }
  const std::size_t room = samples - length - 2;  // first samples in [1, room]
  const std::size_t fit = std::max<std::size_t>(1, std::min(count, room / length));
  for (std::size_t i = 0; i < fit; ++i)
  {
    starts.push_back(fit == 1 ? 1 : 1 + i * (room - 1) / (fit - 1));
  }
  return starts;
}

template <class Visit>
void ReplayWindows::replayWindow(const ServoParams& params, std::size_t w, const double* c, Visit visit) const
{
  static const double none[CORRECTIONS] = {0.0, 0.0};
  c = c ? c : none;
  const double delta = params.backlash;
  const double band = band_ > 0.0 ? band_ : 1e-8 * delta;
  const Anchor& a = anchors_[w];
  State x;
  x.time = a.time;
  x.motor_position = a.motor_position;
  x.motor_velocity = a.motor_velocity + (a.motor_still ? 0.0 : c[0]);
  x.load_velocity = a.load_velocity + (a.load_still ? 0.0 : c[1]);
  if (params.compliant())
  {
    // A compliant mesh: the angles as measured (a gap beyond a flank is the mesh's penetration), each velocity its own.
    x.load_position = rho_ * x.motor_position + a.gap;
  }
  else
  {
    // Rigid teeth: on a flank within the band (the pair then moves as one), else apart with the gap clamped.
    x.contact = a.gap <= band ? Contact::Forward : a.gap >= delta - band ? Contact::Backward : Contact::Apart;
    x.load_position = rho_ * x.motor_position + (x.contact == Contact::Forward    ? 0.0
                                                 : x.contact == Contact::Backward ? delta
                                                                                  : a.gap);
    if (x.contact != Contact::Apart && a.motor_still != a.load_still)
    {
      x.load_velocity = x.motor_velocity = 0.0;  // (one of them is seen still)
    }
    else if (x.contact != Contact::Apart)
    {
      x.load_velocity = 0.5 * (x.load_velocity + rho_ * x.motor_velocity);
      x.motor_velocity = x.load_velocity / rho_;
    }
  }
  Simulator sim(params, x, 0.0);
  sim.setEnergyTracking(false);
  const double shift = a.load_position - x.load_position;  // the encoders' offset, put back when compared
  const std::size_t k0 = starts_[w];
  sim.setMotorTorque(data_.motor_torque[k0]);
  sim.setInputHorizon(data_.time[k0 + 1]);  // (held: the next change is at the next sample)
  for (std::size_t k = k0 + 1; k <= k0 + length_; ++k)
  {
    sim.advanceTo(data_.time[k]);
    visit(k, sim.state().motor_position, sim.state().load_position + shift);
    sim.setMotorTorque(data_.motor_torque[k]);
    sim.setInputHorizon(data_.time[std::min(k + 1, data_.time.size() - 1)]);
  }
}

void ReplayWindows::residuals(const ServoParams& params, std::vector<double>* out, bool load_only,
                              const std::vector<double>* corrections) const
{
  out->clear();
  out->reserve(load_only ? size() / 2 : size());
  for (std::size_t w = 0; w < starts_.size(); ++w)
  {
    replayWindow(params, w, corrections ? corrections->data() + CORRECTIONS * w : nullptr,
                 [&](std::size_t k, double motor, double load) {
                   if (!load_only)
                   {
                     out->push_back(rho_ * (motor - data_.motor_position[k]));
                   }
                   out->push_back(load - data_.load_position[k]);
                 });
  }
}

void ReplayWindows::windowResiduals(const ServoParams& params, std::size_t w, const double* corrections,
                                    std::vector<double>* out) const
{
  out->clear();
  replayWindow(params, w, corrections, [&](std::size_t k, double motor, double load) {
    out->push_back(rho_ * (motor - data_.motor_position[k]));
    out->push_back(load - data_.load_position[k]);
  });
}

void ReplayWindows::simulate(const ServoParams& params, std::vector<double>* motor, std::vector<double>* load,
                             const std::vector<double>* corrections) const
{
  motor->assign(data_.time.size(), NAN);
  load->assign(data_.time.size(), NAN);
  for (std::size_t w = 0; w < starts_.size(); ++w)
  {
    replayWindow(params, w, corrections ? corrections->data() + CORRECTIONS * w : nullptr,
                 [&](std::size_t k, double m, double l) {
                   (*motor)[k] = m;
                   (*load)[k] = l;
                 });
  }
}

Estimate fitRestitution(const Recording& d, const IdentificationSettings& s, const InitialEstimates& e, double window,
                        int windows)
{
  const std::size_t n = d.time.size();
  requireThat(n >= 50 && d.load_position.size() == n && d.motor_position.size() == n && d.motor_torque.size() == n,
              "data", "needs at least 50 samples of equal columns");
  requireThat(window > 0.0 && windows > 0, "window", "must be > 0 s, with at least one window");
  const double h = (d.time.back() - d.time.front()) / static_cast<double>(n - 1), rho = s.gear_ratio;
  const double delta = e.backlash.value;
  // The initial estimates (static friction as the rests gave it, at least the Coulomb level).
  ServoParams base;
  base.gear_ratio = rho;
  ServoParams p = withEstimates(base, e.byKey());
  p.gain = replayGain(p);
  const std::size_t lead = 20, length = static_cast<std::size_t>(std::ceil(window / h));
  const std::vector<std::size_t> starts =
      ReplayWindows::beforeImpacts(d, rho, e.zero_offset, delta, length, lead, static_cast<std::size_t>(windows));
  requireThat(!starts.empty(), "data",
              "has no impact to fit the restitution on (the teeth never close across the free play)");
  const ReplayWindows replay(d, s, e.zero_offset, starts, length);
  std::vector<double> r;
  const auto cost = [&](double restitution) {
    ServoParams q = p;
    q.restitution = restitution;
    replay.residuals(q, &r, true);
    double sum = 0.0;
    for (double x : r)
    {
      sum += x * x;
    }
    return sum;
  };
  // Golden-section search on [0, 1].
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = 0.0, b = 1.0, c = b - golden * (b - a), dd = a + golden * (b - a);
  double fc = cost(c), fd = cost(dd);
  for (int i = 0; i < 40; ++i)
  {
    if (fc <= fd)
    {
      b = dd;
      dd = c;
      fd = fc;
      c = b - golden * (b - a);
      fc = cost(c);
    }
    else
    {
      a = c;
      c = dd;
      fc = fd;
      dd = a + golden * (b - a);
      fd = cost(dd);
    }
  }
  Estimate out;
  out.value = 0.5 * (a + b);
  // Standard error from the curvature (a central second difference over a small step) and the residual variance.
  const double step = std::min({0.01, out.value, 1.0 - out.value});
  const double f0 = cost(out.value);
  if (step > 1e-6)
  {
    const double curvature = (cost(out.value + step) - 2.0 * f0 + cost(out.value - step)) / (step * step);
    const double sigma2 = f0 / std::max(1.0, static_cast<double>(r.size()) - 1.0);
    out.standard_error = curvature > 0.0 ? std::sqrt(2.0 * sigma2 / curvature) : NAN;
  }
  else
  {
    out.standard_error = NAN;  // at a bound of [0, 1]
  }
  return out;
}
}  // namespace backlash_servo
