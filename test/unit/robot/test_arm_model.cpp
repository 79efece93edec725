// The arm's dynamics from a URDF against a two-link arm in a vertical plane worked by hand (Lagrange's equations).
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "backlash_servo/robot/arm_model.h"

namespace backlash_servo
{
namespace
{
constexpr double G = 9.80665;
// Two links swinging about y (pitch): link 1 (m1, centre lc1 along x, I1 about its centre), link 2 from x = l1
// (m2, lc2, its inertia given in a frame turned 90° about z: ixx is the one about the link's y axis).
constexpr double M1 = 3.0, LC1 = 0.2, L1 = 0.5, I1 = 0.04;
constexpr double M2 = 1.5, LC2 = 0.15, I2 = 0.01, I2_OTHER = 0.003;

std::string twoLinkArm(const std::string& extra = "")
{
  return R"(<?xml version="1.0"?>
<robot name="two_link">
  <link name="base_link"/>
  <link name="upper">
    <inertial><origin xyz=")" +
         std::to_string(LC1) + R"( 0 0"/><mass value=")" + std::to_string(M1) + R"("/><inertia ixx="0.001" iyy=")" +
         std::to_string(I1) + R"(" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="fore">
    <inertial><origin xyz=")" +
         std::to_string(LC2) + R"( 0 0" rpy="0 0 1.5707963267948966"/><mass value=")" + std::to_string(M2) +
         R"("/><inertia ixx=")" + std::to_string(I2) + R"(" iyy=")" + std::to_string(I2_OTHER) +
         R"(" izz="0.002" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base_link"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="80" velocity="1.5"/>
  </joint>
  <joint name="elbow" type="continuous">
    <parent link="upper"/><child link="fore"/><origin xyz=")" +
         std::to_string(L1) + R"( 0 0"/><axis xyz="0 1 0"/>
  </joint>
  <transmission name="shoulder_trans">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="shoulder"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="shoulder_motor"><mechanicalReduction>100</mechanicalReduction></actuator>
  </transmission>
)" + extra +
         "</robot>\n";
}

/// Potential energy [J]: rotating x about y by q takes height to −x sin q.
double potential(double q1, double q2)
{
  const double z1 = -LC1 * std::sin(q1);
  const double z2 = -L1 * std::sin(q1) - LC2 * std::sin(q1 + q2);
  return G * (M1 * z1 + M2 * z2);
}

TEST(ArmModel, ReadsJointsLimitsAndTransmissions)
{
  const ArmModel arm(twoLinkArm());
  EXPECT_EQ(arm.robotName(), "two_link");
  ASSERT_EQ(arm.joints().size(), 2u);
  EXPECT_EQ(arm.joints()[0].name, "shoulder");
  EXPECT_EQ(arm.joints()[1].name, "elbow");
  EXPECT_EQ(arm.indexOf("elbow"), 1);
  EXPECT_EQ(arm.indexOf("wrist"), -1);
  EXPECT_DOUBLE_EQ(arm.joints()[0].lower, -2.0);
  EXPECT_DOUBLE_EQ(arm.joints()[0].upper, 2.0);
  EXPECT_DOUBLE_EQ(arm.joints()[0].effort_limit, 80.0);
  EXPECT_DOUBLE_EQ(arm.joints()[0].velocity_limit, 1.5);
  EXPECT_TRUE(std::isinf(arm.joints()[1].upper));  // continuous
  EXPECT_DOUBLE_EQ(arm.joints()[0].reduction, 100.0);
  EXPECT_EQ(arm.joints()[0].actuator, "shoulder_motor");
  EXPECT_EQ(arm.joints()[1].reduction, 0.0);  // no transmission
  EXPECT_TRUE(arm.joints()[1].actuator.empty());
}

TEST(ArmModel, GravityIsMinusTheGradientOfThePotential)
{
  const ArmModel arm(twoLinkArm());
  for (double q1 : {-1.2, 0.0, 0.4, 1.9})
  {
    for (double q2 : {-2.5, 0.0, 0.7})
    {
      Eigen::VectorXd q(2);
      q << q1, q2;
      const Eigen::VectorXd tau = arm.gravityOnLoad(q, G);
      const double h = 1e-6;
      const double d1 = -(potential(q1 + h, q2) - potential(q1 - h, q2)) / (2 * h);
      const double d2 = -(potential(q1, q2 + h) - potential(q1, q2 - h)) / (2 * h);
      EXPECT_NEAR(tau(0), d1, 1e-7) << q1 << " " << q2;
      EXPECT_NEAR(tau(1), d2, 1e-7) << q1 << " " << q2;
    }
  }
  // Stretched out level (q = 0): each body's weight times its lever arm, pulling the arm down (+q lowers it).
  const Eigen::VectorXd level = arm.gravityOnLoad(Eigen::VectorXd::Zero(2), G);
  EXPECT_NEAR(level(0), G * (M1 * LC1 + M2 * (L1 + LC2)), 1e-9);
  EXPECT_NEAR(level(1), G * M2 * LC2, 1e-9);
}

TEST(ArmModel, TheMassMatrixIsTheTwoLinkArmsByHand)
{
  const ArmModel arm(twoLinkArm());
  for (double q2 : {-2.0, 0.0, 0.6, 3.0})
  {
    Eigen::VectorXd q(2);
    q << 0.3, q2;
    const Eigen::MatrixXd m = arm.massMatrix(q);
    const double c = std::cos(q2);
    EXPECT_NEAR(m(0, 0), I1 + M1 * LC1 * LC1 + I2 + M2 * (L1 * L1 + LC2 * LC2 + 2 * L1 * LC2 * c), 1e-12);
    EXPECT_NEAR(m(1, 1), I2 + M2 * LC2 * LC2, 1e-12);  // I2, not I2_OTHER: the inertial's frame is turned
    EXPECT_NEAR(m(0, 1), I2 + M2 * (LC2 * LC2 + L1 * LC2 * c), 1e-12);
    EXPECT_NEAR(m(1, 0), m(0, 1), 1e-12);
  }
}

TEST(ArmModel, MasslessDrawingsLeaveTheDynamicsAsTheyAre)
{
  // A motor drawn beside the shoulder (a massless rotor on a continuous joint) and a mark mimicking it on the upper
  // arm: listed after the massive joints, with no gravity and no inertia, and the two-link arm's figures unchanged.
  const std::string drawings = R"(
  <link name="rotor"><visual><geometry><cylinder radius="0.03" length="0.02"/></geometry></visual></link>
  <joint name="shoulder_motor" type="continuous">
    <parent link="base_link"/><child link="rotor"/><origin xyz="0 -0.07 0"/><axis xyz="0 1 0"/>
  </joint>
  <link name="mark"/>
  <joint name="shoulder_gear" type="continuous">
    <parent link="upper"/><child link="mark"/><axis xyz="0 1 0"/><mimic joint="shoulder_motor" multiplier="0.01"/>
  </joint>
)";
  const ArmModel plain(twoLinkArm());
  const ArmModel drawn(twoLinkArm(drawings));
  ASSERT_EQ(drawn.joints().size(), 4u);
  EXPECT_EQ(drawn.joints()[0].name, "shoulder");
  EXPECT_EQ(drawn.joints()[1].name, "elbow");
  EXPECT_GE(drawn.indexOf("shoulder_motor"), 2);  // after the massive joints, in the tree's depth-first order
  EXPECT_GE(drawn.indexOf("shoulder_gear"), 2);
  for (double q2 : {-1.0, 0.0, 2.2})
  {
    Eigen::VectorXd q(2), q4(4);
    q << 0.4, q2;
    q4 << 0.4, q2, 31.0, 0.31;
    const Eigen::VectorXd g = plain.gravityOnLoad(q);
    const Eigen::VectorXd g4 = drawn.gravityOnLoad(q4);
    const Eigen::MatrixXd m = plain.massMatrix(q);
    const Eigen::MatrixXd m4 = drawn.massMatrix(q4);
    EXPECT_EQ(g4.head(2), g);
    EXPECT_EQ(g4.tail(2), Eigen::Vector2d::Zero());
    EXPECT_EQ(m4.topLeftCorner(2, 2), m);
    EXPECT_EQ(m4.rightCols(2), Eigen::MatrixXd::Zero(4, 2));
    EXPECT_EQ(m4.bottomRows(2), Eigen::MatrixXd::Zero(2, 4));
    for (std::size_t i = 0; i < 4; ++i)
    {
      const auto k = static_cast<Eigen::Index>(i);
      EXPECT_EQ(drawn.inertiaAbout(q4, i), m4(k, k)) << i;  // one pass gives the diagonal entry
    }
  }
}

TEST(ArmModel, RefusesWhatItCannotRead)
{
  const auto refused = [](const std::string& xml, const std::string& says) {
    try
    {
      ArmModel arm(xml);
      ADD_FAILURE() << "accepted; expected: " << says;
    }
    catch (const std::invalid_argument& e)
    {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused("<robot name='x'><link name='a'>", "not well-formed XML");
  refused("<?xml version='1.0'?><arm/>", "no <robot> element");
  refused(
      "<robot name='x'><link name='a'/><joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
      "<limit lower='0' upper='1' effort='1' velocity='1'/></joint></robot>",
      "not a valid robot description");
  refused(twoLinkArm("<transmission name='t'><type>transmission_interface/DifferentialTransmission</type>"
                     "<joint name='elbow'/><actuator name='m'/></transmission>"),
          "is not transmission_interface/SimpleTransmission");
  refused(twoLinkArm("<transmission name='t'><type>transmission_interface/SimpleTransmission</type>"
                     "<joint name='wrist'/><actuator name='m'><mechanicalReduction>50</mechanicalReduction>"
                     "</actuator></transmission>"),
          "joint 'wrist': the URDF has no movable joint by that name");
  refused(twoLinkArm("<transmission name='t'><type>transmission_interface/SimpleTransmission</type>"
                     "<joint name='elbow'/><actuator name='m'><mechanicalReduction>fifty</mechanicalReduction>"
                     "</actuator></transmission>"),
          "<mechanicalReduction> must be a finite non-zero number (got 'fifty')");
  refused(twoLinkArm("<transmission name='t'><type>transmission_interface/SimpleTransmission</type>"
                     "<joint name='shoulder'/><actuator name='m'/></transmission>"),
          "joint 'shoulder' has a transmission already");
}
}  // namespace
}  // namespace backlash_servo
