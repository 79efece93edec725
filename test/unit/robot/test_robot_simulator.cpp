// Joints of an arm in one time: against the same joints stepped by hand from one update instant to the next with
// gravity and inertia worked out by hand, and against statics.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "backlash_servo/robot/robot_simulator.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
namespace
{
constexpr double G = 9.80665;
// A two-link arm pitching about y (link 1: m1 at lc1; link 2 from l1: m2 at lc2; inertias about the centres).
constexpr double M1 = 4.0, LC1 = 0.25, L1 = 0.6, I1 = 0.05;
constexpr double M2 = 2.0, LC2 = 0.2, I2 = 0.02;

std::string link(const std::string& name, double m, double lc, double iyy)
{
  return "<link name='" + name + "'><inertial><origin xyz='" + std::to_string(lc) + " 0 0'/><mass value='" +
         std::to_string(m) + "'/><inertia ixx='0.001' iyy='" + std::to_string(iyy) +
         "' izz='0.001' ixy='0' ixz='0' iyz='0'/></inertial></link>";
}

std::string twoLinkArm()
{
  return "<robot name='arm'><link name='base_link'/>" + link("upper", M1, LC1, I1) + link("fore", M2, LC2, I2) +
         "<joint name='shoulder' type='continuous'><parent link='base_link'/><child link='upper'/>"
         "<axis xyz='0 1 0'/></joint>"
         "<joint name='elbow' type='continuous'><parent link='upper'/><child link='fore'/><origin xyz='" +
         std::to_string(L1) + " 0 0'/><axis xyz='0 1 0'/></joint></robot>";
}

/// Gravity's torque on each load, by hand (+q lowers a link lying along +x).
double gravityShoulder(double q1, double q2)
{
  return G * ((M1 * LC1 + M2 * L1) * std::cos(q1) + M2 * LC2 * std::cos(q1 + q2));
}
double gravityElbow(double q1, double q2)
{
  return G * M2 * LC2 * std::cos(q1 + q2);
}
double inertiaShoulder(double q2)
{
  return I1 + M1 * LC1 * LC1 + I2 + M2 * (L1 * L1 + LC2 * LC2 + 2 * L1 * LC2 * std::cos(q2));
}

/// A geared joint under a 1 kHz-class PID on an ideal load encoder: ρ = 0.01, 0.15° of backlash.
RunConfig gearedJoint(double rate, double command, double kp, double ki, double kd)
{
  RunConfig c;
  ServoParams& p = c.params;
  p.motor_inertia = 2e-4;
  p.load_inertia = 1.0;
  p.motor_friction = 1e-3;
  p.load_friction = 0.5;
  p.gear_ratio = 0.01;
  p.backlash = 0.0026;
  p.restitution = 0.3;
  p.gain = kp;
  c.drive.control_law = "pid";
  c.drive.controller_rate = rate;
  c.drive.integral_gain = ki;
  c.drive.derivative_gain = kd;
  c.command = command;
  c.initial.load_position = command;  // starts at its set-point; gravity takes it from there
  c.initial.motor_position = command / p.gear_ratio;
  return c;
}

void expectSameState(const State& a, const State& b, double tol)
{
  EXPECT_NEAR(a.load_position, b.load_position, tol);
  EXPECT_NEAR(a.motor_position, b.motor_position, tol / 0.01);
  EXPECT_NEAR(a.load_velocity, b.load_velocity, tol * 100);
  EXPECT_NEAR(a.motor_velocity, b.motor_velocity, tol * 1e4);
  EXPECT_EQ(a.contact, b.contact);
}

TEST(RobotSimulator, EachJointFollowsTheArmsLoadUpdatedAtItsOwnSamples)
{
  // Shoulder at 1 kHz takes gravity and inertia from the arm, elbow at 400 Hz gravity only: the union of the two
  // sample grids, by hand, with the two-link arm's gravity and M_11 worked out by hand.
  const ArmModel arm(twoLinkArm());
  RobotJoint shoulder{"shoulder", "shoulder_motor", gearedJoint(1000.0, 0.3, 30.0, 60.0, 1.0), true, true};
  RobotJoint elbow{"elbow", "elbow_motor", gearedJoint(400.0, -0.5, 30.0, 60.0, 1.0), true, false};
  RobotSimulator robot({shoulder, elbow}, &arm, 1e-3);
  EXPECT_NEAR(robot.loadTorque(0), gravityShoulder(0.3, -0.5), 1e-10);
  EXPECT_NEAR(robot.loadInertia(0), inertiaShoulder(-0.5), 1e-12);
  EXPECT_NEAR(robot.loadTorque(1), gravityElbow(0.3, -0.5), 1e-10);
  EXPECT_EQ(robot.loadInertia(1), 1.0);  // its own constant

  RunConfig s = shoulder.run, e = elbow.run;
  s.params.load_torque = gravityShoulder(0.3, -0.5);
  s.params.load_inertia = inertiaShoulder(-0.5);
  e.params.load_torque = gravityElbow(0.3, -0.5);
  Simulator ref_s = makeSimulator(s), ref_e = makeSimulator(e);
  long ks = 0, ke = 0;
  const double end = 2.0;
  for (;;)
  {
    const double ts = (ks + 1) / 1000.0, te = (ke + 1) / 400.0, t = std::min(ts, te);
    if (t > end)
    {
      break;
    }
    ref_s.advanceTo(t);
    ref_e.advanceTo(t);
    const double q1 = ref_s.state().load_position, q2 = ref_e.state().load_position;
    if (ts == t)
    {
      ServoParams p = ref_s.params();
      p.load_torque = gravityShoulder(q1, q2);
      p.load_inertia = inertiaShoulder(q2);
      ref_s.setParams(p);
      ++ks;
    }
    if (te == t)
    {
      ServoParams p = ref_e.params();
      p.load_torque = gravityElbow(q1, q2);
      ref_e.setParams(p);
      ++ke;
    }
  }
  ref_s.advanceTo(end);
  ref_e.advanceTo(end);
  robot.advanceTo(1.2345);  // any stops in between change nothing
  robot.advanceTo(end);
  EXPECT_EQ(robot.time(), end);
  expectSameState(robot.joint(0).state(), ref_s.state(), 1e-9);
  expectSameState(robot.joint(1).state(), ref_e.state(), 1e-9);
  EXPECT_EQ(robot.joint(0).impactCount(), ref_s.impactCount());
  EXPECT_EQ(robot.joint(1).impactCount(), ref_e.impactCount());
  EXPECT_GT(ref_s.impactCount() + ref_e.impactCount(), 0u);  // the joints did cross their backlash
  EXPECT_NEAR(robot.loadInertia(0), ref_s.params().load_inertia, 1e-12);
  EXPECT_NE(robot.loadInertia(0), inertiaShoulder(-0.5));  // the elbow moved: the shoulder's inertia followed
}

TEST(RobotSimulator, AHeldPoseBalancesGravityThroughTheGear)
{
  // A PID with integral action holds each joint at its command: at rest the motor's torque carries the load's
  // gravity through the gear, T_m = −ρ T_gravity(q), and the teeth rest on the flank gravity presses them to.
  const ArmModel arm(twoLinkArm());
  RobotSimulator robot({{"shoulder", "m1", gearedJoint(1000.0, 0.3, 30.0, 60.0, 1.0), true, true},
                        {"elbow", "m2", gearedJoint(1000.0, -0.5, 30.0, 60.0, 1.0), true, false}},
                       &arm, 1e-3);
  robot.advanceTo(30.0);
  const double q1 = robot.joint(0).state().load_position, q2 = robot.joint(1).state().load_position;
  EXPECT_NEAR(q1, 0.3, 1e-4);
  EXPECT_NEAR(q2, -0.5, 1e-4);
  EXPECT_NEAR(robot.joint(0).motorTorque(), -0.01 * gravityShoulder(q1, q2), 1e-3 * 0.01 * gravityShoulder(q1, q2));
  EXPECT_NEAR(robot.joint(1).motorTorque(), -0.01 * gravityElbow(q1, q2), 1e-3 * 0.01 * gravityElbow(q1, q2));
  // Gravity pulls both loads towards +q (cos > 0 here): the load leans on the motor's gear from above, the gap at Δ.
  EXPECT_EQ(robot.joint(0).state().contact, Contact::Backward);
  EXPECT_EQ(robot.joint(1).state().contact, Contact::Backward);
  // Settling took a few impacts; the load updated at every sample did not part the teeth each time.
  EXPECT_LT(robot.joint(0).impactCount() + robot.joint(1).impactCount(), 100u);
}

TEST(RobotSimulator, JointsWithoutTheArmRunAsSingleJoints)
{
  // No arm load: each joint is exactly the single joint (same closed form, same stops).
  const RunConfig a = gearedJoint(1000.0, 0.2, 400.0, 800.0, 40.0);
  RunConfig b = gearedJoint(250.0, 0.0, 60.0, 100.0, 4.0);
  b.params.load_torque = -2.0;
  RobotSimulator robot({{"a", "am", a, false, false}, {"b", "bm", b, false, false}}, nullptr, 1e-3);
  robot.advanceTo(3.0);
  Simulator ra = makeSimulator(a), rb = makeSimulator(b);
  ra.advanceTo(3.0);
  rb.advanceTo(3.0);
  expectSameState(robot.joint(0).state(), ra.state(), 0.0);
  expectSameState(robot.joint(1).state(), rb.state(), 0.0);
}

TEST(RobotSimulator, RefusesJointsItCannotPlace)
{
  const ArmModel arm(twoLinkArm());
  const RunConfig j = gearedJoint(1000.0, 0.0, 400.0, 800.0, 40.0);
  const auto refused = [](auto make, const std::string& says) {
    try
    {
      make();
      ADD_FAILURE() << "accepted; expected: " << says;
    }
    catch (const std::invalid_argument& e)
    {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused(
      [&] {
        RobotSimulator({{"wrist", "m", j, true, false}}, &arm, 1e-3);
      },
      "'wrist' takes its load from the arm, but the robot description has no movable joint 'wrist'");
  refused([&] { RobotSimulator({{"elbow", "m", j, true, false}}, nullptr, 1e-3); }, "no robot description is given");
  refused(
      [&] {
        RobotSimulator({{"elbow", "m", j, false, false}, {"elbow", "n", j, false, false}}, &arm, 1e-3);
      },
      "'elbow' is given twice");
  refused([&] { RobotSimulator({}, &arm, 1e-3); }, "at least one joint");
  refused([&] { RobotSimulator({{"elbow", "m", j, true, false}}, &arm, 0.0); }, "update_period: must be > 0 s");
}
}  // namespace
}  // namespace backlash_servo
