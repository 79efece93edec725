// Physics against independent truth: the linear closed form, conservation laws at impacts, the energy balance,
// the gap bounds and the scaling laws of docs/model.md.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "backlash_servo/rigid/impact.h"
#include "backlash_servo/rigid/modes.h"
#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

using namespace backlash_servo;
using test_helpers::chart;
using test_helpers::Recorder;

namespace
{
/// Unit-step response of θ̈ + 2ζωθ̇ + ω²θ = ω² from rest (textbook closed form).
double linearStep(double zeta, double w, double t)
{
  if (zeta < 1.0)
  {
    const double wd = w * std::sqrt(1.0 - zeta * zeta);
    return 1.0 - std::exp(-zeta * w * t) * (std::cos(wd * t) + zeta / std::sqrt(1.0 - zeta * zeta) * std::sin(wd * t));
  }
  if (zeta == 1.0)
  {
    return 1.0 - std::exp(-w * t) * (1.0 + w * t);
  }
  const double s = std::sqrt(zeta * zeta - 1.0);
  const double l1 = -w * (zeta - s), l2 = -w * (zeta + s);
  return 1.0 + (l2 * std::exp(l1 * t) - l1 * std::exp(l2 * t)) / (l1 - l2);
}

}  // namespace

TEST(Linear, ZeroBacklashIsTheClosedFormStepResponse)
{
  for (double zeta : {0.1, 0.4, 1.0, 2.5})
  {
    for (double e : {0.0, 1.0})
    {
      const double w = 3.0;
      Simulator sim(chart(zeta, 4.0, 0.4, e, 0.0, w), State(), 1.0);
      double worst = 0.0;
      for (int i = 1; i <= 400; ++i)
      {
        const double t = 0.037 * i;
        sim.advanceTo(t);
        worst = std::max(worst, std::fabs(sim.state().load_position - linearStep(zeta, w, t)));
        EXPECT_DOUBLE_EQ(sim.gap(), 0.0);
      }
      EXPECT_LT(worst, 1e-12) << "zeta " << zeta << " e " << e;
      EXPECT_EQ(sim.impactCount(), 0u);
    }
  }
}

TEST(Impacts, ConserveMomentumAndObeyRestitution)
{
  for (double e : {0.0, 0.5, 0.8, 1.0})
  {
    for (double rho : {1.0, 2.5})
    {
      const ServoParams p = chart(0.2, 4.0, 0.4, e, 0.3, 1.0, rho);
      Recorder rec;
      Simulator sim(p, State(), 1.0);
      sim.advanceTo(80.0, &rec);
      const auto impacts = rec.of(EventType::Impact);
      ASSERT_GT(impacts.size(), 3u) << "e " << e;
      for (const Event& ev : impacts)
      {
        const ImpactInfo& i = ev.impact;
        const double jm = p.motor_inertia, jl = p.load_inertia;
        const double scale = jm * std::fabs(i.motor_velocity_before) + rho * jl * std::fabs(i.load_velocity_before);
        EXPECT_NEAR(jm * (i.motor_velocity_after - i.motor_velocity_before),
                    rho * jl * (i.load_velocity_before - i.load_velocity_after), 1e-13 * scale + 1e-300);
        const double rel_before = rho * i.motor_velocity_before - i.load_velocity_before;
        const double rel_after = rho * i.motor_velocity_after - i.load_velocity_after;
        // Relative speeds are differences of absolute velocities: their rounding is relative to those.
        const double tol = 1e-13 * (rho * std::fabs(i.motor_velocity_before) + std::fabs(i.load_velocity_before));
        if (!i.stuck && e > 0.0)
        {
          EXPECT_NEAR(rel_after, -e * rel_before, tol);
        }
        else
        {
          EXPECT_NEAR(rel_after, 0.0, tol);
        }
        // Kinetic energy lost equals the closed form (1 − e_eff²) ½ μ u².
        const double ke_before = 0.5 * jm * i.motor_velocity_before * i.motor_velocity_before +
                                 0.5 * jl * i.load_velocity_before * i.load_velocity_before;
        const double ke_after = 0.5 * jm * i.motor_velocity_after * i.motor_velocity_after +
                                0.5 * jl * i.load_velocity_after * i.load_velocity_after;
        EXPECT_NEAR(ke_before - ke_after, i.energy_loss, 1e-12 * ke_before + 1e-300);
        // The wall is approached: closing speed positive.
        EXPECT_GT(i.approach_speed, 0.0);
      }
    }
  }
}

TEST(Energy, BalanceClosesToRounding)
{
  struct Case
  {
    ServoParams p;
    double t;
  };
  std::vector<Case> cases = {{ServoParams(), 300.0},
                             {chart(0.1, 1.0, 0.4, 0.6), 400.0},
                             {chart(0.3, 0.04, 0.0, 0.0), 200.0},
                             {chart(0.5, 9.0, 1.0, 0.8, 0.3, 4.0, 3.0), 100.0},
                             {chart(0.7, 0.25, 0.6, 1.0, 0.05), 100.0}};
  for (const Case& c : cases)
  {
    Simulator sim(c.p, State(), 1.0);
    sim.advanceTo(c.t * 0.5);
    sim.setCommand(-0.5);  // a second step mid-run
    sim.advanceTo(c.t);
    const EnergyLedger& e = sim.energy();
    EXPECT_GT(e.input, 0.0);
    EXPECT_LT(std::fabs(sim.energyBalanceError()), 1e-9 * (std::fabs(e.input) + e.motor_friction + e.load_friction))
        << "balance " << sim.energyBalanceError() << " input " << e.input;
  }
  // Effort mode with a torque history (e = 0.8: elastic teeth under a reversing torque chatter physically for
  // ~10⁵ impacts, which is right but slow for a unit test).
  ServoParams chattery;
  chattery.restitution = 0.8;
  Simulator sim(chattery, State(), 0.0);
  const double torques[] = {0.8, -1.2, 0.3, 0.0, -0.4};
  for (int i = 0; i < 5; ++i)
  {
    sim.setMotorTorque(torques[i]);
    sim.advanceTo(7.0 * (i + 1));
  }
  EXPECT_LT(std::fabs(sim.energyBalanceError()), 1e-9 * std::fabs(sim.energy().input) + 1e-14);
}

TEST(Gap, NeverLeavesTheBacklash)
{
  for (double e : {0.0, 0.6, 1.0})
  {
    const ServoParams p = chart(0.15, 1.0, 0.2, e, 0.2);
    struct GapCheck : EventSink
    {
      double lo = 0, hi = 0, rho = 1;
      void onEvent(const Event& ev) override
      {
        const double g = ev.state.load_position - rho * ev.state.motor_position;
        lo = std::min(lo, g);
        hi = std::max(hi, g);
      }
    } check;
    check.rho = p.gear_ratio;
    Simulator sim(p, State(), 1.0);
    for (int i = 1; i <= 100000; ++i)
    {
      sim.advanceTo(i * 1e-3, &check);
      check.lo = std::min(check.lo, sim.gap());
      check.hi = std::max(check.hi, sim.gap());
    }
    EXPECT_GE(check.lo, -1e-12);
    EXPECT_LE(check.hi, p.backlash + 1e-12);
    EXPECT_GT(check.hi, 0.5 * p.backlash);  // the teeth really did cross the gap
  }
}

TEST(Scaling, NaturalFrequencyScalesTimeOnly)
{
  for (double e : {0.6, 1.0})
  {
    RunConfig a, b;
    a.params = chart(0.3, 4.0, 0.4, e, 0.3, 1.0);
    b.params = chart(0.3, 4.0, 0.4, e, 0.3, 5.0);
    a.duration = 100.0;
    b.duration = 100.0 / 5.0;
    const RunSummary ra = runResponse(a), rb = runResponse(b);
    ASSERT_EQ(ra.maxima.size(), rb.maxima.size());
    ASSERT_GT(ra.maxima.size(), 3u);
    for (std::size_t i = 0; i < ra.maxima.size(); ++i)
    {
      EXPECT_NEAR(rb.maxima[i].time * 5.0, ra.maxima[i].time, 1e-9 * ra.maxima[i].time);
      EXPECT_NEAR(rb.maxima[i].position, ra.maxima[i].position, 1e-9);
      EXPECT_NEAR(rb.maxima[i].velocity, 5.0 * ra.maxima[i].velocity, 1e-8);
    }
    EXPECT_EQ(ra.impacts, rb.impacts);
  }
}

TEST(Scaling, GearRatioEntersOnlyThroughReferredInertiaAndFriction)
{
  RunConfig a, b;
  a.params = chart(0.4, 9.0, 0.4, 1.0, 0.3, 1.0, 1.0);
  b.params = chart(0.4, 9.0, 0.4, 1.0, 0.3, 1.0, 2.5);
  a.duration = b.duration = 120.0;
  const RunSummary ra = runResponse(a), rb = runResponse(b);
  ASSERT_EQ(ra.maxima.size(), rb.maxima.size());
  for (std::size_t i = 0; i < ra.maxima.size(); ++i)
  {
    EXPECT_NEAR(rb.maxima[i].time, ra.maxima[i].time, 1e-9 * ra.maxima[i].time);
    EXPECT_NEAR(rb.maxima[i].position, ra.maxima[i].position, 1e-9);
  }
  EXPECT_EQ(ra.impacts, rb.impacts);
}

TEST(Scaling, LimitCycleSizeIsProportionalToBacklash)
{
  RunConfig a, b;
  a.params = chart(0.4, 9.0, 0.4, 1.0, 0.3);
  b.params = chart(0.4, 9.0, 0.4, 1.0, 0.03);
  const RunSummary ra = runResponse(a), rb = runResponse(b);
  ASSERT_EQ(ra.status.verdict, Verdict::LimitCycle);
  ASSERT_EQ(rb.status.verdict, Verdict::LimitCycle);
  EXPECT_NEAR(rb.status.error * 10.0, ra.status.error, 1e-6 * ra.status.error);
  EXPECT_NEAR(rb.status.period, ra.status.period, 1e-5 * ra.status.period);
}

TEST(Modes, ApartMotionSolvesItsOdeForEveryRateCase)
{
  // Generic (α ≠ β, both > 0; the written-out fast path), α = 0, β = 0, α = β (resonance): the closed form must
  // start at the given state and satisfy J_L θ̈_c + f_L θ̇_c = 0, J_m θ̈_m + f_m θ̇_m = a − kθ_c (central
  // differences), and its gap must be θ_c − ρθ_m.
  struct Case
  {
    double jm, jl, fm, fl;
  };
  const Case cases[] = {{0.1, 0.9, 0.48, 0.32}, {0.1, 0.9, 0.48, 0.0}, {0.1, 0.9, 0.0, 0.32}, {0.2, 0.5, 0.4, 1.0}};
  for (const Case& c : cases)
  {
    ServoParams p;
    p.motor_inertia = c.jm;
    p.load_inertia = c.jl;
    p.motor_friction = c.fm;
    p.load_friction = c.fl;
    p.gear_ratio = 1.7;
    const MotorInput in{0.8, 1.3};
    State s;
    s.load_position = 0.4;
    s.load_velocity = -0.7;
    s.motor_position = 0.1;
    s.motor_velocity = 1.1;
    s.contact = Contact::Apart;
    const FreeMotion m(p, in, s, 3.14159265358979323846);
    State at0;
    m.at(0.0, &at0);
    EXPECT_NEAR(at0.load_position, s.load_position, 1e-14);
    EXPECT_NEAR(at0.load_velocity, s.load_velocity, 1e-14);
    EXPECT_NEAR(at0.motor_position, s.motor_position, 1e-14);
    EXPECT_NEAR(at0.motor_velocity, s.motor_velocity, 1e-14);
    for (double tau : {0.3, 1.7, 4.0})
    {
      const double h = 1e-4;
      State a, b, mid;
      m.at(tau - h, &a);
      m.at(tau + h, &b);
      m.at(tau, &mid);
      const double dv = (b.load_velocity - a.load_velocity) / (2 * h);
      const double dw = (b.motor_velocity - a.motor_velocity) / (2 * h);
      EXPECT_NEAR((b.load_position - a.load_position) / (2 * h), mid.load_velocity, 1e-7);
      EXPECT_NEAR((b.motor_position - a.motor_position) / (2 * h), mid.motor_velocity, 1e-7);
      EXPECT_NEAR(p.load_inertia * dv + p.load_friction * mid.load_velocity, 0.0, 1e-7);
      EXPECT_NEAR(p.motor_inertia * dw + p.motor_friction * mid.motor_velocity, in.torque(mid.load_position), 1e-7);
      EXPECT_NEAR(m.gap(tau), mid.load_position - p.gear_ratio * mid.motor_position, 1e-12);
    }
  }
}
