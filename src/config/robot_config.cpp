// An arm's joints from a robot YAML file and its URDF.
#include "backlash_servo/config/robot_config.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>

#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/config/safe_input.h"

namespace backlash_servo
{
namespace
{
const char* const JOINTS = "joints";
const char* const URDF = "urdf";

/// "joints/NAME/KEY" for a key the joint's own entry gives, "KEY (the top level, every joint's)" otherwise.
std::string placeOf(const std::string& joint, const KeyValues& own, const std::string& key)
{
  return own.has(key) ? "joints/" + joint + "/" + key : key + " (the file's top level, every joint's default)";
}

/// Every joint's initial load position [rad] in the arm's order (0 for the joints not simulated).
Eigen::VectorXd initialPose(const KeyValues& top, const std::vector<std::pair<std::string, KeyValues>>& joints,
                            const ArmModel& arm)
{
  Eigen::VectorXd q = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(arm.joints().size()));
  for (const auto& [name, own] : joints)
  {
    KeyValues kv = top;
    kv.overrideWith(own);
    const int a = arm.indexOf(name);
    if (a >= 0 && kv.has("load_position"))
    {
      q(a) = kv.number("load_position");
    }
  }
  return q;
}

/// The URDF's name for the joint: the joint must be a movable one of the arm (its nearest named if not).
void requireInArm(const std::string& name, const ArmModel& arm)
{
  if (arm.indexOf(name) >= 0)
  {
    return;
  }
  std::vector<std::string> names;
  for (const ArmJoint& j : arm.joints())
  {
    names.push_back(j.name);
  }
  const std::string near = nearestName(name, names);
  std::string list;
  for (const std::string& n : names)
  {
    list += (list.empty() ? "" : ", ") + n;
  }
  throw ConfigError("joints/" + name + ": the robot description '" + arm.robotName() +
                    "' has no movable joint by that name" + (near.empty() ? "" : " (did you mean '" + near + "'?)") +
                    "; its movable joints: " + list);
}

/// What the URDF's transmission says of the joint (its gear ratio into kv; the motor's name returned, "" without
/// one), refusing a key given both ways.
std::string fromTransmission(const std::string& name, const KeyValues& own, const ArmJoint& joint, KeyValues* kv)
{
  if (joint.reduction == 0.0)
  {
    return "";
  }
  const std::string where = "the URDF's transmission of '" + name + "' (mechanicalReduction " +
                            formatNumber(joint.reduction) + ", actuator '" + joint.actuator + "')";
  for (const char* key : {"gear_ratio", "motor_joint_name"})
  {
    if (kv->has(key))
    {
      throw ConfigError(placeOf(name, own, key) + " and " + where + " both give the joint's " +
                        (std::string(key) == "gear_ratio" ? "gear ratio" : "motor name") + ": keep one");
    }
  }
  if (!(joint.reduction > 0.0))
  {
    throw ConfigError("joints/" + name + ": " + where +
                      ": a negative reduction (a reversing gear) is not modelled: turn the joint's axis instead");
  }
  kv->setNumber("gear_ratio", 1.0 / joint.reduction);
  return joint.actuator;
}
}  // namespace

bool isRobotFile(const std::string& path)
{
  const YAML::Node root = loadYamlFile(path);
  return root.IsMap() && root[JOINTS];
}

RobotFile loadRobotFile(const std::string& path)
{
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap())
  {
    throw ConfigError("robot file '" + path + "' must be a mapping of key: value with a `joints:` mapping");
  }
  RobotFile file;
  readYamlKeys(root, {JOINTS, URDF}, "robot file '" + path + "'", &file.top);
  if (root[URDF])
  {
    file.urdf = yamlScalar(root[URDF], "robot file '" + path + "': urdf");
    if (!file.urdf.empty() && file.urdf[0] != '/' && path.find('/') != std::string::npos)
    {
      file.urdf = path.substr(0, path.rfind('/') + 1) + file.urdf;  // next to the YAML
    }
  }
  const YAML::Node joints = root[JOINTS];
  if (!joints || !joints.IsMap() || joints.size() == 0)
  {
    throw ConfigError("robot file '" + path + "': joints must map each joint's URDF name to its keys, e.g. " +
                      "`joints: {shoulder: {backlash: 0.003}, elbow: {}}`");
  }
  for (const auto& item : joints)
  {
    const std::string name = yamlScalar(item.first, "robot file '" + path + "': a joint's name");
    const std::string where = "robot file '" + path + "': joints/" + name;
    if (!item.second.IsNull() && !item.second.IsMap())
    {
      throw ConfigError(where + " must be a mapping of key: value (or empty: {})");
    }
    KeyValues own;
    if (item.second.IsMap())
    {
      readYamlKeys(item.second, {}, where, &own);
    }
    file.joints.emplace_back(name, own);
  }
  return file;
}

std::vector<RobotJoint> robotJointsFrom(const KeyValues& top,
                                        const std::vector<std::pair<std::string, KeyValues>>& joints,
                                        const ArmModel* arm, ControlMode mode)
{
  const Eigen::VectorXd q0 = arm != nullptr ? initialPose(top, joints, *arm) : Eigen::VectorXd();
  const Eigen::MatrixXd mass = arm != nullptr ? arm->massMatrix(q0) : Eigen::MatrixXd();
  const Eigen::VectorXd gravity = arm != nullptr ? arm->gravityOnLoad(q0) : Eigen::VectorXd();
  std::vector<RobotJoint> out;
  for (const auto& [name, own] : joints)
  {
    KeyValues kv = top;
    kv.overrideWith(own);
    RobotJoint j;
    j.name = name;
    std::string actuator;
    if (arm != nullptr)
    {
      requireInArm(name, *arm);
      const int a = arm->indexOf(name);
      actuator = fromTransmission(name, own, arm->joints()[static_cast<std::size_t>(a)], &kv);
      j.arm_gravity = !kv.has("load_torque");
      j.arm_inertia = !kv.has("load_inertia");
      if (j.arm_gravity)
      {
        kv.setNumber("load_torque", gravity(a));  // at the initial pose, for the validation below
      }
      if (j.arm_inertia)
      {
        kv.setNumber("load_inertia", mass(a, a));
      }
    }
    j.motor_name = !actuator.empty() ? actuator : kv.text("motor_joint_name", name + "_motor");
    try
    {
      j.run = runConfigFrom(kv, mode);
    }
    catch (const std::exception& e)
    {
      throw ConfigError("joints/" + name + ": " + e.what());
    }
    out.push_back(std::move(j));
  }
  if (arm != nullptr)
  {
    // The URDF's order (a parameter server keeps no order of its own: the node reads ~joints sorted by name).
    std::stable_sort(out.begin(), out.end(), [arm](const RobotJoint& a, const RobotJoint& b) {
      return arm->indexOf(a.name) < arm->indexOf(b.name);
    });
  }
  return out;
}

std::unique_ptr<ArmModel> armModelFrom(const std::string& urdf_text, const std::string& source)
{
  if (urdf_text.empty())
  {
    return nullptr;
  }
  try
  {
    return std::make_unique<ArmModel>(urdf_text);
  }
  catch (const std::invalid_argument& e)
  {
    throw ConfigError(source + ": " + e.what());
  }
}

RobotModel loadRobot(const std::string& path)
{
  const RobotFile file = loadRobotFile(path);
  RobotModel model;
  model.top = file.top;
  if (!file.urdf.empty())
  {
    model.arm = armModelFrom(readRegularFile("urdf", file.urdf, MAX_URDF_BYTES), "urdf '" + file.urdf + "'");
  }
  model.joints = robotJointsFrom(file.top, file.joints, model.arm.get());
  return model;
}

}  // namespace backlash_servo
