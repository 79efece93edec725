// Never crash, hang or lie, in the core: live changes that could stall the simulator, overflowing
// inputs, impact storms.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "backlash_servo/simulation/simulator.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

TEST(Robustness, BacklashTunedToZeroWhileTheTeethFloatIsALegalTransition)
{
  // Before: "Simulator made no progress" (the teeth ping-ponged between two walls that had become one).
  for (double e : {1.0, 0.6, 0.0})
  {
    for (double t_change : {2.0, 2.5, 3.3, 9.0, 14.2})
    {
      ServoParams p;
      p.restitution = e;
      Simulator sim(p, State(), 1.0);
      sim.advanceTo(t_change);
      const bool was_apart = sim.state().contact == Contact::Apart;
      ServoParams rigid = p;
      rigid.backlash = 0.0;
      ASSERT_NO_THROW(sim.setParams(rigid)) << e << " " << t_change;
      EXPECT_NE(sim.state().contact, Contact::Apart);
      // A rigid mesh moves as one body: no relative velocity is left after the (plastic) closing.
      EXPECT_NEAR(sim.state().load_velocity, p.gear_ratio * sim.state().motor_velocity, 1e-12);
      ASSERT_NO_THROW(sim.advanceTo(t_change + 30.0));
      EXPECT_NEAR(sim.gap(), 0.0, 1e-12);
      const double scale = sim.energy().input + sim.energy().initial_kinetic;
      EXPECT_LE(std::fabs(sim.energyBalanceError()), 1e-12 * scale) << e << " " << t_change;
      if (was_apart)
      {
        EXPECT_GT(sim.energy().impact_loss, 0.0) << "closing a floating gap at once dissipates";
      }
      // ... and back: the teeth float again once there is play.
      ASSERT_NO_THROW(sim.setParams(p));
      ASSERT_NO_THROW(sim.advanceTo(t_change + 60.0));
    }
  }
}

TEST(Robustness, AnOverflowingMotionIsAnErrorNotACrash)
{
  // Before: unbounded recursion (segfault) in the root isolation once the coefficients were NaN.
  ServoParams p;
  State s;
  s.load_velocity = 1e308;
  s.motor_velocity = 1e308;
  Simulator sim(p, s, 1.0);
  EXPECT_THROW(sim.advanceTo(1.0), std::exception);
}

TEST(Robustness, TheEventBudgetStopsAnImpactStorm)
{
  // A light load dribbled by a heavy motor: tens of thousands of impacts per simulated second (physical chatter).
  Simulator sim(test_helpers::chart(0.2, 0.04, 0.8, 1.0), State(), 1.0);
  sim.setEventBudget(2000);
  EXPECT_THROW(sim.advanceTo(100.0), EventBudgetExceeded);
  EXPECT_EQ(sim.impactCount(), 2001u);
}

TEST(Robustness, HowARunIsCutIntoStepsChangesNotOneBit)
{
  // The closed form of a segment stays anchored at the segment's start, so output samples and node ticks do not
  // re-base it: the same events and the same final state, bit for bit, for any cutting. The third case is elastic
  // chatter (a light load, ~17 000 impacts in 10 s): uncut, its flights run in the plant's chatter loop, cut every
  // millisecond that loop hands the flight crossing each step to a segment — the two must still agree to the bit.
  struct Case
  {
    ServoParams params;
    double duration;  // [s]
  };
  for (const Case& c :
       {Case{test_helpers::chart(0.4, 9.0, 0.4, 1.0), 60.0}, Case{test_helpers::chart(0.4, 9.0, 0.4, 0.6), 60.0},
        Case{test_helpers::chart(0.3, 0.04, 1.0, 1.0), 10.0}})
  {
    const ServoParams& p = c.params;
    const double end = c.duration;
    Simulator whole(p, State(), 1.0);
    test_helpers::Recorder a;
    whole.advanceTo(end, &a);
    Simulator steps(p, State(), 1.0);
    test_helpers::Recorder b;
    const int n = static_cast<int>(std::lround(end * 1e3));
    for (int i = 1; i <= n; ++i)
    {
      steps.advanceTo(i == n ? end : std::min(end, i * 1e-3), &b);
    }
    if (p.load_inertia < 0.1)
    {
      EXPECT_GT(whole.impactCount(), 10000u) << "not the chatter the case is for";
    }
    EXPECT_EQ(whole.impactCount(), steps.impactCount());
    ASSERT_EQ(a.events.size(), b.events.size());
    for (std::size_t i = 0; i < a.events.size(); ++i)
    {
      EXPECT_EQ(a.events[i].state.time, b.events[i].state.time) << i;
      EXPECT_EQ(a.events[i].state.load_position, b.events[i].state.load_position) << i;
    }
    EXPECT_EQ(whole.state().load_position, steps.state().load_position);
    EXPECT_EQ(whole.state().motor_velocity, steps.state().motor_velocity);
    EXPECT_EQ(whole.energy().input, steps.energy().input);
  }
}

}  // namespace

namespace
{
TEST(Robustness, RigidMeshWithALoadTorqueDoesNotFlipFlanksForEver)
{
  // Regression: Δ = 0, a large load torque, the mesh torque at rounding level. The level-crossing
  // search skipped its first monotone piece and reported a separation at τ = 0 on the flank that holds; the two
  // flanks then took turns for ever ("made no progress").
  ServoParams p;
  p.motor_inertia = 0.29429766605145347;
  p.load_inertia = 25.890763837608279;
  p.motor_friction = 0.0025343175909771851;
  p.load_friction = 0.01206889133010744;
  p.gain = 0.088359281940251111;
  p.gear_ratio = 0.11447054780407151;
  p.backlash = 0.0;
  p.restitution = 0.079410606104206055;
  p.load_torque = -990.36509081817815;
  State s;
  s.load_velocity = 418.50929608758037;
  s.motor_velocity = 3656.0434462487542;
  Simulator sim(p, s, -5338.1883777535932);
  EXPECT_NO_THROW(sim.advanceTo(994.5));
  EXPECT_LE(std::fabs(sim.energyBalanceError()),
            1e-9 * (std::fabs(sim.energy().input) + sim.energy().initial_kinetic + std::fabs(sim.energy().load_work)));
}

TEST(Robustness, RigidMeshWhoseMeshTorqueCrossesZeroWithinTheClockTakesTheOtherFlank)
{
  // A rigid mesh (Δ = 0) under a digital drive or dry friction, as random joints meet it: the mesh torque crosses
  // zero within the clock's resolution; the segment on the flank it leaves ends at once, while the contact test on
  // the other flank still sees the old sign (1e-14 N·m, above its rounding) — the flanks took turns at one instant.
  ServoParams p;
  p.motor_inertia = 0.019615907787737769;
  p.load_inertia = 0.023648793528116191;
  p.motor_friction = 1.4913874599777572;
  p.load_friction = 1490.1542458770032;
  p.gain = 65247.53429368083;
  p.gear_ratio = 0.035187866633468283;
  p.backlash = 0.0;
  p.restitution = 0.99999999999900002;
  State s;
  s.load_position = 1.9522140477248004;
  s.load_velocity = 2448.5359362387712;
  s.motor_position = 55.479750109885565;
  s.motor_velocity = 69584.66569581379;
  DriveParams d;
  d.controller_rate = 1238.4838717976791;
  d.feedback = "motor";
  const double command = -1.853828144061213;
  Simulator sim(p, s, command);
  sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, command, 0.0));
  const double duration = 0.36758641549514975;
  for (int i = 1; i <= 1000; ++i)
  {
    ASSERT_NO_THROW(sim.advanceTo(duration * i / 1000.0)) << "step " << i;
  }
  EXPECT_NE(sim.state().contact, Contact::Apart);
}
}  // namespace
