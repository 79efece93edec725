#include "identification/identify_mesh.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "backlash_servo/model/params.h"
#include "identification/least_squares.h"
#include "identification/rest_runs.h"

namespace backlash_servo
{
namespace
{
/// The body moves one way over the difference stencil of sample k (its filtered sign ±1 on k − 1 … k + 1, so the
/// raw sign held over the filter's support too) and faster than `still` [rad/s].
bool moving(const BodyMotion& b, std::size_t k, double still)
{
  const double s = b.sign[k];
  return std::fabs(s) == 1.0 && b.sign[k - 1] == s && b.sign[k + 1] == s && std::fabs(b.velocity[k]) > still;
}

double largestMagnitude(const std::vector<double>& v)
{
  double m = 0.0;
  for (double x : v)
  {
    m = std::max(m, std::fabs(x));
  }
  return m;
}

Eigen::Index rows(std::size_t n)
{
  return static_cast<Eigen::Index>(n);
}

}  // namespace

namespace
{
/// Both bodies' motion from the recording, and the speeds below which each stands [rad/s].
struct BothBodies
{
  double h = 0.0;          ///< sample period [s]
  std::size_t reach = 0;   ///< samples a phase must hold on each side (stencil and filter)
  BodyMotion motor, load;  ///< filtered angles and their differences
  double still_m = 0.0, still_c = 0.0;
};

/// The bodies where both move: ū = J_m α_m + f_m ω_m + T_cm sgn ω_m + ρ(J_L α_c + f_L ω_c + T_cL sgn ω_c − T_ext).
void compliantBodies(const Recording& d, const IdentificationSettings& s, const BothBodies& m, InitialEstimates* est)
{
  InitialEstimates& out = *est;
  const std::size_t n = d.time.size(), reach = m.reach;
  const double rho = s.gear_ratio;
  const BodyMotion &motor = m.motor, &load = m.load;
  const std::vector<double> ubar = meanTorque(d, s.smoothing);
  const double still_m = m.still_m, still_c = m.still_c;
  std::vector<std::size_t> both;
  bool forward = false, backward = false;
  for (std::size_t k = reach; k + reach < n; ++k)
  {
    if (moving(motor, k, still_m) && moving(load, k, still_c))
    {
      both.push_back(k);
      forward = forward || load.sign[k] > 0.0;
      backward = backward || load.sign[k] < 0.0;
    }
  }
  requireThat(both.size() >= 50, "data",
              "too few samples with both bodies moving (" + std::to_string(both.size()) +
                  "): the recording needs the motor to drive the load, and to cross the free play");
  const bool known_load = !(forward && backward) && std::isfinite(s.load_torque_fallback);
  requireThat(
      (forward && backward) || known_load, "data",
      "the load moved one way only: its Coulomb friction and the load torque cannot be told apart (the recording "
      "needs load motion in both directions, or give the load torque)");
  Eigen::MatrixXd xb(rows(both.size()), known_load ? 6 : 7);
  Eigen::VectorXd yb(rows(both.size()));
  for (std::size_t i = 0; i < both.size(); ++i)
  {
    const std::size_t k = both[i];
    xb.row(rows(i)).head(6) << motor.acceleration[k], motor.velocity[k], motor.sign[k], rho * load.acceleration[k],
        rho * load.velocity[k], rho * load.sign[k];
    if (!known_load)
    {
      xb(rows(i), 6) = -rho;
    }
    yb(rows(i)) = ubar[k] + (known_load ? rho * s.load_torque_fallback : 0.0);
  }
  std::size_t body_rows = 0;
  const LeastSquaresFit body = leastSquares(xb, yb, &body_rows);
  out.motor_inertia = {body.p(0), body.se(0)};
  out.motor_friction = {body.p(1), body.se(1)};
  out.motor_coulomb_friction = {body.p(2), body.se(2)};
  out.load_inertia = {body.p(3), body.se(3)};
  out.load_friction = {body.p(4), body.se(4)};
  out.load_coulomb_friction = {body.p(5), body.se(5)};
  out.load_torque = known_load ? Estimate{s.load_torque_fallback, NAN} : Estimate{body.p(6), body.se(6)};
  out.load_torque_given = known_load;
  out.apart_rms_residual = body.rms;
}

/// The mesh where the load moves: τ = J_L α_c + f_L ω_c + T_cL sgn ω_c − T_ext = −c g − d ġ + b (b per flank) →
/// stiffness, damping, the flanks (zero offset, backlash). Also fills `gap` and `rate` [rad, rad/s].
void compliantMesh(const IdentificationSettings& s, const BothBodies& m, std::vector<double>* gap_out,
                   std::vector<double>* rate_out, InitialEstimates* est)
{
  InitialEstimates& out = *est;
  const std::size_t n = m.motor.angle.size(), reach = m.reach;
  const double rho = s.gear_ratio, still_c = m.still_c, text = out.load_torque.value;
  const BodyMotion &motor = m.motor, &load = m.load;
  std::vector<double>&gap = *gap_out, &rate = *rate_out;
  gap.assign(n, 0.0);
  rate.assign(n, 0.0);
  std::vector<double> tau(n, NAN);
  std::vector<double> magnitudes;
  for (std::size_t k = 0; k < n; ++k)
  {
    gap[k] = load.angle[k] - rho * motor.angle[k];
    rate[k] = load.velocity[k] - rho * motor.velocity[k];
    if (k >= reach && k + reach < n && moving(load, k, still_c))
    {
      tau[k] = out.load_inertia.value * load.acceleration[k] + out.load_friction.value * load.velocity[k] +
               out.load_coulomb_friction.value * load.sign[k] - text;
      magnitudes.push_back(std::fabs(tau[k]));
    }
  }
  requireThat(!magnitudes.empty(), "data", "the load never moves");
  std::nth_element(magnitudes.begin(), magnitudes.begin() + static_cast<long>(0.99 * (magnitudes.size() - 1)),
                   magnitudes.end());
  const double threshold = 0.1 * magnitudes[static_cast<std::size_t>(0.99 * (magnitudes.size() - 1))];
  const auto side = [&](std::size_t k) { return tau[k] > threshold ? 1 : tau[k] < -threshold ? -1 : 0; };
  std::vector<std::size_t> pressed;
  std::size_t on_forward = 0, on_backward = 0, free_samples = 0;
  // A sample counts when its side holds over the filter's support and the stencil (reach samples each way): the
  // filtered law F τ = −c F g − d F ġ + b F[flank] holds there with F[flank] = 1.
  std::vector<std::size_t> changes(n + 1, 0);  // side changes before each sample (prefix count)
  for (std::size_t k = 1; k < n; ++k)
  {
    changes[k + 1] = changes[k] + (side(k) != side(k - 1) ? 1 : 0);
  }
  for (std::size_t k = 2 * reach; k + 2 * reach < n; ++k)
  {
    const int f = side(k);
    if (f != 0 && changes[k + reach + 1] == changes[k - reach + 1])
    {
      pressed.push_back(k);
      (f > 0 ? on_forward : on_backward) += 1;
    }
    else if (std::isfinite(tau[k]) && f == 0)
    {
      ++free_samples;
    }
  }
  requireThat(on_forward >= 20 && on_backward >= 20, "data",
              "the mesh was seen pressed on " +
                  std::string(on_forward >= 20    ? "the forward flank only"
                              : on_backward >= 20 ? "the backward flank only"
                                                  : "neither flank") +
                  ": the recording needs reversals that carry the motor across the free play to both flanks");
  Eigen::MatrixXd xm(rows(pressed.size()), 4);
  Eigen::VectorXd ym(rows(pressed.size()));
  for (std::size_t i = 0; i < pressed.size(); ++i)
  {
    const std::size_t k = pressed[i];
    const bool f = tau[k] > 0.0;
    xm.row(rows(i)) << -gap[k], -rate[k], f ? 1.0 : 0.0, f ? 0.0 : 1.0;
    ym(rows(i)) = tau[k];
  }
  std::size_t mesh_rows = 0;
  const LeastSquaresFit mesh = leastSquares(xm, ym, &mesh_rows);
  const double c = mesh.p(0), bf = mesh.p(2), bb = mesh.p(3);
  requireThat(c > 0.0, "data",
              "the mesh torque does not grow with the penetration (stiffness " + std::to_string(c) +
                  " N·m/rad): the samples do not resolve the contact — identify the joint as rigid teeth");
  out.mesh_stiffness = {c, mesh.se(0)};
  out.mesh_damping = {mesh.p(1), mesh.se(1)};
  const auto carried = [&](const Eigen::Vector4d& gradient) {
    return std::sqrt(std::max(0.0, gradient.dot(mesh.cov * gradient)));
  };
  out.zero_offset = bf / c;
  out.backlash = {(bb - bf) / c, carried(Eigen::Vector4d(-(bb - bf) / (c * c), 0.0, -1.0 / c, 1.0 / c))};
  requireThat(out.backlash.value > 0.0, "data",
              "the flanks come out crossed (backlash " + std::to_string(out.backlash.value) +
                  " rad): the samples do not resolve the contact — identify the joint as rigid teeth");
  out.contact_samples = mesh_rows;
  out.apart_samples = free_samples;
  out.contact_rms_residual = mesh.rms;
}

/// Static friction from each body's rests: the net torque on it, the mesh's from the gap by the law.
void compliantStatics(const Recording& d, const IdentificationSettings& s, const BothBodies& m,
                      const std::vector<double>& gap, const std::vector<double>& rate, InitialEstimates* est)
{
  InitialEstimates& out = *est;
  const std::size_t n = d.time.size(), r = static_cast<std::size_t>(s.smoothing), reach = m.reach;
  const double rho = s.gear_ratio;
  const BodyMotion &motor = m.motor, &load = m.load;
  const double h = m.h, text = out.load_torque.value, c = out.mesh_stiffness.value;
  const double g0 = out.zero_offset, delta = out.backlash.value, dm = out.mesh_damping.value;
  const auto meshTorque = [&](std::size_t k) {
    if (gap[k] < g0)
    {
      return std::max(0.0, c * (g0 - gap[k]) - dm * rate[k]);
    }
    if (gap[k] > g0 + delta)
    {
      return std::min(0.0, -c * (gap[k] - g0 - delta) - dm * rate[k]);
    }
    return 0.0;
  };
  const double band = s.contact_band > 0.0 ? s.contact_band : 1e-8 * delta;
  const std::size_t min_rest = minimumRest(s, h);
  // (Measured angles: the filter blurs the instant of a breakaway, the mesh's torque moves fast then — only the lower
  // bounds are kept.)
  const bool exact = !(s.contact_band > 0.0);
  const auto bounds = [&](const std::vector<double>& theta, auto net) {
    RestBounds b;
    const auto always = [](std::size_t, std::size_t) { return true; };
    forEachRest(theta, band, reach, n - reach - 1, min_rest, always, [&](std::size_t a, std::size_t e) {
      // Inside: the differences at the ends see the motion, and the filter spreads a breakaway over its support.
      for (std::size_t k = a + 1 + 2 * r; k + 2 + 4 * r < e; ++k)
      {
        b.low = std::max(b.low, net(k));
      }
      // The torque on it grows through the interval it broke away in (the mesh's share follows the other body), so
      // the net torque at the interval's end bounds T_s from above (the filter moves 2r samples early).
      const std::size_t away = e + 2 * r;
      if (exact && away + reach < n)
      {
        b.high = std::min(b.high, net(away));
      }
    });
    if (b.low >= 0.0 && b.low > b.high)
    {
      // Crossed by the change of the mesh's torque within the sample interval of a breakaway (it moves with the
      // other body): the level between them, their distance its scatter.
      return Estimate{0.5 * (b.low + b.high), (b.low - b.high) / std::sqrt(12.0)};
    }
    return b.level();
  };
  out.motor_static_friction =
      bounds(motor.angle, [&](std::size_t k) { return std::fabs(d.motor_torque[k] - rho * meshTorque(k)); });
  out.load_static_friction = bounds(load.angle, [&](std::size_t k) { return std::fabs(meshTorque(k) + text); });
}
}  // namespace

InitialEstimates estimateCompliantInitial(const Recording& d, const IdentificationSettings& s)
{
  BothBodies m;
  m.h = samplePeriod(d, s);
  m.reach = 2 + 2 * static_cast<std::size_t>(s.smoothing);
  m.motor = differentiate(d.motor_position, m.h, s.smoothing);
  m.load = differentiate(d.load_position, m.h, s.smoothing);
  m.still_m = s.still_speed > 0.0 ? s.still_speed : 1e-6 * largestMagnitude(m.motor.velocity);
  m.still_c = s.still_speed > 0.0 ? s.still_speed : 1e-6 * largestMagnitude(m.load.velocity);
  InitialEstimates out;
  compliantBodies(d, s, m, &out);
  std::vector<double> gap, rate;
  compliantMesh(s, m, &gap, &rate, &out);
  compliantStatics(d, s, m, gap, rate, &out);
  return out;
}

}  // namespace backlash_servo
