// dynamic_reconfigure's generated config ↔ the parameter table's key values, for every node of the package.
#include "reconfigure_values.h"

#include <dynamic_reconfigure/config_tools.h>

#include <algorithm>

#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
/// The generated config → key values, by the names of the parameter table.
KeyValues reconfigureValues(const BacklashServoConfig& c)
{
  KeyValues kv;
  kv.nameKeysAsFlags(false);
  for (const auto& d : BacklashServoConfig::__getParamDescriptions__())
  {
    boost::any value;
    d->getValue(c, value);
    const ParamSpec* spec = findParam(d->name);
    if (spec == nullptr)
    {
      continue;  // a .cfg entry the table does not know: the consistency test fails for it
    }
    if (d->type == "double")
    {
      kv.setNumber(d->name, boost::any_cast<double>(value));
    }
    else if (d->type == "int")
    {
      const int i = boost::any_cast<int>(value);
      kv.set(d->name, i >= 0 && i < static_cast<int>(spec->choices.size()) ? spec->choices[i] : std::to_string(i));
    }
    else if (d->type == "bool")
    {
      kv.setBoolean(d->name, boost::any_cast<bool>(value));
    }
    else
    {
      kv.set(d->name, boost::any_cast<std::string>(value));
    }
  }
  return kv;
}

BacklashServoConfig reconfigureConfig(const ServoParams& p, const DriveParams& d, const NodeConfig& node)
{
  // Every live key of the table, by name: the generated config is filled through its own message form.
  dynamic_reconfigure::Config msg;
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
    {
      const auto it = std::find(spec->choices.begin(), spec->choices.end(), p.*(*text));
      dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, static_cast<int>(it - spec->choices.begin()));
      continue;
    }
    dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, p.*std::get<double ServoParams::*>(spec->field));
  }
  const KeyValues drive = driveKeyValues(d);
  for (const ParamSpec* spec : paramsIn(ParamSection::Drive))
  {
    if (spec->type == ParamType::Choice)
    {
      const std::string value = drive.text(spec->key, spec->fallback);
      const auto it = std::find(spec->choices.begin(), spec->choices.end(), value);
      dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, static_cast<int>(it - spec->choices.begin()));
    }
    else
    {
      dynamic_reconfigure::ConfigTools::appendParameter(msg, spec->key, drive.number(spec->key));
    }
  }
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "control_mode",
                                                    node.control_mode == ControlMode::Effort ? 1 : 0);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "publish_rate", node.publish_rate);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "real_time_factor", node.real_time_factor);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "min_impact_speed", node.min_impact_speed);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "sync_timeout", node.sync_timeout);
  dynamic_reconfigure::ConfigTools::appendParameter(msg, "effort_timeout", node.effort_timeout);
  BacklashServoConfig c = BacklashServoConfig::__getDefault__();
  c.__fromMessage__(msg);
  return c;
}
}  // namespace backlash_servo
