// Linear modes of any order (linear_mode.h) against independent truth: the second-order step response in closed
// form, a two-mass drive (momentum, energy, its antiresonance), crossings of a two-frequency signal against a dense
// scan of its closed form, grazing, and Modelica's Rotational.Examples.Backlash events (an inertia bouncing between
// the flanks of a compliant backlash: ElastoBacklash2's Kelvin–Voigt contact that never pulls, ElastoBacklash's).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "numerics/gauss_legendre.h"
#include "numerics/linear_mode.h"

namespace
{
using backlash_servo::LinearMode;
using Eigen::MatrixXd;
using Eigen::VectorXd;
constexpr double INF = std::numeric_limits<double>::infinity();

VectorXd vec(std::initializer_list<double> v)
{
  VectorXd x(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double d : v)
  {
    x(i++) = d;
  }
  return x;
}

// ẍ = −2ζẋ − (x − 1) from rest: x = 1 − e^{−ζt}(cos ω_d t + ζ/ω_d sin ω_d t) — the thesis' rigid contact mode.
TEST(LinearMode, TheSecondOrderStepIsItsClosedForm)
{
  const double zeta = 0.4, wd = std::sqrt(1.0 - zeta * zeta);
  MatrixXd a(2, 2);
  a << 0.0, 1.0, -1.0, -2.0 * zeta;
  const LinearMode m(a, vec({0.0, 1.0}), vec({0.0, 0.0}));
  EXPECT_TRUE(m.modal());
  for (double t : {0.1, 1.0, 3.3, 10.0, 40.0})
  {
    const double x = 1.0 - std::exp(-zeta * t) * (std::cos(wd * t) + zeta / wd * std::sin(wd * t));
    const double v = std::exp(-zeta * t) * (1.0 + zeta * zeta / (wd * wd)) * wd * std::sin(wd * t);
    EXPECT_NEAR(m.state(t)(0), x, 1e-14) << t;
    EXPECT_NEAR(m.state(t)(1), v, 1e-14) << t;
  }
  // The first maximum (velocity from + to −) at π/ω_d, to the last bits.
  EXPECT_NEAR(m.firstCrossing(vec({0.0, 1.0}), 0.0, -1, 10.0), M_PI / wd, 1e-14 * M_PI / wd);
}

// Two inertias joined by a spring c, nothing else (a free–free two-mass drive, A defective: the oscillation plus a
// polynomial part of order 2 for the common drift): the
// relative angle rings at ω² = c(1/J₁ + 1/J₂) as r₀ cos ωt, momentum is zero and the energy constant.
TEST(LinearMode, ATwoMassDriveRingsAtItsAntiresonance)
{
  const double j1 = 0.2, j2 = 1.5, c = 3.0e4, r0 = 1e-3;
  MatrixXd a = MatrixXd::Zero(4, 4);  // (θ₁, ω₁, θ₂, ω₂)
  a(0, 1) = 1.0;
  a(2, 3) = 1.0;
  a(1, 0) = -c / j1;
  a(1, 2) = c / j1;
  a(3, 0) = c / j2;
  a(3, 2) = -c / j2;
  const LinearMode m(a, VectorXd::Zero(4), vec({r0, 0.0, 0.0, 0.0}));
  EXPECT_TRUE(m.modal());
  EXPECT_EQ(m.polynomialOrder(), 2);
  const double w = std::sqrt(c * (1.0 / j1 + 1.0 / j2));
  const double e0 = 0.5 * c * r0 * r0;
  for (double t : {1e-4, 3e-3, 0.05, 1.0})
  {
    const VectorXd x = m.state(t);
    EXPECT_NEAR(x(0) - x(2), r0 * std::cos(w * t), 1e-10 * r0) << t;
    EXPECT_NEAR(j1 * x(1) + j2 * x(3), 0.0, 1e-12 * j1 * r0 * w) << t;
    const double e = 0.5 * j1 * x(1) * x(1) + 0.5 * j2 * x(3) * x(3) + 0.5 * c * (x(0) - x(2)) * (x(0) - x(2));
    EXPECT_NEAR(e, e0, 1e-10 * e0) << t;
  }
  const VectorXd rel = vec({1.0, 0.0, -1.0, 0.0});
  EXPECT_NEAR(m.firstCrossing(rel, 0.0, -1, 1.0), 0.5 * M_PI / w, 1e-13);
  EXPECT_NEAR(m.firstCrossing(rel, 0.0, +1, 1.0), 1.5 * M_PI / w, 1e-13);
}

// A body without friction under a constant torque (A = [[0, 1], [0, 0]], a Jordan block: no eigenbasis, A nilpotent
// as a whole) is its parabola θ₀ + ω₀τ + ½ατ² — the polynomial part alone — at any τ, and it reaches a level at the
// root of that quadratic.
TEST(LinearMode, ADefectiveModeIsItsPolynomial)
{
  MatrixXd a(2, 2);
  a << 0.0, 1.0, 0.0, 0.0;
  const double th0 = 0.3, w0 = -2.0, alpha = 0.01;
  const LinearMode m(a, vec({0.0, alpha}), vec({th0, w0}));
  EXPECT_TRUE(m.modal());
  EXPECT_EQ(m.polynomialOrder(), 2);
  for (double t : {1e-3, 0.7, 12.5, 399.0, 1000.0, 3.3e4, 1e5})
  {
    const double th = th0 + w0 * t + 0.5 * alpha * t * t;
    EXPECT_NEAR(m.state(t)(0), th, 1e-14 * (std::fabs(th) + std::fabs(w0 * t) + 1.0)) << t;
    EXPECT_NEAR(m.state(t)(1), w0 + alpha * t, 1e-14 * (std::fabs(w0) + alpha * t)) << t;
  }
  // θ = 50 upward: ½ατ² + ω₀τ + θ₀ − 50 = 0, the larger root.
  const double c = th0 - 50.0, root = (-w0 + std::sqrt(w0 * w0 - 2.0 * alpha * c)) / alpha;
  EXPECT_NEAR(m.firstCrossing(vec({1.0, 0.0}), -50.0, +1, 1e4), root, 1e-12 * root);
}

// A defective eigenvalue that is not zero (a critically damped pair under a constant force, A = [[0, 1], [−ω², −2ω]])
// has no modal form: its Taylor series from anchors, against x_∞ + (d₀ + (v₀ + ωd₀)τ)e^{−ωτ} (d₀ = x₀ − x_∞), over
// a thousand time scales and far beyond (8e4 anchors: past those all kept) and back — the same bits asked again after
// going back, a pure function of τ — and its crossing of a level against a dense scan of that closed form.
TEST(LinearMode, ACriticallyDampedModeIsItsTaylorSeries)
{
  const double w = 2.0, f = 3.0, x0 = 0.4, v0 = 5.0;
  MatrixXd a(2, 2);
  a << 0.0, 1.0, -w * w, -2.0 * w;
  const LinearMode m(a, vec({0.0, f}), vec({x0, v0}));
  EXPECT_FALSE(m.modal());
  const double xinf = f / (w * w), d0 = x0 - xinf;
  const auto exact = [&](double t) { return xinf + (d0 + (v0 + w * d0) * t) * std::exp(-w * t); };
  for (double t : {1e-3, 0.7, 3.0, 12.5, 399.0})
  {
    EXPECT_NEAR(m.state(t)(0), exact(t), 1e-13) << t;
  }
  const VectorXd far = m.state(2e4);
  for (double t : {1.2e4 + 0.3, 2e4, 8e3, 1.8e4 + 0.1})
  {
    EXPECT_NEAR(m.state(t)(0), xinf, 1e-13) << t;
  }
  EXPECT_EQ(m.state(2e4), far);
  // x rises from 0.4 over its peak and falls back through 1.0 once: the falling crossing.
  double lo = 0.0, hi = 0.0;
  for (double t = 1e-4;; t += 1e-4)
  {
    if (exact(t - 1e-4) >= 1.0 && exact(t) < 1.0)
    {
      lo = t - 1e-4;
      hi = t;
      break;
    }
  }
  for (int i = 0; i < 60; ++i)
  {
    const double mid = 0.5 * (lo + hi);
    (exact(mid) >= 1.0 ? lo : hi) = mid;
  }
  EXPECT_NEAR(m.firstCrossing(vec({1.0, 0.0}), -1.0, -1, 100.0), hi, 1e-12);
}

// The free mode of a joint under the continuous law: the motor driven by the free load's position
// (J_m ω̇_m = a − kθ_c − f_m ω_m, J_L ω̇_c = −f_L ω_c; two zero eigenvalues, one eigenvector: no eigenbasis, the modal
// form with a polynomial part) against RK4 on the same equations with a step of 1e-4 s.
TEST(LinearMode, TheDriveLawsFreeModeAgainstRK4)
{
  const double jm = 0.1, jl = 0.9, fm = 0.48, fl = 0.32, k = 1.0, off = 1.0;
  MatrixXd a = MatrixXd::Zero(4, 4);  // (θ_m, ω_m, θ_c, ω_c)
  a(0, 1) = 1.0;
  a(1, 1) = -fm / jm;
  a(1, 2) = -k / jm;
  a(2, 3) = 1.0;
  a(3, 3) = -fl / jl;
  const VectorXd u = vec({0.0, off / jm, 0.0, 0.0});
  const VectorXd x0 = vec({0.2, -0.5, 0.1, 1.5});
  const LinearMode m(a, u, x0);
  EXPECT_TRUE(m.modal());
  EXPECT_EQ(m.polynomialOrder(), 2);
  VectorXd x = x0;
  const double h = 1e-4;
  long step = 0;
  for (double t : {0.5, 2.0, 7.0})
  {
    for (; step * h < t - h / 2; ++step)
    {
      const VectorXd k1 = a * x + u, k2 = a * (x + 0.5 * h * k1) + u, k3 = a * (x + 0.5 * h * k2) + u,
                     k4 = a * (x + h * k3) + u;
      x += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    EXPECT_LT((m.state(t) - x).norm(), 1e-11) << t;
  }
}

// A zero eigenvalue beside one that is merely small: a motor pressing a gear through a spring–damper mesh, the gear
// driving a load through a soft shaft, each body with a viscous friction, under a constant motor torque — referred
// to the output shaft. The common drift decays at (f_m + f_L)/(J_m + J_g + J_L), far below the mesh's frequency: a
// near-Jordan pair that no eigenbasis resolves, and not exactly nilpotent either.
struct DriftingDrive
{
  double jm, jg, jl;  // [kg·m²]; jg = 0: no shaft, the mesh drives the load itself
  double c, d;        // mesh [N·m/rad], [N·m·s/rad]
  double ks, ds;      // shaft [N·m/rad], [N·m·s/rad]
  double fm, fl;      // viscous friction [N·m·s/rad]
  double torque;      // on the motor [N·m]
};

// Its motion against the same equations stepped by exp(Ah) in long double (h = 0.01 s)
// over the longest motion a compliant joint evaluates (4096 fast time scales), and the motor's angle against the
// integral of its speed (8-point Gauss–Legendre on pieces of 0.05 s) over the last second. The closed form must be
// modal (the Taylor series' bounds make the event search crawl along an output near zero).
void expectTheDriftExact(const DriftingDrive& p, const VectorXd& x0)
{
  // (θ_m, ω_m, θ_g, ω_g, θ_L, ω_L), or (θ_m, ω_m, θ_L, ω_L) without a shaft; Q = c(θ_m − θ_g) + d(ω_m − ω_g) on the
  // gear.
  const bool shaft = p.jg > 0.0;
  const Eigen::Index n = shaft ? 6 : 4;
  const std::vector<double> inertia = shaft ? std::vector<double>{p.jm, p.jg, p.jl} : std::vector<double>{p.jm, p.jl};
  MatrixXd a = MatrixXd::Zero(n, n);
  for (Eigen::Index b = 0; b < n / 2; ++b)
  {
    a(2 * b, 2 * b + 1) = 1.0;
  }
  const auto couple = [&](Eigen::Index i, Eigen::Index j, double k, double damping) {  // a spring–damper i ↔ j
    for (const auto& [self, other] : {std::pair{i, j}, std::pair{j, i}})
    {
      const double inv = 1.0 / inertia[static_cast<std::size_t>(self)];
      a(2 * self + 1, 2 * self) -= k * inv;
      a(2 * self + 1, 2 * other) += k * inv;
      a(2 * self + 1, 2 * self + 1) -= damping * inv;
      a(2 * self + 1, 2 * other + 1) += damping * inv;
    }
  };
  couple(0, 1, p.c, p.d);
  if (shaft)
  {
    couple(1, 2, p.ks, p.ds);
  }
  a(1, 1) -= p.fm / p.jm;
  a(n - 1, n - 1) -= p.fl / p.jl;
  VectorXd u = VectorXd::Zero(n);
  u(1) = p.torque / p.jm;
  const LinearMode m(a, u, x0);
  EXPECT_TRUE(m.modal());
  const double h = 0.01;
  using MatrixL = Eigen::Matrix<long double, Eigen::Dynamic, Eigen::Dynamic>;
  using VectorL = Eigen::Matrix<long double, Eigen::Dynamic, 1>;
  const MatrixL al = a.cast<long double>();
  // e^{Ah} and ∫₀ʰ e^{As} ds by scaling and squaring: the series on h/2^k (‖A‖₁ h/2^k ≤ ½), then doubled k times
  // (∫₀^{2τ} = ∫₀^τ + e^{Aτ} ∫₀^τ).
  int halvings = 0;
  long double tau = h;
  while (al.cwiseAbs().colwise().sum().maxCoeff() * tau > 0.5L)
  {
    tau /= 2.0L;
    ++halvings;
  }
  MatrixL phi = MatrixL::Zero(n, n), term = MatrixL::Identity(n, n) * tau;
  for (int k = 1; k < 40; ++k)
  {
    phi += term;
    term = (al * term * tau / static_cast<long double>(k + 1)).eval();
  }
  MatrixL step = MatrixL::Identity(n, n) + al * phi;
  for (int k = 0; k < halvings; ++k)
  {
    phi = (phi + step * phi).eval();
    step = (step * step).eval();
  }
  const VectorL ul = u.cast<long double>(), drive = phi * ul;
  VectorL x = x0.cast<long double>();
  const double span = 4096.0 / m.norm();
  std::vector<double> times = {1.0, 10.0, 0.25 * span, span};
  std::sort(times.begin(), times.end());
  times.erase(std::upper_bound(times.begin(), times.end(), span), times.end());
  long steps = 0;
  for (double t : times)
  {
    for (; static_cast<double>(steps) * h < t - h / 2; ++steps)
    {
      x = step * x + drive;
    }
    const double t_k = static_cast<double>(steps) * h;
    const VectorXd got = m.state(t_k), want = x.cast<double>();
    // (Relative to how far each angle moved and to the speeds: the modal form's rounding, amplified by its basis'
    // condition; a drift resolved to 1e-7 only — the slow eigenvalue's neighbour taken as nilpotent — is far beyond.)
    for (Eigen::Index i = 0; i < n; i += 2)
    {
      EXPECT_LT(std::fabs(got(i) - want(i)), 1e-11 * std::fabs(want(i) - x0(i))) << t_k << " angle " << i;
      EXPECT_LT(std::fabs(got(i + 1) - want(i + 1)), 1e-11 * (std::fabs(want(i + 1)) + std::fabs(x0(i + 1))))
          << t_k << " speed " << i + 1;
    }
  }
  double integral = 0.0;
  const double t0 = span - 1.0, piece = 0.05;
  for (int p = 0; p < 20; ++p)
  {
    const double mid = t0 + (p + 0.5) * piece;
    for (int i = 0; i < 8; ++i)
    {
      integral +=
          0.5 * piece * backlash_servo::GAUSS_WEIGHT[i] * m.state(mid + 0.5 * piece * backlash_servo::GAUSS_NODE[i])(1);
    }
  }
  const double moved = m.state(t0 + 1.0)(0) - m.state(t0)(0);
  EXPECT_NEAR(integral, moved, 1e-11 * std::fabs(moved));  // (the speeds' tolerance above)
}

// A small robot axis: the motor's viscous friction 1e-6 of the mesh's frequency (the drift decays at ~1e-9 of it).
TEST(LinearMode, ASlowDriftBesideAZeroEigenvalueIsExact)
{
  expectTheDriftExact({1.06e-5, 4.1e-5, 1.19e-3, 3.7e-4, 8.5e-5, 2.3e-8, 0.0, 1.14e-11, 0.0, -3.3e-8},
                      vec({1.25, -0.03, 1.2, -0.03, 1.2, -0.03}));
}

// Teeth without damping on a soft, damped shaft, both bodies with friction (the drift decays at 4e-7 /s, 2e-10 of the
// mesh's frequency, and couples to the mesh's subspace at 3e-10 of it): still split and decoupled, not the Taylor
// series.
TEST(LinearMode, ADriftCoupledMoreStronglyIsStillSplit)
{
  expectTheDriftExact({0.34103, 3.01524e-3, 0.130146, 6017.42, 0.0, 0.0158218, 9.77157e-4, 1.2206e-7, 7.4989e-8, -3e-9},
                      vec({4.3167e-3, 1.3075e-4, 4.3167e-3, 1.3075e-4, 4.3167e-3, 1.3075e-4}));
}

// A light load on a soft, damped mesh behind a heavy motor, no shaft (the drift decays at 4e-6 /s, 3e-8 of ‖Â‖): at
// Â² that slow end of the chain is a singular value of 3e-8, not a structural zero — still found as a chain (and the
// shaft's slow mode above, whose singular value falls below the same threshold at Â², left out of it).
TEST(LinearMode, AChainWhoseEndIsSlowIsStillFound)
{
  expectTheDriftExact({2.926024546325764e-3, 0.0, 3.3781248853507316e-6, 0.037587042634201297, 2.0241109198193543e-5,
                       0.0, 0.0, 3.0560250989676897e-9, 8.7999262495915381e-9, 1e-9},
                      vec({0.54141551728706727, 3.3057965451995961e-3, 0.5412, 3.3e-3}));
}

// Slow modes that are not a chain of the zero eigenvalue: a motor under the P law reading a load that floats in the
// free play behind a stiff torsional shaft (the load's viscous friction decays its drift at −0.0217 /s, the motor's
// at −0.136 /s, the shaft rings at 2590 rad/s). The powers of Â drop those slow modes below the rank threshold by
// Â³, but Â does not map them into ker Â² as it maps a chain: they are not nilpotent, and the motion they carry
// is not a polynomial. Against RK4 in long double over 0.09 s (2e5 steps, converged to 1e-19 rad).
TEST(LinearMode, ASlowModeIsNotTakenForAChainOfTheZeroEigenvalue)
{
  const double jm = 3.580572550076141e-4, fm = 4.8599267706510226e-5, k = 5.3464817752078402e-5;
  const double jg = 3.5371609623569014e-10, jl = 1.7243244236782205e-9, fl = 4.5190447082065772e-11;
  const double ks = 1.9682913649031685e-3, ds = 2.4085390845573488e-9, command = 1.1085239592396035e-3;
  MatrixXd a = MatrixXd::Zero(6, 6);  // (θ_m, ω_m, θ_g, ω_g, θ_L, ω_L), T_m = K(θ_R − θ_L)
  a(0, 1) = a(2, 3) = a(4, 5) = 1.0;
  a(1, 1) = -fm / jm;
  a(1, 4) = -k / jm;
  a(3, 2) = -ks / jg;
  a(3, 3) = -ds / jg;
  a(3, 4) = ks / jg;
  a(3, 5) = ds / jg;
  a(5, 2) = ks / jl;
  a(5, 3) = ds / jl;
  a(5, 4) = -ks / jl;
  a(5, 5) = -(ds + fl) / jl;
  const VectorXd u = vec({0.0, k * command / jm, 0.0, 0.0, 0.0, 0.0});
  const VectorXd x0 = vec({7.2e-6, 5.4e-5, 1.1e-3, 0.0323, 1.1e-3, 0.0323});
  const LinearMode m(a, u, x0);
  using VectorL = Eigen::Matrix<long double, 6, 1>;
  const Eigen::Matrix<long double, 6, 6> al = a.cast<long double>();
  const VectorL ul = u.cast<long double>();
  VectorL x = x0.cast<long double>();
  const int steps = 200000;
  const long double h = 0.09L / steps;
  for (int i = 0; i < steps; ++i)
  {
    const VectorL k1 = al * x + ul, k2 = al * (x + 0.5L * h * k1) + ul, k3 = al * (x + 0.5L * h * k2) + ul,
                  k4 = al * (x + h * k3) + ul;
    x += h / 6.0L * (k1 + 2.0L * k2 + 2.0L * k3 + k4);
  }
  const VectorXd got = m.state(0.09), want = x.cast<double>();
  for (int i : {0, 2, 4})
  {
    // (Relative to how far each angle moved; the motor's was cut off at 7e-7 of it.)
    EXPECT_LT(std::fabs(got(i) - want(i)), 1e-11 * std::fabs(want(i) - x0(i))) << "angle " << i;
    EXPECT_LT(std::fabs(got(i + 1) - want(i + 1)), 1e-11 * std::fabs(want(i + 1))) << "speed " << i + 1;
  }
}

// A mesh's torque at large angles: a motor and a gear (ρ = 3) 9e4 rad from where they started, pressed 1e-6 rad
// into each other, the torque c(ρθ_m − θ_o) a difference of terms 1e11 times larger. The motion's start rate is
// A x₀ + u of its own matrix to rounding of the result — against the same sums in quadruple precision, where the
// products of doubles are exact — read from the speeds a moment (1e-10 s, 1e-7 of a mesh period) after a start at
// rest. (Summed plainly, the rate kept 5 digits.)
TEST(LinearMode, AMeshsTorqueAtLargeAnglesKeepsItsDigits)
{
  const double rho = 3.0, jm = 0.7, jo = 1.9, c = 2e5, theta_m = 30000.123456789;
  const double theta_o = rho * theta_m - 1e-6;
  MatrixXd a = MatrixXd::Zero(4, 4);  // (θ_m, ω_m, θ_o, ω_o); Q = c(ρθ_m − θ_o) on the gear, −ρQ on the motor
  a(0, 1) = a(2, 3) = 1.0;
  a(1, 0) = -rho * rho * c / jm;
  a(1, 2) = rho * c / jm;
  a(3, 0) = rho * c / jo;
  a(3, 2) = -c / jo;
  const VectorXd u = vec({0.0, 0.25 / jm, 0.0, 0.0}), x0 = vec({theta_m, 0.0, theta_o, 0.0});
  const LinearMode m(a, u, x0);
  const double tau = 1e-10;
  const VectorXd x = m.state(tau);
  for (int i : {1, 3})
  {
    const __float128 exact = static_cast<__float128>(a(i, 0)) * static_cast<__float128>(x0(0)) +
                             static_cast<__float128>(a(i, 2)) * static_cast<__float128>(x0(2)) +
                             static_cast<__float128>(u(i));
    const double rate = static_cast<double>(exact);
    EXPECT_NEAR(x(i) / tau, rate, 1e-10 * std::fabs(rate)) << i;
  }
}

// Two independent damped oscillators, 1 rad/s and 37 rad/s, and s = x₁ + 0.3 x₃ − 0.05: the crossings in both
// directions, found one after the other from each crossing's state, against a dense scan of the closed form written
// here (sign changes every 1e-5 s, refined by bisection). Then a grazing: s = x₁ − (its first maximum) touches 0 there
// without crossing — no crossing; lowered by 1e-9 it crosses twice, and both are found.
TEST(LinearMode, CrossingsOfTwoFrequenciesAgainstADenseScan)
{
  const double z1 = 0.05, w1 = 1.0, z2 = 0.02, w2 = 37.0;
  MatrixXd a = MatrixXd::Zero(4, 4);
  a << 0.0, 1.0, 0.0, 0.0, -w1 * w1, -2.0 * z1 * w1, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -w2 * w2, -2.0 * z2 * w2;
  const VectorXd x0 = vec({0.4, 0.0, 0.2, 0.0});
  auto osc = [](double z, double w, double x, double t) {
    const double wd = w * std::sqrt(1.0 - z * z);
    return x * std::exp(-z * w * t) * (std::cos(wd * t) + z * w / wd * std::sin(wd * t));
  };
  auto s = [&](double t) { return osc(z1, w1, 0.4, t) + 0.3 * osc(z2, w2, 0.2, t) - 0.05; };
  std::vector<double> truth;
  const double horizon = 30.0, step = 1e-5;
  for (double t = step; t <= horizon; t += step)
  {
    if ((s(t - step) > 0.0) != (s(t) > 0.0))
    {
      double lo = t - step, hi = t;
      for (int i = 0; i < 80; ++i)
      {
        const double mid = 0.5 * (lo + hi);
        ((s(mid) > 0.0) == (s(lo) > 0.0) ? lo : hi) = mid;
      }
      truth.push_back(hi);
    }
  }
  ASSERT_GT(truth.size(), 10u);
  const VectorXd w = vec({1.0, 0.0, 0.3, 0.0});
  std::vector<double> found;
  double t0 = 0.0;
  VectorXd x = x0;
  for (;;)
  {
    const LinearMode m(a, VectorXd::Zero(4), x);
    const double up = m.firstCrossing(w, -0.05, +1, horizon - t0);
    const double down = m.firstCrossing(w, -0.05, -1, horizon - t0);
    const double next = std::min(up, down);
    if (next == INF)
    {
      break;
    }
    t0 += next;
    found.push_back(t0);
    x = m.state(next);
  }
  ASSERT_EQ(found.size(), truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i)
  {
    EXPECT_NEAR(found[i], truth[i], 1e-9) << i;
  }
  // Grazing at the first maximum of x₁ alone (an undamped 1 rad/s oscillator from x = 0, v = 1: max 1 at π/2).
  MatrixXd b(2, 2);
  b << 0.0, 1.0, -1.0, 0.0;
  const LinearMode g(b, VectorXd::Zero(2), vec({0.0, 1.0}));
  EXPECT_EQ(g.firstCrossing(vec({1.0, 0.0}), -1.0, +1, 3.0), INF);
  const double below = g.firstCrossing(vec({1.0, 0.0}), -(1.0 - 1e-9), +1, 3.0);
  const double above = g.firstCrossing(vec({1.0, 0.0}), -(1.0 - 1e-9), -1, 3.0);
  // (Crossings at a slope of only 4.5e-5: a rounding of the output moves them by ~1e-12 s.)
  EXPECT_NEAR(below, std::asin(1.0 - 1e-9), 1e-10);
  EXPECT_NEAR(above, M_PI - std::asin(1.0 - 1e-9), 1e-10);
}

/// Modelica.Mechanics.Rotational.Examples.Backlash: an inertia J = 5 kg·m² on a fixed flange through a compliant
/// backlash of total play b = π/4 rad (free for |φ| ≤ b/2), c = 2e4 N·m/rad, d = 50 N·m·s/rad, from φ = π/2 at rest
/// (deep in the positive flank). Contact on the flank of sign σ: penetration y = σφ − b/2, P = c y + d ẏ, torque −σQ
/// on the inertia. ElastoBacklash2 (Q = max(0, P), Kelvin–Voigt that never pulls); ElastoBacklash (Q = c y + min(cy,
/// dẏ) while positive: 2cy while dẏ > cy, then cy + dẏ). The reference results (modelica/MAP-LIB_ReferenceResults,
/// Rotational/Examples/Backlash): first release at t = 0.0236592 s with w = −66.19662 rad/s, next contact at
/// t = 0.0380238 s (both laws); ElastoBacklash2 releases from that contact at t = 0.0853423 s with w = 52.24986 rad/s
/// (restitution 0.789313 = exp(−ζ/√(1−ζ²)(π − atan2(2ζ√(1−ζ²), 1 − 2ζ²))), ζ = d/(2√(cJ))).
struct Bounce
{
  double j = 5.0, c = 2e4, d = 50.0, b = M_PI / 4.0;
  /// Contact mode on flank σ with torque c y + k_d ẏ (k_d = d, or 0 with stiffness 2c in ElastoBacklash's K2).
  LinearMode contact(double sigma, double stiffness, double damping, const VectorXd& x) const
  {
    MatrixXd a(2, 2);
    a << 0.0, 1.0, -stiffness / j, -damping / j;
    // J φ̈ = −σ(k (σφ − b/2) + k_d σ φ̇) = −k φ + σ k b/2 − k_d φ̇
    return LinearMode(a, vec({0.0, sigma * stiffness * 0.5 * b / j}), x);
  }
  LinearMode flight(const VectorXd& x) const
  {
    MatrixXd a(2, 2);
    a << 0.0, 1.0, 0.0, 0.0;
    return LinearMode(a, VectorXd::Zero(2), x);
  }
};

// Two free bodies with light friction, the motor driven hard (3.6e6 rad/s²), the load spinning at 3e4 rad/s: the
// penetration y = ρθ_m − θ_c dips from 1.6 mrad through zero and back within 5 µs. Its two crossings are far above
// what rounding can do to the deviation the closed form computes — though far below the rounding of the whole state's
// speeds, which once hid them as a grazing. Reference: the bodies' closed forms written here, scanned densely.
TEST(LinearMode, ACrossingOfAFastSpinningJointIsNotLostInRounding)
{
  const double fm = 0.00017515641016332761, fc = 9.8190576351812383e-06, um = 3641493.9478083043;
  const double rho = 106.6377993717318;
  MatrixXd a = MatrixXd::Zero(4, 4);
  a(0, 1) = 1.0;
  a(1, 1) = -fm;
  a(2, 3) = 1.0;
  a(3, 3) = -fc;
  const VectorXd x0 = vec({-0.012172693096842855, 283.74150838763518, -1.2996593869293906, 31519.901757133262});
  const LinearMode m(a, vec({0.0, um, 0.0, 0.0}), x0);
  const auto y = [&](double t) {
    // θ_m = θ₀ + (u/f)t + (ω₀ − u/f)(1 − e^{−ft})/f, θ_c = θ₀ + ω₀(1 − e^{−ft})/f (expm1: no cancellation).
    const double sm = -std::expm1(-fm * t) / fm, sc = -std::expm1(-fc * t) / fc;
    const double theta_m = x0(0) + um / fm * (t - sm) + x0(1) * sm;
    const double theta_c = x0(2) + x0(3) * sc;
    return rho * theta_m - theta_c;
  };
  double root = NAN;
  const int n = 200000;
  const double horizon = 1.932e-05;
  for (int i = 1; i <= n && std::isnan(root); ++i)
  {
    if (y(horizon * i / n) < 0.0)
    {
      double lo = horizon * (i - 1) / n, hi = horizon * i / n;
      for (int k = 0; k < 60; ++k)
      {
        const double mid = 0.5 * (lo + hi);
        (y(mid) < 0.0 ? hi : lo) = mid;
      }
      root = hi;
    }
  }
  ASSERT_FALSE(std::isnan(root));
  EXPECT_NEAR(m.firstCrossing(vec({rho, 0.0, -1.0, 0.0}), 0.0, -1, horizon), root, 1e-12);
}

TEST(LinearMode, ModelicasBacklashExampleEvents)
{
  const Bounce k;
  // Both laws: from rest in the positive flank, ẏ < 0 at once, so ElastoBacklash's min(cy, dẏ) = dẏ: the same contact.
  const LinearMode first = k.contact(+1.0, k.c, k.d, vec({M_PI / 2.0, 0.0}));
  const double t1 = first.firstCrossing(vec({k.c, k.d}), -k.c * 0.5 * k.b, -1, 1.0);  // P = c(φ − b/2) + dφ̇ ↓ 0
  const VectorXd x1 = first.state(t1);
  EXPECT_NEAR(t1, 0.0236592, 5e-7);
  EXPECT_NEAR(x1(1), -66.19662, 5e-5);
  EXPECT_GT(x1(0), 0.5 * k.b);  // released while still penetrating: y = −dẏ/c > 0
  // Free flight to the negative flank: y₋ = −φ − b/2 ↑ 0.
  const LinearMode fly = k.flight(x1);
  const double t2 = fly.firstCrossing(vec({-1.0, 0.0}), -0.5 * k.b, +1, 1.0);
  EXPECT_NEAR(t1 + t2, 0.0380238, 5e-7);
  const VectorXd x2 = fly.state(t2);
  // ElastoBacklash2 on the negative flank: P = c(−φ − b/2) − dφ̇ ↓ 0.
  const LinearMode second = k.contact(-1.0, k.c, k.d, x2);
  const double t3 = second.firstCrossing(vec({-k.c, -k.d}), -k.c * 0.5 * k.b, -1, 1.0);
  const VectorXd x3 = second.state(t3);
  EXPECT_NEAR(t1 + t2 + t3, 0.0853423, 5e-7);
  EXPECT_NEAR(x3(1), 52.24986, 5e-5);
  const double zeta = k.d / (2.0 * std::sqrt(k.c * k.j)), r = std::sqrt(1.0 - zeta * zeta);
  const double e = std::exp(-zeta / r * (M_PI - std::atan2(2.0 * zeta * r, 1.0 - 2.0 * zeta * zeta)));
  EXPECT_NEAR(e, 0.7893131, 1e-7);
  EXPECT_NEAR(x3(1) / -x2(1), e, 1e-12);  // the contact's exact restitution, entering at y = 0
  // ElastoBacklash on the negative flank: enters in K2 (dẏ > cy = 0: torque 2cy, undamped) until cy = dẏ, then KD.
  const LinearMode k2 = k.contact(-1.0, 2.0 * k.c, 0.0, x2);
  const double ts = k2.firstCrossing(vec({-k.c, k.d}), -k.c * 0.5 * k.b, +1, 1.0);  // cy − dẏ ↑ 0
  const VectorXd xs = k2.state(ts);
  const double y = -xs(0) - 0.5 * k.b, ydot = -xs(1);
  EXPECT_NEAR(k.c * y, k.d * ydot, 1e-9 * k.c * y);
  EXPECT_GT(y, 0.0);
  // The K2 phase is an undamped spring 2c from y = 0 at speed ẏ₀: y = ẏ₀/Ω sin Ωt, and cy = dẏ at tan Ωt = dΩ/c.
  const double omega = std::sqrt(2.0 * k.c / k.j);
  EXPECT_NEAR(ts, std::atan(k.d * omega / k.c) / omega, 1e-14);
}
}  // namespace

// An overdamped pair ẋ₁ = −x₁, ẋ₂ = −10⁶ x₂ from (1, 1): both parts vary at first (speedup 1); the fast part's
// velocity starts 10⁶ times the slow one's, so once 10⁶ e^{−10⁶τ} is below 1e-18 of it (τ > 5.5e-5 s) only the slow
// one varies — the speedup is then the ratio of the rates, 10⁶ (the cap). A ringing mode (a lightly damped oscillator) never decays against itself: 1 at every τ.
TEST(LinearMode, TheDecayedSpeedupCountsOnlyTheModesThatStillVary)
{
  MatrixXd a(2, 2);
  a << -1.0, 0.0, 0.0, -1e6;
  const LinearMode fast_and_slow(a, vec({0.0, 0.0}), vec({1.0, 1.0}));
  ASSERT_TRUE(fast_and_slow.modal());
  EXPECT_EQ(fast_and_slow.decayedSpeedup(0.0), 1.0);
  EXPECT_EQ(fast_and_slow.decayedSpeedup(5e-5), 1.0);  // 10⁶ e^{−50} = 2e-16 of the slow part: still varying
  EXPECT_EQ(fast_and_slow.decayedSpeedup(6e-5), 1e6);
  a << -1.0, 0.0, 0.0, -1e3;
  EXPECT_NEAR(LinearMode(a, vec({0.0, 0.0}), vec({1.0, 1.0})).decayedSpeedup(0.1), 1e3, 1e-9);
  MatrixXd ring(2, 2);
  ring << 0.0, 1.0, -1.0, -0.02;
  const LinearMode oscillator(ring, vec({0.0, 0.0}), vec({1.0, 0.0}));
  for (double t : {0.0, 10.0, 1000.0})
  {
    EXPECT_EQ(oscillator.decayedSpeedup(t), 1.0) << t;
  }
}
