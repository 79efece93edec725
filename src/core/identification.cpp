#include "backlash_servo/identification.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <variant>

#include "backlash_servo/param_table.h"
#include "backlash_servo/params.h"
#include "backlash_servo/replay_windows.h"
#include "least_squares.h"
#include "rest_runs.h"

namespace backlash_servo
{
namespace
{
/// Samples on each side of a sample whose gap must stay in its phase (the difference stencil, and one more).
constexpr int STENCIL = 2;

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

void need(bool ok, const std::string& key, const std::string& what)
{
  if (!ok)
  {
    throw InvalidParameterError(key, what);
  }
}

}  // namespace

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
  need(n >= 50, "data", "needs at least 50 samples (got " + std::to_string(n) + ")");
  need(d.motor_torque.size() == n && d.motor_position.size() == n && d.load_position.size() == n, "data",
       "the columns time, motor_torque, motor_position and load_position must have equal lengths");
  need(std::isfinite(s.gear_ratio) && s.gear_ratio > 0.0, "gear_ratio", "must be known and > 0 (give it in the prior)");
  const double h = (d.time.back() - d.time.front()) / static_cast<double>(n - 1);
  need(h > 0.0 && std::isfinite(h), "time", "must increase");
  for (std::size_t k = 0; k < n; ++k)
  {
    need(std::isfinite(d.time[k]) && std::isfinite(d.motor_torque[k]) && std::isfinite(d.motor_position[k]) &&
             std::isfinite(d.load_position[k]),
         "data", "row " + std::to_string(k + 1) + " has a value that is not a finite number");
    if (k > 0)
    {
      need(std::fabs(d.time[k] - d.time[k - 1] - h) <= 1e-6 * h, "time",
           "samples must be uniform in time (row " + std::to_string(k + 1) + " is " +
               std::to_string(d.time[k] - d.time[k - 1]) + " s after the one before, the mean step is " +
               std::to_string(h) + " s)");
    }
  }
  need(s.smoothing >= 0 && s.smoothing <= 100000, "smoothing", "must be in [0, 100000] samples");
  need(n > 8 * static_cast<std::size_t>(s.smoothing) + 50, "smoothing",
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

InitialEstimates estimateInitial(const Recording& d, const IdentificationSettings& s)
{
  const std::size_t n = d.time.size();
  const double h = samplePeriod(d, s);
  const double rho = s.gear_ratio;
  std::vector<double> gap(n);
  for (std::size_t k = 0; k < n; ++k)
  {
    gap[k] = d.load_position[k] - rho * d.motor_position[k];
  }
  InitialEstimates out;
  const auto [lo, hi] = std::minmax_element(gap.begin(), gap.end());
  const double backlash = *hi - *lo;
  out.zero_offset = *lo;
  const double band = s.contact_band > 0.0 ? s.contact_band : 1e-8 * backlash;
  // Apart means clear of both flanks: a chatter of short flights (a few µrad) between samples is neither phase.
  const double margin = std::max(1e-3 * backlash, 4.0 * band);
  need(backlash > 4.0 * std::max(band, 1e-3 * backlash) && backlash > 0.0, "data",
       "the gap θ_c − ρθ_m never spans the backlash: the recording needs reversals that carry the motor across the "
       "free play to both flanks");
  // Derivatives, and each sample's phase (0 apart, +1 forward flank, −1 backward flank, 2 mixed).
  // Every term of the equations filtered by the same F (differences commute with it): D²(Fθ) = F(D²θ) against Fū
  // and F sgn ω — quantisation and noise averaged out, the equations unchanged.
  const std::size_t r = static_cast<std::size_t>(s.smoothing);
  const BodyMotion motor = differentiate(d.motor_position, h, s.smoothing);
  const std::vector<double>&theta = motor.angle, &wm = motor.velocity, &am = motor.acceleration, &sg = motor.sign;
  const std::vector<double> ubar = meanTorque(d, s.smoothing);
  double fastest = 0.0;
  for (double w : wm)
  {
    fastest = std::max(fastest, std::fabs(w));
  }
  const double still = s.still_speed > 0.0 ? s.still_speed : 1e-6 * fastest;
  std::vector<int> phase(n);
  for (std::size_t k = 0; k < n; ++k)
  {
    const double df = gap[k] - *lo, db = *hi - gap[k];
    phase[k] = df <= band ? 1 : db <= band ? -1 : (df > margin && db > margin) ? 0 : 2;
  }
  // A sample's phase must hold over the filter's support and the difference stencil.
  const std::size_t reach = STENCIL + 2 * r;
  std::vector<std::size_t> changes(n + 1, 0);  // phase changes before each sample (prefix count)
  for (std::size_t k = 1; k < n; ++k)
  {
    changes[k + 1] = changes[k] + (phase[k] != phase[k - 1] ? 1 : 0);
  }
  std::vector<std::size_t> contact, apart;
  for (std::size_t k = reach; k + reach < n; ++k)
  {
    const bool same = changes[k + reach + 1] == changes[k - reach + 1];
    if (!same || phase[k] == 2 || std::fabs(wm[k]) <= still)
    {
      continue;
    }
    (phase[k] == 0 ? apart : contact).push_back(k);
  }
  out.contact_samples = contact.size();
  out.apart_samples = apart.size();
  if (contact.size() < 20)
  {
    // The gap near the flanks but never held within the band: teeth that give (or angles coarser than the band).
    std::size_t near = 0;
    for (std::size_t k = 0; k < n; ++k)
    {
      near += std::min(gap[k] - *lo, *hi - gap[k]) <= 0.05 * backlash ? 1 : 0;
    }
    need(near < n / 10, "data",
         "the gap θ_c − ρθ_m keeps moving near the flanks while the motor drives the load (never within the contact "
         "band of " +
             formatNumber(band) +
             " rad): the mesh looks compliant — give a prior with mesh_stiffness > 0 (a guess) to identify a "
             "compliant mesh — or, for measured angles, a contact band of their resolution");
  }
  need(contact.size() >= 20, "data",
       "too few samples with the teeth in contact and moving (" + std::to_string(contact.size()) +
           "): the recording needs motion while the motor drives the load");
  need(apart.size() >= 20, "data",
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
  need(both_ways || known_load, "data",
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
  out.contact_samples = contact_kept;
  out.apart_samples = apart_kept;
  const auto combined = [](double x, double y) { return std::sqrt(x * x + y * y); };
  // The backlash between the flanks' typical gaps (medians over the samples in contact on each: quantisation and
  // noise at the extremes do not widen it); the zero offset likewise.
  std::vector<double> on_forward, on_backward;
  for (std::size_t k = 0; k < n; ++k)
  {
    if (phase[k] == 1)
    {
      on_forward.push_back(gap[k]);
    }
    else if (phase[k] == -1)
    {
      on_backward.push_back(gap[k]);
    }
  }
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  if (!on_forward.empty() && !on_backward.empty())
  {
    out.zero_offset = median(on_forward);
    out.backlash = {median(on_backward) - out.zero_offset, band};
  }
  else
  {
    out.backlash = {backlash, band};
  }
  out.motor_inertia = {a.p(0), a.se(0)};
  out.motor_friction = {a.p(1), a.se(1)};
  out.motor_coulomb_friction = {a.p(2), a.se(2)};
  out.load_inertia = {(c.p(0) - a.p(0)) / (rho * rho), combined(c.se(0), a.se(0)) / (rho * rho)};
  out.load_friction = {(c.p(1) - a.p(1)) / (rho * rho), combined(c.se(1), a.se(1)) / (rho * rho)};
  out.load_coulomb_friction = {(c.p(2) - a.p(2)) / rho, combined(c.se(2), a.se(2)) / rho};
  out.load_torque = known_load ? Estimate{s.load_torque_fallback, NAN} : Estimate{-c.p(3) / rho, c.se(3) / rho};
  out.load_torque_given = known_load;
  out.contact_rms_residual = c.rms;
  out.apart_rms_residual = a.rms;
  // Static friction from the rests: over a sample interval [t_k, t_k+1) the torque u_k is held, so a body at rest
  // over it was held by its static band (|net| ≤ T_s: a lower bound) and the interval where it broke away had
  // |net| > T_s (an upper bound). Teeth apart: the motor alone, net u_k; teeth on a flank: the pair, net u_k + ρT_ext
  // against T_sm + ρT_sL. A rest is a run of at least minimumRest() samples, in one phase, over which the
  // (filtered) motor angle stays within the contact band: a velocity reversal passes through slow motion too, but
  // leaves the band (½α t² grows). The filter F starts moving 2r samples before the body does, so the
  // breakaway interval is the one after the run's last sample, plus 2r.
  const std::size_t min_rest = minimumRest(s, h);
  RestBounds motor_alone, pair;
  const double text = out.load_torque.value;
  const auto net = [&](std::size_t k, int in) { return std::fabs(d.motor_torque[k] + (in == 0 ? 0.0 : rho * text)); };
  // (A run in one phase, never the mixed one.)
  const auto together = [&phase](std::size_t a, std::size_t k) { return phase[a] != 2 && phase[k] == phase[a]; };
  forEachRest(theta, band, reach, n - reach - 1, min_rest, together, [&](std::size_t a, std::size_t b) {
    RestBounds& bound = phase[a] == 0 ? motor_alone : pair;
    for (std::size_t k = a; k + 1 < b; ++k)  // the intervals inside the run
    {
      bound.low = std::max(bound.low, net(k, phase[a]));
    }
    // The interval from the run's last sample broke it away (on a flank the pair must still be there after it: a
    // motor breaking away from the load alone has a lower threshold).
    const std::size_t away = b - 1 + 2 * r;
    if (away + reach + 1 < n && phase[b] == phase[a] && phase[away] == phase[a] && phase[away + 1] == phase[a])
    {
      bound.high = std::min(bound.high, net(away, phase[a]));
    }
  });
  out.motor_static_friction = motor_alone.level();
  const Estimate combined_static = pair.level();
  if (std::isfinite(out.motor_static_friction.value) && std::isfinite(combined_static.value))
  {
    out.load_static_friction = {
        (combined_static.value - out.motor_static_friction.value) / rho,
        combined(combined_static.standard_error, out.motor_static_friction.standard_error) / rho};
  }
  return out;
}

std::vector<ProfileSegment> identificationExperiment(const ServoParams& params, double duration, double travel,
                                                     double dither_amplitude, double dither_frequency)
{
  need(std::isfinite(dither_amplitude) && dither_amplitude >= 0.0, "dither", "the amplitude must be >= 0 rad");
  need(dither_amplitude == 0.0 || (std::isfinite(dither_frequency) && dither_frequency > 0.0), "dither",
       "the frequency must be > 0 Hz");
  need(std::isfinite(duration) && duration > 0.0, "duration", "must be > 0 s");
  need(std::isfinite(travel) && travel >= 3.0 * params.backlash && travel > 0.0, "travel",
       "must be at least three times the backlash (" + std::to_string(3.0 * params.backlash) +
           " rad): every reversal must carry the motor across the free play");
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

Estimate fitRestitution(const Recording& d, const IdentificationSettings& s, const InitialEstimates& e, double window,
                        int windows)
{
  const std::size_t n = d.time.size();
  need(n >= 50 && d.load_position.size() == n && d.motor_position.size() == n && d.motor_torque.size() == n, "data",
       "needs at least 50 samples of equal columns");
  need(window > 0.0 && windows > 0, "window", "must be > 0 s, with at least one window");
  const double h = (d.time.back() - d.time.front()) / static_cast<double>(n - 1), rho = s.gear_ratio;
  const double delta = e.backlash.value;
  // The initial estimates (static friction as the rests gave it, at least the Coulomb level).
  ServoParams base;
  base.gear_ratio = rho;
  const ServoParams p = withEstimates(base, e.byKey());
  const std::size_t lead = 20, length = static_cast<std::size_t>(std::ceil(window / h));
  const std::vector<std::size_t> starts =
      ReplayWindows::beforeImpacts(d, rho, e.zero_offset, delta, length, lead, static_cast<std::size_t>(windows));
  need(!starts.empty(), "data", "has no impact to fit the restitution on (the teeth never close across the free play)");
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
