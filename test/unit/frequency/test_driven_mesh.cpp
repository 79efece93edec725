// The compliant mesh's element driven by an exact sine (driven_mesh.h) against independent truth: without backlash
// and damping it is a linear spring on the load, whose response is written here; with backlash and damping, under
// either mesh law and with the load's dry friction, a brute-force fixed-step integration of its equation written
// here; refusals name the key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <functional>
#include <string>

#include "backlash_servo/frequency/driven_mesh.h"
#include "backlash_servo/model/params.h"

using namespace backlash_servo;

// Δ = 0, d = 0: the teeth pass c(x − θ_c) at all times (one flank or the other), so N_θ = c/(−ω²J_L + jωf_L + c) —
// below, near and above the load's resonance √(c/J_L), soft and stiff — and N_T = (−ω²J_L + jωf_L) N_θ.
TEST(DrivenMesh, WithoutBacklashAndDampingItIsTheLinearSpring)
{
  ServoParams p;
  p.load_inertia = 0.5;
  p.load_friction = 0.08;
  p.backlash = 0.0;
  p.mesh_damping = 0.0;
  for (double c : {3.0, 1000.0})
  {
    p.mesh_stiffness = c;
    for (double w : {0.7, 2.0, 3.0})
    {
      const DrivenBacklash d = drivenCompliantMesh(p, 0.2, w);
      const std::complex<double> l(-w * w * p.load_inertia, w * p.load_friction);
      const std::complex<double> expected = c / (l + c);
      ASSERT_TRUE(d.periodic) << c << " " << w;
      EXPECT_LT(std::abs(d.position - expected), 1e-9 * std::abs(expected)) << c << " " << w;
      EXPECT_LT(std::abs(d.torque - l * expected), 1e-9 * std::abs(l * expected)) << c << " " << w;
    }
  }
}

// With backlash the element passes less than the spring would (N_θ below the linear one at small amplitudes, the
// free play crossed without torque) and tends to it as A/Δ grows.
TEST(DrivenMesh, ItTendsToTheLinearSpringAtLargeAmplitude)
{
  ServoParams p;
  p.load_inertia = 0.5;
  p.load_friction = 0.08;
  p.mesh_stiffness = 50.0;
  p.mesh_damping = 0.0;
  p.backlash = 0.01;
  const double w = 2.0;
  const std::complex<double> l(-w * w * p.load_inertia, w * p.load_friction);
  const std::complex<double> linear = p.mesh_stiffness / (l + p.mesh_stiffness);
  double previous = INFINITY;
  for (double a : {0.02, 0.1, 1.0})
  {
    const double off = std::abs(drivenCompliantMesh(p, a, w).position - linear) / std::abs(linear);
    EXPECT_LT(off, previous) << a;
    previous = off;
  }
  EXPECT_LT(previous, 0.01);
}

TEST(DrivenMesh, WhatItDoesNotTakeIsNamed)
{
  const auto refusal = [](const ServoParams& p) {
    try
    {
      drivenCompliantMesh(p, 0.5, 1.0);
    }
    catch (const InvalidParameterError& e)
    {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  ServoParams p;
  p.mesh_stiffness = 100.0;
  EXPECT_EQ(refusal(p), "accepted");
  ServoParams q = p;
  q.mesh_stiffness = 0.0;
  EXPECT_NE(refusal(q).find("mesh_stiffness"), std::string::npos);
  q = p;
  q.load_coulomb_friction = -0.1;
  EXPECT_NE(refusal(q).find("load_coulomb_friction"), std::string::npos);
  q = p;
  q.load_static_friction = NAN;
  EXPECT_NE(refusal(q).find("load_static_friction"), std::string::npos);
  q = p;
  q.load_torque = 0.1;
  EXPECT_NE(refusal(q).find("load_torque"), std::string::npos);
}

namespace
{
/// The element by brute force: J_L θ̈_c = −f_L θ̇_c − F + Q, x = A sin ωt, Q the mesh law of docs/model.md as a
/// function of the state, F the load's dry friction by the rest rule; from rest at the centre, classical RK4 steps of
/// a period/steps while the load slides, a stop located by bisection on the step length (then stuck while |H| ≤ T_s,
/// else sliding on in the direction of H), a stuck load's breakaway by bisection on its holding torque H(t) = Q(t)
/// (explicit in t: the load does not move), a step across a flank redone in 10⁴ sub-steps. Returns N_θ and N_T (the
/// fundamental of the mesh torque Q on the load, by the rectangle rule at the steps).
void bruteForce(const ServoParams& p, double a, double w, int periods, int steps, std::complex<double>* n_theta,
                std::complex<double>* n_torque)
{
  const double half = 0.5 * p.backlash, c = p.mesh_stiffness, d = p.mesh_damping;
  const double tc = p.load_coulomb_friction, ts = std::max(p.load_static_friction, tc);
  const bool msl = p.mesh_law == "msl_elastobacklash";
  const auto mesh = [&](double t, double th, double om) {
    const double g = a * std::sin(w * t) - th, gd = a * w * std::cos(w * t) - om;
    const int sigma = g > half ? 1 : (g < -half ? -1 : 0);
    if (sigma == 0)
    {
      return 0.0;
    }
    const double y = sigma * g - half, yd = sigma * gd, tcy = c * y, td = d * yd;
    return sigma * (msl ? (tcy + td <= 0.0 ? 0.0 : tcy + std::min(tcy, td)) : std::max(0.0, tcy + td));
  };
  int slide = 0;
  const auto accel = [&](double t, double th, double om) {
    return (-p.load_friction * om - slide * tc + mesh(t, th, om)) / p.load_inertia;
  };
  const auto rk4 = [&](double t, double dt, double* th, double* om) {
    const double k1x = *om, k1v = accel(t, *th, *om);
    const double k2x = *om + 0.5 * dt * k1v, k2v = accel(t + 0.5 * dt, *th + 0.5 * dt * k1x, *om + 0.5 * dt * k1v);
    const double k3x = *om + 0.5 * dt * k2v, k3v = accel(t + 0.5 * dt, *th + 0.5 * dt * k2x, *om + 0.5 * dt * k2v);
    const double k4x = *om + dt * k3v, k4v = accel(t + dt, *th + dt * k3x, *om + dt * k3v);
    *th += dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
    *om += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
  };
  const auto side = [&](double t, double th) {
    const double g = a * std::sin(w * t) - th;
    return g > half ? 1 : (g < -half ? -1 : 0);
  };
  const auto rest = [&](double t, double th) {
    const double h = mesh(t, th, 0.0);
    slide = std::fabs(h) <= ts ? 0 : (h > 0.0 ? 1 : -1);
  };
  // One piece [t, t + dt] of a smooth stretch: stuck (breakaway located) or sliding (stop located).
  const std::function<void(double, double, double*, double*)> piece = [&](double t, double dt, double* th, double* om) {
    while (dt > 0.0)
    {
      if (slide == 0)
      {
        const auto beyond = [&](double tt) { return std::fabs(mesh(tt, *th, 0.0)) - ts; };
        if (beyond(t + dt) <= 0.0)
        {
          return;  // stuck throughout
        }
        double lo = t, hi = t + dt;
        for (int i = 0; i < 80; ++i)
        {
          const double mid = 0.5 * (lo + hi);
          (beyond(mid) > 0.0 ? hi : lo) = mid;
        }
        slide = mesh(hi, *th, 0.0) > 0.0 ? 1 : -1;
        dt -= hi - t;
        t = hi;
        continue;
      }
      double th1 = *th, om1 = *om;
      rk4(t, dt, &th1, &om1);
      if (om1 * slide > 0.0)
      {
        *th = th1;
        *om = om1;
        return;
      }
      double lo = 0.0, hi = dt;
      for (int i = 0; i < 80; ++i)
      {
        const double mid = 0.5 * (lo + hi);
        double thm = *th, omm = *om;
        rk4(t, mid, &thm, &omm);
        (omm * slide > 0.0 ? lo : hi) = mid;
      }
      rk4(t, hi, th, om);
      *om = 0.0;
      t += hi;
      dt -= hi;
      rest(t, *th);
    }
  };
  const double h = 2.0 * M_PI / w / steps;
  double th = 0.0, om = 0.0;
  std::complex<double> line = 0.0, torque = 0.0;
  for (int k = 0; k < periods * steps; ++k)
  {
    const double t = k * h;
    if (k >= (periods - 1) * steps)
    {
      line += th * std::polar(1.0, -w * t);
      torque += mesh(t, th, om) * std::polar(1.0, -w * t);
    }
    double th1 = th, om1 = om;
    const int slide0 = slide;
    piece(t, h, &th1, &om1);
    if (side(t, th) != side(t + h, th1))
    {
      th1 = th;
      om1 = om;
      slide = slide0;
      constexpr int SUB = 10000;
      for (int i = 0; i < SUB; ++i)
      {
        piece(t + i * h / SUB, h / SUB, &th1, &om1);
      }
    }
    th = th1;
    om = om1;
  }
  *n_theta = std::complex<double>(0.0, 1.0) * (2.0 / steps) * line / a;
  *n_torque = std::complex<double>(0.0, 1.0) * (2.0 / steps) * torque / a;
}
/// The element of the brute-force comparisons: a light load (0.1 kg·m², 0.08 N·m·s/rad) behind a soft damped mesh
/// (30 N·m/rad, 1 N·m·s/rad, √(c/J_L) ≈ 17 rad/s) across 0.3 rad of play.
ServoParams softElement()
{
  ServoParams p;
  p.load_inertia = 0.1;
  p.load_friction = 0.08;
  p.mesh_stiffness = 30.0;
  p.mesh_damping = 1.0;
  p.backlash = 0.3;
  return p;
}
}  // namespace

// Backlash, damping and the two mesh laws: the exact element's N_θ equals the brute-force one to 1e-7 (the fixed
// step's error), below, near and above the contact's resonance √(c/J_L) ≈ 17 rad/s; and the laws
// differ there (by more than 1e-3: msl's 2c·y sub-mode while d·ẏ > c·y).
TEST(DrivenMesh, EitherMeshLawMatchesABruteForceIntegration)
{
  ServoParams p = softElement();
  for (double w : {5.0, 20.0, 40.0})
  {
    std::complex<double> laws[2];
    for (int i = 0; i < 2; ++i)
    {
      p.mesh_law = i == 0 ? "spring_damper" : "msl_elastobacklash";
      const DrivenBacklash exact = drivenCompliantMesh(p, 0.5, w);
      std::complex<double> reference, torque;
      bruteForce(p, 0.5, w, 80, 20000, &reference, &torque);
      std::printf("%s ω %g: N_θ %.9f%+.9fj, brute force off by %.2e (%d periods to settle)\n", p.mesh_law.c_str(), w,
                  exact.position.real(), exact.position.imag(), std::abs(exact.position - reference), exact.periods);
      ASSERT_TRUE(exact.periodic) << p.mesh_law << " " << w;
      EXPECT_LT(std::abs(exact.position - reference), 1e-7 * std::abs(reference)) << p.mesh_law << " " << w;
      laws[i] = exact.position;
    }
    EXPECT_GT(std::abs(laws[1] - laws[0]), 1e-3 * std::abs(laws[0])) << w;
  }
}

// The load's dry friction (Coulomb 0.05, static 0.08 N·m): it sticks in the free play and on a flank until the mesh
// torque leaves its static band. The exact element's N_θ equals the brute-force one to 1e-6 and its N_T — the
// fundamental of the mesh torque, inertia, viscous and dry friction's together — to 1e-4 (the brute force's
// rectangle rule across the torque's jumps), under either law, and differs from the frictionless element's.
TEST(DrivenMesh, TheLoadsDryFrictionMatchesABruteForceIntegration)
{
  ServoParams p = softElement();
  p.load_coulomb_friction = 0.05;
  p.load_static_friction = 0.08;
  for (const char* law : {"spring_damper", "msl_elastobacklash"})
  {
    for (double w : {5.0, 20.0})
    {
      p.mesh_law = law;
      const DrivenBacklash exact = drivenCompliantMesh(p, 0.5, w);
      std::complex<double> n_theta, n_torque;
      bruteForce(p, 0.5, w, 80, 20000, &n_theta, &n_torque);
      std::printf("%s ω %g: N_θ %.9f%+.9fj (brute force off by %.2e), N_T %.6f%+.6fj (off by %.2e), %d periods\n", law,
                  w, exact.position.real(), exact.position.imag(), std::abs(exact.position - n_theta),
                  exact.torque.real(), exact.torque.imag(), std::abs(exact.torque - n_torque), exact.periods);
      ASSERT_TRUE(exact.periodic) << law << " " << w;
      EXPECT_LT(std::abs(exact.position - n_theta), 1e-6 * std::abs(n_theta)) << law << " " << w;
      EXPECT_LT(std::abs(exact.torque - n_torque), 1e-4 * std::abs(n_torque)) << law << " " << w;
      ServoParams smooth = p;
      smooth.load_coulomb_friction = smooth.load_static_friction = 0.0;
      EXPECT_GT(std::abs(drivenCompliantMesh(smooth, 0.5, w).position - exact.position), 1e-3) << law << " " << w;
    }
  }
}
