// External load torque T_ext (MODEL.md Part 2; issue 10 item 2): checked against closed forms written here, the
// reference case of ../shared/joint_cases_public.json, conservation of energy, and T_ext = 0 reproducing the servo.
#include <gtest/gtest.h>

#include <cmath>

#include "backlash_servo/modes.h"
#include "backlash_servo/plant.h"
#include "backlash_servo/step_response.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

TEST(LoadTorque, RigidMeshFollowsTheClosedFormStepWithAShiftedEquilibrium)
{
  // Δ = 0: J θ'' + F θ' + ρK θ = ρK θ_R + ρ² T_ext, an underdamped step towards θ_eq = θ_R + ρ T_ext / K.
  ServoParams p;
  p.backlash = 0.0;
  p.gear_ratio = 2.0;
  p.load_torque = -0.15;
  Simulator sim(p, State(), 1.0);
  const double j = p.totalInertia(), f = p.totalFriction(), k = p.gear_ratio * p.gain;
  const double eq = 1.0 + p.gear_ratio * p.load_torque / p.gain;
  const double sigma = f / (2 * j), omega = std::sqrt(k / j - sigma * sigma);
  for (double t : {0.5, 2.0, 7.3, 20.0})
  {
    sim.advanceTo(t);
    const double y0 = -eq;  // θ(0) = 0
    const double x = eq + std::exp(-sigma * t) * (y0 * std::cos(omega * t) + sigma * y0 / omega * std::sin(omega * t));
    EXPECT_NEAR(sim.state().load_position, x, 1e-12) << t;
  }
  EXPECT_NEAR(eq, 1.0 - 0.3, 1e-15);
}

TEST(LoadTorque, ReferenceCasePreloadLargeD1)
{
  // joint_cases_public.json "preload_large_D1": D1 with e = 0.8 and T_ext = −0.3 N·m: the teeth never leave the
  // forward flank, no maxima, converged with steady error ρ T_ext / K = −0.3 rad.
  RunConfig c;
  c.params.restitution = 0.8;
  c.params.load_torque = -0.3;
  c.duration = 300.0;
  struct Flanks : EventSink
  {
    int left = 0;
    void onEvent(const Event& e) override { left += e.type == EventType::Separation || e.type == EventType::Impact; }
  } flanks;
  const RunSummary r = runResponse(c, &flanks);
  EXPECT_EQ(flanks.left, 0);
  EXPECT_TRUE(r.maxima.empty());
  EXPECT_EQ(r.status.verdict, Verdict::Converged);
  EXPECT_NEAR(r.final_state.load_position - 1.0, -0.30000000000000004, 1e-9);
}

TEST(LoadTorque, SeparationsHappenWhereTheMeshTorqueVanishes)
{
  // A load torque large enough to pull the teeth apart against the P law: at every separation the contact mesh
  // torque Q = J_L θc'' + f_L θc' − T_ext evaluated from the state is zero (to rounding).
  for (double text : {0.4, -0.05, 0.9})
  {
    ServoParams p;
    p.load_torque = text;
    p.restitution = 0.7;
    struct Seps : EventSink
    {
      ServoParams p;
      MotorInput law;
      int n = 0;
      double worst = 0.0;
      void onEvent(const Event& e) override
      {
        if (e.type == EventType::Separation && p.backlash > 0.0)
        {
          ++n;
          worst = std::max(worst, std::fabs(contactMeshTorque(p, e.law, e.state.load_position, e.state.load_velocity)));
        }
      }
    } seps;
    seps.p = p;
    Simulator sim(p, State(), 1.0);
    sim.advanceTo(60.0, &seps);
    EXPECT_GT(seps.n, 0) << text;
    EXPECT_LE(seps.worst, 1e-12) << text;
    const double scale = sim.energy().input + std::fabs(sim.energy().load_work) + sim.energy().initial_kinetic;
    EXPECT_LE(std::fabs(sim.energyBalanceError()), 1e-12 * scale) << text;
    EXPECT_NE(sim.energy().load_work, 0.0);
  }
}

TEST(LoadTorque, FloatingLoadFallsUnderItsTorqueExactly)
{
  // Apart, the load alone: J_L ω' + f_L ω = T_ext ⇒ ω = v∞ + (v0 − v∞) e^{−αt}, v∞ = T_ext / f_L; also slow α.
  for (double fl : {0.32, 3e-6, 0.0})
  {
    ServoParams p;
    p.load_friction = fl;
    p.load_torque = 0.05;
    p.backlash = 1000.0;  // the motor never reaches it
    p.gain = 1e-3;
    State s;
    s.contact = Contact::Apart;
    s.load_position = 500.0;
    s.load_velocity = 0.2;
    s.motor_position = 0.0;
    Simulator sim(p, s, 0.0);
    sim.setMotorTorque(0.0);
    sim.advanceTo(5.0);
    const double alpha = fl / p.load_inertia, t = 5.0;
    const double v = fl > 0.0 ? p.load_torque / fl + (0.2 - p.load_torque / fl) * std::exp(-alpha * t)
                              : 0.2 + p.load_torque / p.load_inertia * t;
    // Position: integral of the above, written with expm1 so that the slow case does not cancel.
    const double x = fl > 0.0
                         ? 500.0 + p.load_torque / fl * t - (0.2 - p.load_torque / fl) * std::expm1(-alpha * t) / alpha
                         : 500.0 + 0.2 * t + 0.5 * p.load_torque / p.load_inertia * t * t;
    EXPECT_NEAR(sim.state().load_velocity, v, 1e-12) << fl;
    EXPECT_NEAR(sim.state().load_position, x, fl == 3e-6 ? 1e-8 : 1e-12) << fl;
    // (the reference is itself a difference of positions near 500 rad: its rounding is ~1e-14 J)
    EXPECT_NEAR(sim.energy().load_work, p.load_torque * (sim.state().load_position - 500.0), 1e-13);
  }
}

TEST(LoadTorque, ALoadTurnedRoundInFlightIsAMaximum)
{
  // Apart, a load thrown up against a load torque T < 0 turns round in the air: ω = v∞ + (v0 − v∞) e^{−ατ},
  // v∞ = T/f_L, crosses zero at τ* = ln(1 − v0/v∞)/α, where θ_c = θ0 + v∞τ* + v0/α (without friction: τ* = v0 J_L/(−T),
  // θ_c = θ0 + v0² J_L/(2(−T))). That is a maximum of θ_c (MODEL.md: ω_c from + to −) and must be reported — from a
  // long flight in mid-gap (the closed form) and from a short one leaving the wall (the fast path), before the load
  // falls back onto the motor tooth.
  for (double fl : {0.32, 0.0})
  {
    for (bool short_flight : {false, true})
    {
      ServoParams p;
      p.load_friction = fl;
      p.load_torque = -1.0;
      p.restitution = 0.5;
      p.backlash = 2.0;
      const double v0 = short_flight ? 1e-3 : 0.5;
      State s;
      s.contact = Contact::Apart;
      s.load_position = short_flight ? 0.0 : 1.0;  // on the forward wall (g = 0), or mid-gap
      s.load_velocity = v0;
      s.motor_position = 0.0;
      MotorInput law;  // no motor torque
      Plant plant(p, s, law);
      test_helpers::Recorder rec;
      plant.advanceTo(short_flight ? 0.01 : 1.0, &rec);
      const std::vector<Event> maxima = rec.of(EventType::Maximum);
      ASSERT_EQ(maxima.size(), 1u) << "fl " << fl << (short_flight ? " short" : " long");
      const double jl = p.load_inertia;
      double tau, top;
      if (fl > 0.0)
      {
        const double alpha = fl / jl, v_inf = p.load_torque / fl;
        tau = std::log1p(-v0 / v_inf) / alpha;
        top = s.load_position + v_inf * tau + v0 / alpha;
      }
      else
      {
        tau = v0 * jl / -p.load_torque;
        top = s.load_position + v0 * v0 * jl / (2.0 * -p.load_torque);
      }
      EXPECT_NEAR(maxima[0].state.time, tau, 1e-12 * tau + 1e-15);
      EXPECT_NEAR(maxima[0].state.load_position, top, 1e-13);
      EXPECT_NEAR(maxima[0].state.load_velocity, 0.0, 1e-12 * v0);
      if (short_flight)
      {
        EXPECT_GT(plant.shortFlightCount(), 0u);
      }
    }
  }
}

}  // namespace

namespace
{
TEST(LoadTorque, LevelCrossingSeparationMatchesABruteForceScan)
{
  // The separation of an oscillatory contact with a load torque is where L + e^{−στ}(C cos ωτ + D sin ωτ) first
  // crosses zero: compared with a fine scan of the mesh torque, for many starting phases (a missed first monotone
  // piece once made the rigid mesh flip flanks for ever — fuzz case, seed 11 #31).
  ServoParams p;
  p.load_torque = 0.35;
  p.backlash = 0.2;
  const MotorInput law{p.gain * 1.0, p.gain};
  for (int i = 0; i < 40; ++i)
  {
    const double x0 = -0.5 + 0.05 * i;
    const double v0 = std::sin(1.7 * i);
    const ContactMotion m(p, law, x0, v0);
    for (double side : {1.0, -1.0})
    {
      if (side * m.meshTorque(0.0) <= 0.0)
      {
        continue;  // that flank does not hold here
      }
      const double horizon = 12.0;
      const int n = 200000;
      double scan = INFINITY;
      for (int k = 1; k <= n; ++k)
      {
        if (side * m.meshTorque(horizon * k / n) < 0.0)
        {
          scan = horizon * k / n;
          break;
        }
      }
      const double t = m.separationTime(side, horizon);
      if (std::isinf(scan))
      {
        EXPECT_TRUE(std::isinf(t)) << i << " " << side << " " << t;
      }
      else
      {
        EXPECT_NEAR(t, scan, horizon / n) << i << " " << side;
      }
    }
  }
}
}  // namespace

// A load torque balancing the motor's exactly at the start: the mesh torque and the velocity have no oscillating
// part (constant level), the joint stays where it is. The search for the first critical point of a sinusoid with
// zero amplitude looped for ever before (found by the libFuzzer target: `backlash_sim --load-torque -1`).
TEST(LoadTorque, ABalancedStartStaysAtRestWithoutHanging)
{
  ServoParams p;         // App. D1: K = 1 N·m/rad, unit step from 0 → motor torque 1 N·m
  p.load_torque = -1.0;  // holds the load against it through the forward flank
  Simulator sim(p, State(), 1.0);
  sim.advanceTo(20.0);
  EXPECT_EQ(sim.state().load_position, 0.0);
  EXPECT_EQ(sim.state().load_velocity, 0.0);
  EXPECT_EQ(sim.impactCount(), 0u);
}
