// Helpers shared by the gtest files: chart-form parameters, an event recorder, running a command.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/frequency/describing_function.h"
#include "backlash_servo/model/params.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/step_response.h"

namespace test_helpers
{
/// Physical parameters from the thesis' chart form (ω_n [rad/s], Δ [rad]).
inline backlash_servo::ServoParams chart(double zeta, double inertia_ratio, double friction_ratio, double e,
                                         double delta = 0.3, double omega_n = 1.0, double rho = 1.0)
{
  backlash_servo::ChartParams c;
  c.zeta = zeta;
  c.inertia_ratio = inertia_ratio;
  c.friction_ratio = friction_ratio;
  c.restitution = e;
  c.backlash = delta;
  c.natural_frequency = omega_n;
  c.gear_ratio = rho;
  return c.toServoParams();
}

/// Thesis D1 with a compliant mesh: c = 1e4 N·m/rad, d for a contact damping ratio of e = 0.8's (the reference case
/// sd_c1e4_e08_D1 of compliant/test_compliant_joint.cpp).
inline backlash_servo::ServoParams compliantD1()
{
  backlash_servo::ServoParams p;
  p.mesh_stiffness = 1e4;
  p.mesh_damping = 4.461305825858438;
  return p;
}

/// A 100:1 robot joint under gravity (J_m 3e-5, J_L 0.12 kg·m², Δ 0.15° at the load, −3.5 N·m) stepped to 0.5 rad by
/// a 1 kHz PD (K_d 0.3 N·m·s/rad) reading a 17-bit load encoder; `gain` K [N·m/rad]. No dry friction, no torque
/// limit, no integral action: each test adds its own.
inline backlash_servo::RunConfig quantisedRobotJoint(double gain)
{
  backlash_servo::RunConfig c;
  backlash_servo::ServoParams& p = c.params;
  p.motor_inertia = 3e-5;
  p.load_inertia = 0.12;
  p.motor_friction = 5e-5;
  p.load_friction = 0.05;
  p.gear_ratio = 0.01;
  p.backlash = 0.002618;
  p.restitution = 0.3;
  p.load_torque = -3.5;
  p.gain = gain;
  c.drive.control_law = "pid";
  c.drive.controller_rate = 1000.0;
  c.drive.load_encoder_resolution = 131072;
  c.drive.derivative_gain = 0.3;
  c.command = 0.5;
  return c;
}

/// The robot joint of config/compare_compliant.yaml: 100:1 gear, 5 mrad backlash at the load, a harmonic drive's mesh
/// stiffness (c = 8.6e4 N·m/rad, d = 20 N·m·s/rad), viscous friction only, K = 6 N·m/rad.
inline backlash_servo::ServoParams compliantRobotJoint()
{
  backlash_servo::ServoParams p;
  p.motor_inertia = 1e-4;
  p.load_inertia = 0.5;
  p.motor_friction = 1e-4;
  p.load_friction = 0.5;
  p.gear_ratio = 0.01;
  p.backlash = 0.005;
  p.gain = 6.0;
  p.mesh_stiffness = 8.6e4;
  p.mesh_damping = 20.0;
  return p;
}

/// A limit cycle the harmonic balance predicts: amplitude [rad], frequency [rad/s], stability.
struct BalanceRoot
{
  double amplitude, frequency;
  bool stable;
};

/**
 * The closed form of the harmonic balance of a second-order type-1 loop G(s) = gain/(j s² + f s) with the classical
 * backlash DF: its phase −π/2 − atan(jω/f) and the DF's give ω(A) = (f/j)(−N_R/N_I) on the balance, and the
 * magnitude leaves one equation in A, m(A) = gain·|N(A)| − ω√(j²ω² + f²) = 0, scanned over A/d − 1 in [1e-9, 1e3]
 * and bisected. A cycle is stable where m falls through zero (a larger amplitude lowers the loop's gain).
 */
inline std::vector<BalanceRoot> typeOneLoopCycles(double j, double f, double gain, double backlash)
{
  const double d = 0.5 * backlash;
  const auto omega_of = [&](double a) {
    const std::complex<double> n = backlash_servo::backlashDescribingFunction(a, backlash);
    return f / j * (-n.real() / n.imag());
  };
  const auto m = [&](double a) {
    const double w = omega_of(a);
    return gain * std::abs(backlash_servo::backlashDescribingFunction(a, backlash)) -
           w * std::sqrt(j * j * w * w + f * f);
  };
  std::vector<BalanceRoot> roots;
  double prev_a = d * (1.0 + 1e-9), prev_m = m(prev_a);
  for (int i = 1; i <= 20000; ++i)
  {
    const double a = d * (1.0 + std::pow(10.0, -9.0 + i * 0.0006));
    const double here = m(a);
    if ((here > 0.0) != (prev_m > 0.0))
    {
      double lo = prev_a, hi = a;
      for (int it = 0; it < 200; ++it)
      {
        const double mid = 0.5 * (lo + hi);
        ((m(mid) > 0.0) == (prev_m > 0.0) ? lo : hi) = mid;
      }
      roots.push_back({lo, omega_of(lo), here < prev_m});
    }
    prev_a = a;
    prev_m = here;
  }
  return roots;
}

/// Keeps every event.
struct Recorder : backlash_servo::EventSink
{
  std::vector<backlash_servo::Event> events;
  void onEvent(const backlash_servo::Event& e) override { events.push_back(e); }
  std::vector<backlash_servo::Event> of(backlash_servo::EventType t) const
  {
    std::vector<backlash_servo::Event> out;
    for (const backlash_servo::Event& e : events)
    {
      if (e.type == t)
      {
        out.push_back(e);
      }
    }
    return out;
  }
  std::vector<double> times(backlash_servo::EventType t) const
  {
    std::vector<double> out;
    for (const backlash_servo::Event& e : of(t))
    {
      out.push_back(e.state.time);
    }
    return out;
  }
};

/// The whole content of a file ("" if unreadable).
inline std::string readFile(const std::string& path)
{
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Runs a shell command; returns its stdout and sets *code to its exit status.
inline std::string runCapture(const std::string& cmd, int* code = nullptr)
{
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0)
  {
    out.append(buf, n);
  }
  const int status = pclose(p);
  if (code != nullptr)
  {
    *code = WEXITSTATUS(status);
  }
  return out;
}
/// Classical RK4 in long double, `steps` steps of h on y' = f(y) (f(y, dy) writes dy): a reference integrator.
template <int N, class F>
void rk4(const F& f, long double (&y)[N], long double h, int steps)
{
  for (int n = 0; n < steps; ++n)
  {
    long double k1[N], k2[N], k3[N], k4[N], t[N];
    f(y, k1);
    for (int i = 0; i < N; ++i)
      t[i] = y[i] + h / 2 * k1[i];
    f(t, k2);
    for (int i = 0; i < N; ++i)
      t[i] = y[i] + h / 2 * k2[i];
    f(t, k3);
    for (int i = 0; i < N; ++i)
      t[i] = y[i] + h * k3[i];
    f(t, k4);
    for (int i = 0; i < N; ++i)
      y[i] += h / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
  }
}

/// The thesis' D1 servo (ζ = 0.4, ω_n = 1 rad/s) with a heavy load (2 kg·m², 0.3 N·m·s/rad, ρ = 0.5) and bouncing
/// teeth (Δ = 0.2 rad, e = 0.6).
inline backlash_servo::ServoParams bouncing()
{
  backlash_servo::ServoParams p;
  p.gear_ratio = 0.5;
  p.backlash = 0.2;
  p.restitution = 0.6;
  p.load_inertia = 2.0;
  p.load_friction = 0.3;
  return p;
}

/// The locked joint (Δ = 0) on the forced response θ_c = Im(z e^{jωt}) [rad] at time t [s], the motor at θ_c/ρ.
inline backlash_servo::State onForcedResponse(std::complex<double> z, double omega, double rho, double t)
{
  const std::complex<double> at = z * std::exp(std::complex<double>(0.0, omega * t));
  backlash_servo::State s;
  s.time = t;
  s.load_position = at.imag();
  s.load_velocity = (std::complex<double>(0.0, omega) * at).imag();
  s.motor_position = s.load_position / rho;
  s.motor_velocity = s.load_velocity / rho;
  return s;
}

/// Advances `sim` over 40 quarter periods of ω and returns the largest deviation of its load from the forced response
/// Im(z e^{jωt}) — in angle [rad], and in speed divided by ω.
inline double worstFromForcedResponse(backlash_servo::Simulator& sim, std::complex<double> z, double omega,
                                      backlash_servo::EventSink* sink = nullptr)
{
  double worst = 0.0;
  for (int i = 1; i <= 40; ++i)
  {
    const double t = i * 0.25 * 3.14159265358979323846 / omega;
    sim.advanceTo(t, sink);
    const backlash_servo::State expected = onForcedResponse(z, omega, 1.0, t);
    worst = std::max({worst, std::fabs(sim.state().load_position - expected.load_position),
                      std::fabs(sim.state().load_velocity - expected.load_velocity) / omega});
  }
  return worst;
}

}  // namespace test_helpers
