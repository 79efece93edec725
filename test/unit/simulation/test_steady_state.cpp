// The steady answer of a converged joint (steady_state.h) against closed forms, an independent reference case and
// brute force (the same joint run on much longer); the tracking figures of the run's own pass against the replay.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

using namespace backlash_servo;

namespace
{
/// Where the same joint is after `duration` [s], run with a fixed duration (brute force: no steady answer read).
double loadAfter(RunConfig c, double duration)
{
  c.duration = duration;
  c.steady_answer = false;
  return runResponse(c).final_state.load_position;
}

/// The P law's rest position of the load from the torque balance at rest, written out here: the motor holds the load
/// torque through the gear, K(θ_R − θ_c) = −ρ T_ext.
double pLawRest(const ServoParams& p, double command)
{
  return command + p.gear_ratio * p.load_torque / p.gain;
}

void expectBitEqual(double a, double b, const char* what)
{
  EXPECT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << what << ": " << a << " vs " << b;
}
}  // namespace

// The thesis' D1 servo, e = 0.8, under −0.3 N·m: the run stops by the state rule while the load is still 2.6e-6 rad
// short of its rest; the steady error is the rest's, −0.3, not that offset.
TEST(Steady, TheD1ServoUnderALoadTorqueReportsItsEquilibriumNotTheOffsetAtTheStop)
{
  RunConfig c;
  c.params.restitution = 0.8;
  c.params.load_torque = -0.3;
  const RunSummary r = runResponse(c);
  ASSERT_EQ(r.status.verdict, Verdict::Converged);
  EXPECT_EQ(r.steady.basis, SteadyBasis::Equilibrium);
  EXPECT_NEAR(r.steady.error, -0.3, 1e-12 * 0.3);
  EXPECT_NEAR(r.steady.position, pLawRest(c.params, 1.0), 1e-15);
  EXPECT_GT(std::fabs((r.final_state.load_position - 1.0) - (-0.3)), 1e-7);  // the offset where it stopped
  EXPECT_NEAR(loadAfter(c, 400.0), r.steady.position, 1e-12);
}

// A compliant robot joint under the continuous P law, still ringing down in contact when it is called converged:
// its steady error is ρT_ext/K = −0.00333 rad (the offset at the stop was −0.00121 rad).
TEST(Steady, ACompliantRobotJointRingingInContactReportsItsEquilibrium)
{
  RunConfig c;
  ServoParams& p = c.params;
  p = test_helpers::compliantRobotJoint();  // with more friction, a softer mesh and a load torque:
  p.motor_friction = 2e-4;
  p.load_friction = 1.0;
  p.load_torque = -2.0;
  p.mesh_stiffness = 1e4;
  p.mesh_damping = 8.585787;
  c.command = 0.5;
  const RunSummary r = runResponse(c);
  ASSERT_EQ(r.status.verdict, Verdict::Converged);
  EXPECT_EQ(r.steady.basis, SteadyBasis::Equilibrium);
  const double expected = 0.01 * -2.0 / 6.0;
  EXPECT_NEAR(r.steady.error, expected, 1e-12 * std::fabs(expected));
  EXPECT_GT(std::fabs(r.final_state.load_position - 0.5 - expected), 1e-4);
  EXPECT_NEAR(loadAfter(c, 200.0), pLawRest(p, 0.5), 1e-10);
}

// A compliant mesh pressed by a load torque, with and without a torsional shaft: the mesh and the shaft deflect, the
// load rests where the P law balances the load torque.
TEST(Steady, ACompliantMeshPressedByALoadTorqueRestsAtTheLawsBalanceWithAndWithoutAShaft)
{
  for (const double shaft : {0.0, 100.0})
  {
    RunConfig c;
    c.params = test_helpers::compliantD1();
    c.params.load_torque = -0.05;
    c.params.shaft_stiffness = shaft;
    c.params.shaft_damping = shaft > 0.0 ? 1.0 : 0.0;
    c.params.gear_inertia = shaft > 0.0 ? 0.01 : 0.0;  // (the output gear between the mesh and the shaft)
    const RunSummary r = runResponse(c);
    ASSERT_EQ(r.status.verdict, Verdict::Converged) << "shaft " << shaft;
    EXPECT_EQ(r.steady.basis, SteadyBasis::Equilibrium);
    EXPECT_NEAR(r.steady.error, -0.05, 1e-12 * 0.05) << "shaft " << shaft;
    EXPECT_NEAR(loadAfter(c, 300.0), pLawRest(c.params, 1.0), 1e-10) << "shaft " << shaft;
  }
}

// A joint held by dry friction off its equilibrium: the position it is held at, exact — it never moves again.
TEST(Steady, AJointHeldByDryFrictionReportsThePositionItIsHeldAt)
{
  RunConfig c;
  c.params.restitution = 0.5;
  c.params.load_coulomb_friction = 0.2;
  c.params.load_static_friction = 0.2;
  const RunSummary r = runResponse(c);
  ASSERT_EQ(r.status.verdict, Verdict::Converged);
  EXPECT_EQ(r.steady.basis, SteadyBasis::Held);
  EXPECT_EQ(r.steady.position, r.final_state.load_position);
  EXPECT_EQ(r.steady.error, r.final_state.load_position - 1.0);
  EXPECT_GT(std::fabs(r.steady.error), 1e-4);  // held off θ_R: the P law alone would not rest there
  EXPECT_EQ(loadAfter(c, r.simulated + 1000.0), r.steady.position);
}

// The reference case pid_motor_semi (an independent exact implementation of docs/model.md): a PID on the motor's
// angle, the load held by its dry friction where the backlash left it. The law has no closed-form rest of the
// load: the run goes on in a copy until it is within rounding of it — the reference's 0.009254792639264986 rad.
TEST(Steady, AJointWithoutAClosedFormRestRunsOnToItsLimit)
{
  RunConfig c;
  c.params.backlash = 0.05;
  c.params.restitution = 0.5;
  c.params.load_coulomb_friction = 0.02;
  c.params.load_static_friction = 0.05;
  c.drive.controller_rate = 1000.0;
  c.drive.control_law = "pid";
  c.drive.feedback = "motor";
  c.drive.integral_gain = 0.3;
  c.drive.derivative_gain = 0.3;
  c.duration = 600.0;
  const RunSummary r = runResponse(c);
  ASSERT_EQ(r.status.verdict, Verdict::Converged);
  EXPECT_TRUE(r.steady.basis == SteadyBasis::Limit || r.steady.basis == SteadyBasis::Held) << r.steady.note;
  EXPECT_NEAR(r.steady.error, 0.009254792639264986, 1e-12);
}

// Not converged: no steady answer, whatever the load's offset at the end.
TEST(Steady, ALimitCycleHasNoSteadyAnswer)
{
  RunConfig c;  // the thesis' limit-cycle case (e = 1)
  const RunSummary r = runResponse(c);
  ASSERT_EQ(r.status.verdict, Verdict::LimitCycle);
  EXPECT_EQ(r.steady.basis, SteadyBasis::None);
  EXPECT_TRUE(std::isnan(r.steady.error));
}

// The tracking figures gathered in the run's own pass are replayTracking()'s, bit for bit, and the run itself is
// unchanged by the sampling: continuous and digital laws, until settled and for a fixed duration (one long enough to
// lower the rate), a compliant mesh, a profile.
TEST(Steady, TheTrackingFiguresOfTheRunsOwnPassAreTheReplaysBitForBit)
{
  std::vector<RunConfig> configs(7);
  configs[1].params.restitution = 0.8;
  configs[1].params.load_torque = -0.3;
  configs[2].duration = 1e5;  // 100 samples a natural period would be 1.6e6: lowered to 1e6
  configs[3].params = test_helpers::compliantD1();
  configs[4].drive.controller_rate = 1000.0;
  configs[4].drive.control_law = "pid";
  configs[4].drive.integral_gain = 0.2;
  configs[4].drive.load_encoder_resolution = 4096;
  configs[4].params.restitution = 0.5;
  configs[5] = configs[4];
  configs[5].duration = 50.0;
  ProfileSegment ramp;
  ramp.kind = ProfileSegment::Kind::Ramp;
  ramp.time = 1.0;
  ramp.target = 1.0;
  ramp.duration = 5.0;
  configs[6].params.restitution = 0.6;
  configs[6].profile = std::make_shared<const CommandProfile>(0.0, std::vector<ProfileSegment>{ramp});
  configs[6].command = 1.0;
  for (std::size_t i = 0; i < configs.size(); ++i)
  {
    RunConfig plain = configs[i];
    RunConfig tracked = configs[i];
    tracked.tracking = true;
    const RunSummary a = runResponse(plain);
    const RunSummary b = runResponse(tracked);
    double rate = 0.0;
    const TrackingFigures want = replayTracking(plain, a, &rate);
    SCOPED_TRACE("config " + std::to_string(i));
    EXPECT_EQ(b.tracking_rate, rate);
    expectBitEqual(b.tracking.settling_time, want.settling_time, "settling_time");
    expectBitEqual(b.tracking.rms_error, want.rms_error, "rms_error");
    expectBitEqual(b.tracking.steady_rms_error, want.steady_rms_error, "steady_rms_error");
    expectBitEqual(b.tracking.max_error, want.max_error, "max_error");
    expectBitEqual(b.tracking.overshoot, want.overshoot, "overshoot");
    expectBitEqual(b.tracking.peak_torque, want.peak_torque, "peak_torque");
    expectBitEqual(b.tracking.rms_torque, want.rms_torque, "rms_torque");
    expectBitEqual(b.tracking.band, want.band, "band");
    EXPECT_EQ(a.status.verdict, b.status.verdict);
    EXPECT_EQ(a.simulated, b.simulated);
    EXPECT_EQ(a.impacts, b.impacts);
    EXPECT_EQ(a.maxima.size(), b.maxima.size());
    EXPECT_EQ(a.final_state.load_position, b.final_state.load_position);
    EXPECT_EQ(a.final_state.motor_velocity, b.final_state.motor_velocity);
    expectBitEqual(a.steady.error, b.steady.error, "steady error");
  }
}
