// Dry friction on a compliant joint (compliant_joint.h): stick, slip and breakaway against closed forms written here —
// a load sliding to rest under Coulomb and viscous friction, a motor pressing a stuck load through the mesh spring
// (the load breaks away exactly where the mesh torque reaches its static band) — the energy ledger, chunk-independence
// with stick phases, and the rigid limit: as the mesh stiffens, the joint comes to rest where the rigid one does.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "backlash_servo/drive/drive.h"
#include "backlash_servo/simulation/simulator.h"
#include "compliant/compliant_joint.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

using test_helpers::compliantD1;

struct Seen
{
  MeshEvent kind;
  int which;
  double time;
  double mesh_torque;
};

TEST(CompliantFriction, ALoadSlidingInTheFreePlayStopsWhereCoulombAndViscousFrictionSayAndStaysThere)
{
  ServoParams p = compliantD1();
  p.backlash = 1.0;
  p.load_coulomb_friction = p.load_static_friction = 0.2;
  CompliantJoint joint(p, MotorInput{});
  Eigen::VectorXd x(4);
  x << 0.0, 0.0, 0.25, 0.3;  // motor at rest, the load in the free play at 0.3 rad/s
  joint.setState(x);
  std::vector<Seen> seen;
  const auto observe = [&](MeshEvent e, int which) { seen.push_back({e, which, joint.time(), joint.meshTorque()}); };
  joint.advanceTo(3.0, observe);
  // J ω̇ = −f ω − T: ω = (ω₀ + T/f) e^{−ft/J} − T/f stops at t* = (J/f) ln(1 + fω₀/T), having gone
  // (J/f)(ω₀ − (T/f) ln(1 + fω₀/T)).
  const double j = 0.9, f = 0.32, t = 0.2, w0 = 0.3;
  const double log_term = std::log1p(f * w0 / t);
  const double stop = j / f * log_term, travel = j / f * (w0 - t / f * log_term);
  ASSERT_EQ(seen.size(), 2u);  // the load's maximum and its stop, at one instant
  EXPECT_EQ(seen[0].kind, MeshEvent::Maximum);
  EXPECT_EQ(seen[1].kind, MeshEvent::Stop);
  EXPECT_EQ(seen[1].which, static_cast<int>(Body::Load));
  EXPECT_NEAR(seen[1].time, stop, 1e-12 * stop);
  EXPECT_EQ(joint.slide(Body::Load), 0);
  const double rest = joint.state()(2);
  EXPECT_NEAR(rest, 0.25 + travel, 1e-12);
  EXPECT_EQ(joint.state()(3), 0.0);
  // The ledger: T·travel to dry friction, the rest of the kinetic energy to viscous friction.
  EXPECT_NEAR(joint.energy().load_dry_friction, t * travel, 1e-14);
  EXPECT_NEAR(joint.energy().load_friction, 0.5 * j * w0 * w0 - t * travel, 1e-14);
  EXPECT_LT(std::fabs(joint.energyBalanceError()), 1e-15);
  // Stuck for good: nothing pushes it (the motor stands, the mesh is apart).
  joint.advanceTo(50.0, observe);
  EXPECT_EQ(seen.size(), 2u);
  EXPECT_EQ(joint.state()(2), rest);
  EXPECT_EQ(joint.state()(3), 0.0);
  EXPECT_EQ(joint.state()(0), 0.0);
}

/// The first time [s] the mesh torque Q = cθ + dθ̇ of a motor (J, f) stepped by torque a against a fixed load
/// (touching at rest, ρ = 1) reaches `level`, from the closed form of the damped oscillator; +inf if never.
double firstReach(double j, double f, double c, double d, double a, double level)
{
  const double w0 = std::sqrt(c / j), zeta = (f + d) / (2.0 * std::sqrt(c * j));
  const double wd = w0 * std::sqrt(1.0 - zeta * zeta), s = a / c;
  const auto q = [&](double t) {
    const double e = std::exp(-zeta * w0 * t);
    const double theta = s * (1.0 - e * (std::cos(wd * t) + zeta * w0 / wd * std::sin(wd * t)));
    const double rate = s * e * w0 * w0 / wd * std::sin(wd * t);
    return c * theta + d * rate - level;
  };
  const double dt = 1e-3 / wd;
  for (double t = 0.0; t < 100.0 / (zeta * w0); t += dt)
  {
    if (q(t) < 0.0 && q(t + dt) >= 0.0)
    {
      double lo = t, hi = t + dt;
      for (int i = 0; i < 200 && hi - lo > 0.0; ++i)
      {
        const double mid = 0.5 * (lo + hi);
        (q(mid) < 0.0 ? lo : hi) = mid;
      }
      return hi;
    }
  }
  return INFINITY;
}

TEST(CompliantFriction, AStuckLoadBreaksAwayExactlyWhereTheMeshTorqueReachesItsStaticBand)
{
  ServoParams p = compliantD1();
  p.mesh_damping = 1.0;  // a lightly damped contact: the motor's step overshoots to almost twice its steady torque
  p.load_coulomb_friction = 0.5;
  p.load_static_friction = 1.0;
  const double j = p.motor_inertia, f = p.motor_friction, c = p.mesh_stiffness, d = p.mesh_damping;
  for (double push : {0.45, 0.6})
  {
    SCOPED_TRACE(push);
    const double reach = firstReach(j, f, c, d, push, p.load_static_friction);
    CompliantJoint joint(p, MotorInput{push, 0.0});  // effort: a constant motor torque [N·m]
    std::vector<Seen> seen;
    joint.advanceTo(5.0, [&](MeshEvent e, int which) { seen.push_back({e, which, joint.time(), joint.meshTorque()}); });
    const auto breakaway =
        std::find_if(seen.begin(), seen.end(), [](const Seen& s) { return s.kind == MeshEvent::Breakaway; });
    if (!std::isfinite(reach))
    {
      // Held: the peak mesh torque (under 2 × 0.45 N·m) stays inside the static band; the load never moves and the
      // motor settles on the spring, y = a/c.
      EXPECT_EQ(breakaway, seen.end());
      EXPECT_EQ(joint.slide(Body::Load), 0);
      EXPECT_EQ(joint.state()(2), 0.0);
      EXPECT_EQ(joint.state()(3), 0.0);
      EXPECT_NEAR(joint.state()(0), push / c, 1e-12);
      EXPECT_NEAR(joint.meshTorque(), push, 1e-9);
      continue;
    }
    ASSERT_NE(breakaway, seen.end());
    EXPECT_EQ(breakaway->which, static_cast<int>(Body::Load));
    EXPECT_NEAR(breakaway->time, reach, 1e-12);
    EXPECT_NEAR(breakaway->mesh_torque, p.load_static_friction, 1e-9);
    EXPECT_LT(std::fabs(joint.energyBalanceError()), 1e-12);
  }
}

/// The robot joint of config/compare_compliant.yaml (100:1 gear, 5 mrad backlash, c = 8.6e4 N·m/rad, 1 kHz PID on
/// the load) with stick–slip on both bodies, stepped to 0.1 rad.
Simulator stickSlipJoint()
{
  ServoParams p = test_helpers::compliantRobotJoint();
  p.motor_coulomb_friction = 0.002;
  p.motor_static_friction = 0.003;
  p.load_coulomb_friction = 0.3;
  p.load_static_friction = 0.4;
  DriveParams d;
  d.controller_rate = 1000.0;
  d.control_law = "pid";
  d.integral_gain = 30.0;
  d.derivative_gain = 0.4;
  Simulator sim(p, State(), 0.1);
  sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, 0.1, 0.0));
  return sim;
}

TEST(CompliantFriction, StickSlipUnderASampledPIDKeepsTheLedgerAndCutsNothing)
{
  Simulator whole = stickSlipJoint();
  struct Count : EventSink
  {
    int rests = 0;
    void onEvent(const Event& e) override { rests += e.type == EventType::Rest; }
  } count;
  whole.advanceTo(2.0, &count);
  EXPECT_GT(count.rests, 2);  // it sticks and slips
  const EnergyLedger& e = whole.plant().energy();
  EXPECT_GT(e.motor_dry_friction, 0.0);
  EXPECT_GT(e.load_dry_friction, 0.0);
  EXPECT_LT(std::fabs(whole.plant().energyBalanceError()), 1e-9 * (e.input_magnitude + 1e-12));
  Simulator chunked = stickSlipJoint();
  for (double t = 0.0137; t < 2.0; t += 0.0137)
  {
    chunked.advanceTo(t);
  }
  chunked.advanceTo(2.0);
  EXPECT_EQ(chunked.state().load_position, whole.state().load_position);
  EXPECT_EQ(chunked.state().motor_position, whole.state().motor_position);
  EXPECT_EQ(chunked.state().motor_velocity, whole.state().motor_velocity);
}

TEST(CompliantFriction, AsTheMeshStiffensTheJointComesToRestWhereTheRigidOneDoes)
{
  // D1 under the continuous P law with Coulomb friction on the load: it sticks off the command. The rigid joint
  // (restitution 0.8) against compliant meshes of the same contact damping ratio (ζ_c = 0.0744).
  ServoParams p;
  p.restitution = 0.8;
  p.load_coulomb_friction = 0.05;
  p.load_static_friction = 0.08;
  Simulator rigid(p, State(), 1.0);
  rigid.advanceTo(30.0);
  ASSERT_TRUE(rigid.atRestForever());
  const double rest = rigid.state().load_position;
  ASSERT_GT(std::fabs(rest - 1.0), 1e-3);  // off the command
  std::vector<double> error;
  for (double c : {1e4, 1e5, 1e6})
  {
    ServoParams q = p;
    q.restitution = 1.0;
    q.mesh_stiffness = c;
    q.mesh_damping = 2.0 * 0.0744 * std::sqrt(c * 0.09);
    Simulator soft(q, State(), 1.0);
    soft.advanceTo(30.0);
    EXPECT_EQ(soft.plant().state().load_velocity, 0.0);
    error.push_back(std::fabs(soft.state().load_position - rest));
  }
  // Each tenfold stiffness brings the rest point closer (about √10: the contact phases last ∝ 1/√c).
  EXPECT_LT(error[1], 0.5 * error[0]);
  EXPECT_LT(error[2], 0.5 * error[1]);
  EXPECT_LT(error[2], 2e-5);
}

}  // namespace
