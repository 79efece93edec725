#include "node_config.h"

#include <ros/console.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "sim_options.h"

namespace backlash_servo
{
namespace
{
bool isNumber(const XmlRpc::XmlRpcValue& v)
{
  return v.getType() == XmlRpc::XmlRpcValue::TypeDouble || v.getType() == XmlRpc::XmlRpcValue::TypeInt;
}

double toNumber(const std::string& key, XmlRpc::XmlRpcValue& v)
{
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble)
  {
    return static_cast<double>(v);
  }
  if (v.getType() == XmlRpc::XmlRpcValue::TypeInt)
  {
    return static_cast<int>(v);
  }
  throw UsageError(key + ": expected a number");
}

bool toBool(const std::string& key, XmlRpc::XmlRpcValue& v)
{
  if (v.getType() != XmlRpc::XmlRpcValue::TypeBoolean)
  {
    throw UsageError(key + ": expected true or false");
  }
  return static_cast<bool>(v);
}

std::string toText(const std::string& key, XmlRpc::XmlRpcValue& v)
{
  if (v.getType() != XmlRpc::XmlRpcValue::TypeString)
  {
    throw UsageError(key + ": expected a string");
  }
  return static_cast<std::string>(v);
}

bool contains(const std::vector<std::string>& keys, const std::string& key)
{
  return std::find(keys.begin(), keys.end(), key) != keys.end();
}
}  // namespace

void validateNodeSettings(const NodeConfig& c)
{
  if (!(c.publish_rate > 0.0) || !std::isfinite(c.publish_rate))
  {
    throw UsageError("publish_rate: must be > 0 Hz");
  }
  if (!(c.real_time_factor >= 0.0) || !std::isfinite(c.real_time_factor))
  {
    throw UsageError("real_time_factor: must be >= 0");
  }
  if (c.real_time_factor == 0.0 && !c.publish_clock)
  {
    throw UsageError("real_time_factor: 0 (as fast as possible) needs publish_clock: true");
  }
  if (!(c.min_impact_speed >= 0.0) || !std::isfinite(c.min_impact_speed))
  {
    throw UsageError("min_impact_speed: must be >= 0 rad/s");
  }
  if (!(c.stop_after >= 0.0) || !std::isfinite(c.stop_after))
  {
    throw UsageError("stop_after: must be >= 0 s");
  }
  if (!(c.start_delay >= 0.0) || !std::isfinite(c.start_delay))
  {
    throw UsageError("start_delay: must be >= 0 s");
  }
  if (!std::isfinite(c.motor_effort))
  {
    throw UsageError("motor_effort: must be finite");
  }
  if (c.motor_joint_name.empty() || c.load_joint_name.empty() || c.motor_joint_name == c.load_joint_name)
  {
    throw UsageError("motor_joint_name, load_joint_name: must be two different non-empty names");
  }
}

NodeConfig loadNodeConfig(const ros::NodeHandle& pnh)
{
  XmlRpc::XmlRpcValue all;
  NodeConfig c;
  KeyValues kv;
  kv.nameKeysAsFlags(false);
  if (pnh.getParam(pnh.getNamespace(), all) && all.getType() == XmlRpc::XmlRpcValue::TypeStruct)
  {
    for (auto& item : all)
    {
      const std::string& key = item.first;
      XmlRpc::XmlRpcValue& v = item.second;
      if (contains(modelKeys(), key))
      {
        if (isNumber(v))
        {
          char buf[40];
          std::snprintf(buf, sizeof buf, "%.17g", toNumber(key, v));
          kv.set(key, buf);
        }
        else if (v.getType() == XmlRpc::XmlRpcValue::TypeString)
        {
          kv.set(key, static_cast<std::string>(v));
        }
        else
        {
          throw UsageError(key + ": expected a number" + (key == "contact" ? " or forward/backward/none" : ""));
        }
      }
      else if (key == "control_mode")
      {
        const std::string mode = v.getType() == XmlRpc::XmlRpcValue::TypeInt ? (static_cast<int>(v) == 1   ? "effort"
                                                                                : static_cast<int>(v) == 0 ? "position"
                                                                                                           : "?")
                                                                             : toText(key, v);
        if (mode != "position" && mode != "effort")
        {
          throw UsageError("control_mode: must be position or effort");
        }
        c.control_mode = mode == "effort" ? ControlMode::Effort : ControlMode::Position;
      }
      else if (key == "motor_effort")
      {
        c.motor_effort = toNumber(key, v);
      }
      else if (key == "publish_rate")
      {
        c.publish_rate = toNumber(key, v);
      }
      else if (key == "real_time_factor")
      {
        c.real_time_factor = toNumber(key, v);
      }
      else if (key == "publish_clock")
      {
        c.publish_clock = toBool(key, v);
      }
      else if (key == "motor_joint_name")
      {
        c.motor_joint_name = toText(key, v);
      }
      else if (key == "load_joint_name")
      {
        c.load_joint_name = toText(key, v);
      }
      else if (key == "min_impact_speed")
      {
        c.min_impact_speed = toNumber(key, v);
      }
      else if (key == "paused")
      {
        c.paused = toBool(key, v);
      }
      else if (key == "stop_after")
      {
        c.stop_after = toNumber(key, v);
      }
      else if (key == "start_delay")
      {
        c.start_delay = toNumber(key, v);
      }
      else if (v.getType() != XmlRpc::XmlRpcValue::TypeStruct)  // dynamic_reconfigure keeps its groups as structs
      {
        ROS_WARN("backlash_servo_node: ignoring unknown parameter ~%s (typo?)", key.c_str());
      }
    }
  }
  c.run = runConfigFrom(kv);
  validateNodeSettings(c);
  return c;
}

}  // namespace backlash_servo
