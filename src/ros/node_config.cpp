#include "node_config.h"

#include <ros/console.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
namespace
{
double realValue(const KeyValues& kv, const char* key, double current)
{
  const double v = kv.has(key) ? kv.number(key) : current;
  param(key).check(v);
  return v;
}

std::string textValue(const KeyValues& kv, const char* key, const std::string& current)
{
  return kv.text(key, current);
}

/// A ROS param → a typed key value (numbers stay numbers: no text round trip).
void putValue(KeyValues* kv, const ParamSpec& spec, XmlRpc::XmlRpcValue& v)
{
  switch (v.getType())
  {
    case XmlRpc::XmlRpcValue::TypeDouble:
      kv->setNumber(spec.key, static_cast<double>(v));
      break;
    case XmlRpc::XmlRpcValue::TypeInt:
      if (spec.type == ParamType::Choice)
      {
        // dynamic_reconfigure stores a choice as its index.
        const int i = static_cast<int>(v);
        if (i < 0 || i >= static_cast<int>(spec.choices.size()))
        {
          throw ConfigError(std::string(spec.key) + ": choice index " + std::to_string(i) + " out of range");
        }
        kv->set(spec.key, spec.choices[i]);
      }
      else
      {
        kv->setNumber(spec.key, static_cast<int>(v));
      }
      break;
    case XmlRpc::XmlRpcValue::TypeBoolean:
      kv->setBoolean(spec.key, static_cast<bool>(v));
      break;
    case XmlRpc::XmlRpcValue::TypeString:
      kv->set(spec.key, static_cast<std::string>(v));
      break;
    default:
      throw ConfigError(std::string(spec.key) + ": expected a single " + toString(spec.type) + " value" +
                        (spec.type == ParamType::Text ? " (the node takes a profile as a file path, not inline)" : ""));
  }
}
}  // namespace

void validateNodeSettings(const NodeConfig& c)
{
  if (c.real_time_factor == 0.0 && !c.publish_clock)
  {
    throw ConfigError("real_time_factor: 0 (as fast as possible) needs publish_clock: true");
  }
  if (c.sync && !c.publish_clock)
  {
    throw ConfigError("sync: lockstep needs publish_clock: true (the controller must follow the node's sim time)");
  }
  const std::pair<const char*, const std::string*> names[] = {{"motor_joint_name", &c.motor_joint_name},
                                                              {"load_joint_name", &c.load_joint_name},
                                                              {"gear_joint_name", &c.gear_joint_name},
                                                              {"shaft_twist_joint_name", &c.shaft_twist_joint_name}};
  for (std::size_t i = 0; i < std::size(names); ++i)
  {
    if (names[i].second->empty())
    {
      throw ConfigError(std::string(names[i].first) + ": must be a non-empty joint name");
    }
    for (std::size_t k = 0; k < i; ++k)
    {
      if (*names[k].second == *names[i].second)
      {
        throw ConfigError(std::string(names[k].first) + ", " + names[i].first +
                          ": must be different joint names (both '" + *names[i].second + "')");
      }
    }
  }
}

NodeConfig nodeSettingsFrom(const KeyValues& kv, const NodeConfig& base)
{
  NodeConfig c = base;
  const ParamSpec& mode = param("control_mode");
  const std::string mode_text =
      textValue(kv, "control_mode", c.control_mode == ControlMode::Effort ? "effort" : "position");
  if (!mode.isChoice(mode_text))
  {
    throw ConfigError("control_mode: must be position or effort (got '" + mode_text + "')");
  }
  c.control_mode = mode_text == "effort" ? ControlMode::Effort : ControlMode::Position;
  c.motor_effort = realValue(kv, "motor_effort", c.motor_effort);
  c.publish_rate = realValue(kv, "publish_rate", c.publish_rate);
  c.real_time_factor = realValue(kv, "real_time_factor", c.real_time_factor);
  c.publish_clock = kv.has("publish_clock") ? kv.boolean("publish_clock") : c.publish_clock;
  c.clock_publish_rate = realValue(kv, "clock_publish_rate", c.clock_publish_rate);
  c.motor_joint_name = textValue(kv, "motor_joint_name", c.motor_joint_name);
  c.load_joint_name = textValue(kv, "load_joint_name", c.load_joint_name);
  c.gear_joint_name = textValue(kv, "gear_joint_name", c.gear_joint_name);
  c.shaft_twist_joint_name = textValue(kv, "shaft_twist_joint_name", c.shaft_twist_joint_name);
  c.min_impact_speed = realValue(kv, "min_impact_speed", c.min_impact_speed);
  c.paused = kv.has("paused") ? kv.boolean("paused") : c.paused;
  c.stop_after = realValue(kv, "stop_after", c.stop_after);
  c.stop_launch = kv.has("stop_launch") ? kv.boolean("stop_launch") : c.stop_launch;
  c.start_time = realValue(kv, "start_time", c.start_time);
  c.start_delay = realValue(kv, "start_delay", c.start_delay);
  c.record_bag = textValue(kv, "record_bag", c.record_bag);
  c.sync = kv.has("sync") ? kv.boolean("sync") : c.sync;
  c.sync_timeout = realValue(kv, "sync_timeout", c.sync_timeout);
  c.effort_timeout = realValue(kv, "effort_timeout", c.effort_timeout);
  validateNodeSettings(c);
  return c;
}

PrivateParams readPrivateParams(const ros::NodeHandle& pnh)
{
  PrivateParams out;
  out.given.nameKeysAsFlags(false);
  XmlRpc::XmlRpcValue all;
  if (!pnh.getParam(pnh.getNamespace(), all) || all.getType() != XmlRpc::XmlRpcValue::TypeStruct)
  {
    return out;
  }
  for (auto& item : all)
  {
    const ParamSpec* spec = findParam(item.first);
    if (spec != nullptr)
    {
      putValue(&out.given, *spec, item.second);
    }
    else if (item.first == "joints" && item.second.getType() == XmlRpc::XmlRpcValue::TypeStruct)
    {
      out.arm = true;
      for (auto& joint : item.second)
      {
        if (joint.second.getType() != XmlRpc::XmlRpcValue::TypeStruct)
        {
          throw ConfigError("~joints/" + joint.first + ": must be a mapping of key: value");
        }
        KeyValues own;
        own.nameKeysAsFlags(false);
        for (auto& key : joint.second)
        {
          const ParamSpec* joint_spec = findParam(key.first);
          if (joint_spec == nullptr)
          {
            throw ConfigError("~joints/" + joint.first + "/" + key.first + ": unknown parameter" +
                              didYouMean(key.first));
          }
          putValue(&own, *joint_spec, key.second);
        }
        out.joints.emplace_back(joint.first, own);
      }
    }
    else if (item.first == "urdf" && item.second.getType() == XmlRpc::XmlRpcValue::TypeString)
    {
      out.urdf = static_cast<std::string>(item.second);
    }
    else if (item.second.getType() != XmlRpc::XmlRpcValue::TypeStruct)  // dynamic_reconfigure keeps groups
    {
      // A typo must not run as the key's default (a derivative gain of 0): refused, the nearest key named.
      throw ConfigError("~" + item.first + ": unknown parameter" + didYouMean(item.first));
    }
  }
  return out;
}

KeyValues withNodeDefaults(const KeyValues& given)
{
  KeyValues kv;
  kv.nameKeysAsFlags(false);
  for (const ParamSpec* spec : paramsIn(ParamSection::Node))
  {
    kv.set(spec->key, spec->fallback);  // the table's defaults, under the params given
  }
  kv.overrideWith(given);
  return kv;
}

NodeConfig loadNodeConfig(const ros::NodeHandle& pnh)
{
  const PrivateParams params = readPrivateParams(pnh);
  if (params.arm)
  {
    throw ConfigError("~joints: an arm's parameters (the node reads them as an arm: loadRobotNodeConfig)");
  }
  const KeyValues kv = withNodeDefaults(params.given);
  NodeConfig c = nodeSettingsFrom(kv, NodeConfig());
  c.run = runConfigFrom(kv, c.control_mode);
  return c;
}

}  // namespace backlash_servo
