// Robot files: the example arm's joints as its URDF and YAML give them, and the refusals that name the key.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <fstream>
#include <string>

#include "backlash_servo/config/robot_config.h"
#include "test_helpers.h"

namespace backlash_servo
{
namespace
{
using test_helpers::readFile;

std::string arm_file()
{
  return std::string(SOURCE_DIR) + "/config/three_joint_arm.yaml";
}

/// A robot file in a fresh folder beside a copy of the example URDF: an elbow-sized drive for every joint, then `yaml`.
std::string robotFile(const std::string& name, const std::string& yaml)
{
  const std::string dir = "/tmp/backlash_robot_config_" + std::to_string(getpid());
  (void)system(("mkdir -p " + dir).c_str());
  std::ofstream(dir + "/arm.urdf") << readFile(std::string(SOURCE_DIR) + "/urdf/three_joint_arm.urdf");
  const std::string path = dir + "/" + name + ".yaml";
  std::ofstream(path) << "urdf: arm.urdf\ncontrol_law: pid\ncontroller_rate: 1000\nmotor_inertia: 5.0e-5\n"
                      << "motor_friction: 1.0e-4\nload_friction: 0.2\ngain: 6.8\nintegral_gain: 14\n"
                      << yaml;
  return path;
}

std::vector<RobotJoint> jointsOf(const std::string& path, std::unique_ptr<ArmModel>* arm)
{
  const RobotFile file = loadRobotFile(path);
  *arm = file.urdf.empty() ? nullptr : std::make_unique<ArmModel>(readFile(file.urdf));
  return robotJointsFrom(file.top, file.joints, arm->get());
}

std::string refusal(const std::string& path)
{
  try
  {
    std::unique_ptr<ArmModel> arm;
    jointsOf(path, &arm);
  }
  catch (const std::exception& e)
  {
    return e.what();
  }
  return "(accepted)";
}

TEST(RobotConfig, TheExampleArmTakesItsGearsNamesAndLoadsFromItsUrdf)
{
  EXPECT_TRUE(isRobotFile(arm_file()));
  EXPECT_FALSE(isRobotFile(std::string(SOURCE_DIR) + "/config/default.yaml"));
  std::unique_ptr<ArmModel> arm;
  const std::vector<RobotJoint> joints = jointsOf(arm_file(), &arm);
  ASSERT_EQ(joints.size(), 3u);
  const char* names[] = {"shoulder", "elbow", "wrist"};
  const double rho[] = {0.01, 0.01, 0.02};
  for (int i = 0; i < 3; ++i)
  {
    EXPECT_EQ(joints[i].name, names[i]);
    EXPECT_EQ(joints[i].motor_name, std::string(names[i]) + "_motor");
    EXPECT_DOUBLE_EQ(joints[i].run.params.gear_ratio, rho[i]);
    EXPECT_TRUE(joints[i].arm_gravity && joints[i].arm_inertia);
    EXPECT_EQ(joints[i].run.drive.control_law, "pid");  // the top level's, for every joint
    EXPECT_EQ(joints[i].run.params.restitution, 0.3);
  }
  EXPECT_EQ(joints[0].run.params.backlash, 0.0044);  // each joint's own
  EXPECT_EQ(joints[2].run.drive.integral_gain, 1.2);
  // Gravity at the initial pose by hand: link masses at their centres, +q turning a link down (about +y).
  const double g = 9.80665, q1 = 0.3, q12 = 0.3 - 0.6, q123 = 0.3 - 0.6 + 0.4;
  const double wrist = g * 0.9 * 0.08 * std::cos(q123);
  const double elbow = g * 2.1 * 0.175 * std::cos(q12) + g * 0.9 * 0.35 * std::cos(q12) + wrist;
  const double shoulder = g * 3.2 * 0.2 * std::cos(q1) + g * (2.1 + 0.9) * 0.4 * std::cos(q1) + elbow;
  EXPECT_NEAR(joints[0].run.params.load_torque, shoulder, 1e-9);
  EXPECT_NEAR(joints[1].run.params.load_torque, elbow, 1e-9);
  EXPECT_NEAR(joints[2].run.params.load_torque, wrist, 1e-9);
  // The wrist's inertia: its link about the joint (parallel axes), whatever the pose.
  EXPECT_NEAR(joints[2].run.params.load_inertia, 0.0025 + 0.9 * 0.08 * 0.08, 1e-12);
}

TEST(RobotConfig, AKeyGivenKeepsItsConstant)
{
  const std::string path = robotFile("constant", "joints:\n  elbow: {load_torque: -3.0, load_inertia: 0.4}\n");
  std::unique_ptr<ArmModel> arm;
  const std::vector<RobotJoint> joints = jointsOf(path, &arm);
  ASSERT_EQ(joints.size(), 1u);
  EXPECT_FALSE(joints[0].arm_gravity || joints[0].arm_inertia);
  EXPECT_EQ(joints[0].run.params.load_torque, -3.0);
  EXPECT_EQ(joints[0].run.params.load_inertia, 0.4);
  RobotSimulator robot(joints, arm.get(), 1e-3);
  robot.advanceTo(0.5);
  EXPECT_EQ(robot.loadTorque(0), -3.0);
  EXPECT_EQ(robot.loadInertia(0), 0.4);
}

TEST(RobotConfig, RefusalsNameTheKeyAndWhereItWasGiven)
{
  EXPECT_NE(refusal(robotFile("both_top", "gear_ratio: 0.02\njoints:\n  elbow: {}\n"))
                .find("gear_ratio (the file's top level, every joint's default) and the URDF's transmission of "
                      "'elbow' (mechanicalReduction 100, actuator 'elbow_motor') both give the joint's gear ratio"),
            std::string::npos);
  EXPECT_NE(refusal(robotFile("both_joint", "joints:\n  wrist: {gear_ratio: 0.02}\n"))
                .find("joints/wrist/gear_ratio and the URDF's transmission of 'wrist'"),
            std::string::npos);
  EXPECT_NE(refusal(robotFile("unknown_joint", "joints:\n  elbw: {}\n"))
                .find("joints/elbw: the robot description 'three_joint_arm' has no movable joint by that name (did you "
                      "mean 'elbow'?); its movable joints: shoulder, elbow, wrist"),
            std::string::npos);
  EXPECT_NE(refusal(robotFile("unknown_key", "joints:\n  elbow: {backlsh: 0.1}\n"))
                .find("joints/elbow: unknown key 'backlsh' (did you mean 'backlash'?)"),
            std::string::npos);
  EXPECT_NE(refusal(robotFile("bad_value", "joints:\n  elbow: {restitution: 1.5}\n")).find("joints/elbow: restitution"),
            std::string::npos);
  EXPECT_NE(
      refusal(robotFile("not_a_map", "joints: [shoulder, elbow]\n")).find("joints must map each joint's URDF name"),
      std::string::npos);
  EXPECT_NE(refusal(robotFile("list_value", "joints:\n  elbow: {backlash: [1, 2]}\n"))
                .find("joints/elbow: key 'backlash' must have a single value"),
            std::string::npos);
}

TEST(RobotConfig, WithoutAUrdfTheJointsAreSingleJointsUnderOneClock)
{
  const std::string path = "/tmp/backlash_robot_config_plain_" + std::to_string(getpid()) + ".yaml";
  std::ofstream(path) << "backlash: 0.01\njoints:\n  a: {}\n  b: {backlash: 0.02, motor_joint_name: b_rotor}\n";
  std::unique_ptr<ArmModel> arm;
  const std::vector<RobotJoint> joints = jointsOf(path, &arm);
  ASSERT_EQ(joints.size(), 2u);
  EXPECT_EQ(arm, nullptr);
  EXPECT_EQ(joints[0].motor_name, "a_motor");
  EXPECT_EQ(joints[1].motor_name, "b_rotor");
  EXPECT_EQ(joints[0].run.params.backlash, 0.01);
  EXPECT_EQ(joints[1].run.params.backlash, 0.02);
  EXPECT_FALSE(joints[0].arm_gravity || joints[1].arm_inertia);
}
}  // namespace
}  // namespace backlash_servo
