// Light damping and nearly equal rates: the apart mode's closed forms must stay exact when a decay rate
// is slow over the search window (its exponential becomes a Taylor polynomial) or two rates nearly coincide.
// Checked against a reference integrator written here (RK4 in long double on the apart-mode ODE), the energy
// balance (a conservation law), and continuity towards the undamped servo.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "backlash_servo/simulation/simulator.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

/// Apart mode: J_L θc'' + f_L θc' = 0, J_m θm'' + f_m θm' = a − k θc, by classical RK4 in long double.
State rk4Apart(const ServoParams& p, double a, double k, const State& s0, double duration, int steps)
{
  using L = long double;
  L x[4] = {s0.load_position, s0.load_velocity, s0.motor_position, s0.motor_velocity};
  auto f = [&](const L* y, L* d) {
    d[0] = y[1];
    d[1] = -static_cast<L>(p.load_friction) * y[1] / p.load_inertia;
    d[2] = y[3];
    d[3] = (static_cast<L>(a) - k * y[0] - static_cast<L>(p.motor_friction) * y[3]) / p.motor_inertia;
  };
  test_helpers::rk4(f, x, static_cast<L>(duration) / steps, steps);
  State out = s0;
  out.load_position = static_cast<double>(x[0]);
  out.load_velocity = static_cast<double>(x[1]);
  out.motor_position = static_cast<double>(x[2]);
  out.motor_velocity = static_cast<double>(x[3]);
  return out;
}

TEST(LightDamping, ApartModeMatchesAReferenceIntegratorForSlowAndNearlyEqualRates)
{
  // (α = f_L/J_L, β = f_m/J_m) [1/s]: slow, very slow, one slow one fast, nearly equal (fast and slow), zero.
  const double rates[][2] = {{1e-3, 2e-3},      {1e-6, 3e-7},         {1e-9, 0.5},    {0.8, 1e-7}, {0.5, 0.5 + 1e-9},
                             {0.5, 0.5 + 1e-3}, {2e-5, 2e-5 + 1e-13}, {0.0, 1e-4},    {1e-4, 0.0}, {3e-2, 7e-2},
                             {1e-9, 0.0221},    {1e-9, 0.0200},       {1e-9, 0.0250}, {1e-9, 0.05}};
  for (const auto& r : rates)
  {
    ServoParams p;
    p.motor_inertia = 0.1;
    p.load_inertia = 0.9;
    p.load_friction = r[0] * p.load_inertia;
    p.motor_friction = r[1] * p.motor_inertia;
    p.gain = 0.05;  // the motor stays far from both walls over 7.5 s: apart throughout
    p.backlash = 100.0;
    State s;
    s.contact = Contact::Apart;
    s.load_position = 0.2;
    s.load_velocity = 0.7;
    s.motor_position = -50.0;  // gap 50.2 rad
    s.motor_velocity = -0.4;
    Simulator sim(p, s, 1.5);  // T_m = K(θ_R − θ_c), K = 1 N·m/rad
    for (double t : {0.3, 1.0, 2.9, 7.5})
    {
      sim.advanceTo(t);
      const State ref = rk4Apart(p, p.gain * 1.5, p.gain, s, t, 20000);
      const State& got = sim.state();
      EXPECT_NEAR(got.load_position, ref.load_position, 1e-12) << r[0] << " " << r[1] << " t " << t;
      EXPECT_NEAR(got.load_velocity, ref.load_velocity, 1e-12) << r[0] << " " << r[1] << " t " << t;
      EXPECT_NEAR(got.motor_position, ref.motor_position, 1e-11) << r[0] << " " << r[1] << " t " << t;
      EXPECT_NEAR(got.motor_velocity, ref.motor_velocity, 1e-12) << r[0] << " " << r[1] << " t " << t;
      EXPECT_EQ(sim.impactCount(), 0u);
      const double scale = std::fabs(sim.energy().input) + sim.energy().initial_kinetic;
      EXPECT_LE(std::fabs(sim.energyBalanceError()), 1e-11 * scale) << r[0] << " " << r[1] << " t " << t;
    }
  }
}

/// Checks every event: the gap stays in [0, Δ] up to rounding.
struct GapWatch : EventSink
{
  double delta;
  double rho;
  double worst = 0.0;
  void onEvent(const Event& e) override
  {
    const double g = e.state.load_position - rho * e.state.motor_position;
    worst = std::max({worst, -g, g - delta});
  }
};

TEST(LightDamping, EnergyBalanceClosesAndTheGapStaysInTheBacklashDownToZeta1e9)
{
  for (double zeta : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-9})
  {
    for (double e : {1.0, 0.6})
    {
      const ServoParams p = test_helpers::chart(zeta, 9.0, 0.4, e);
      Simulator sim(p, State(), 1.0);
      GapWatch watch;
      watch.delta = p.backlash;
      watch.rho = p.gear_ratio;
      sim.advanceTo(200.0, &watch);
      const double scale = sim.energy().input + sim.energy().initial_kinetic;
      EXPECT_LE(std::fabs(sim.energyBalanceError()), 1e-9 * scale) << "zeta " << zeta << " e " << e;
      EXPECT_LE(watch.worst, 1e-12) << "zeta " << zeta << " e " << e;
      EXPECT_GT(sim.impactCount(), 100u);
    }
  }
}

TEST(LightDamping, TheResponseTendsToTheUndampedOneAsZetaVanishes)
{
  // Over 20 s (40 impacts, before the motion's sensitivity grows) the state depends smoothly on ζ: the difference
  // from ζ = 0 falls in proportion to ζ (measured ~180 ζ rad and ~1.7e4 ζ rad/s), never the 1e14 rad the
  // cancelling closed forms gave at ζ = 1e-7.
  auto finalState = [](double zeta) {
    Simulator sim(test_helpers::chart(zeta, 9.0, 0.4, 1.0), State(), 1.0);
    sim.advanceTo(20.0);
    return sim.state();
  };
  const State undamped = finalState(0.0);
  for (double zeta : {1e-6, 1e-7, 1e-8, 1e-9, 1e-11})
  {
    const State s = finalState(zeta);
    EXPECT_LE(std::fabs(s.load_position - undamped.load_position), 1e3 * zeta + 1e-12) << zeta;
    EXPECT_LE(std::fabs(s.motor_velocity - undamped.motor_velocity), 1e5 * zeta + 1e-12) << zeta;
  }
}

}  // namespace
