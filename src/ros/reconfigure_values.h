// dynamic_reconfigure's generated config ↔ the parameter table's key values, for every node of the package.
#pragma once

#include "backlash_servo/BacklashServoConfig.h"
#include "backlash_servo/config/key_values.h"
#include "backlash_servo/model/drive_params.h"
#include "backlash_servo/model/params.h"
#include "node_config.h"

namespace backlash_servo
{
/// The generated config → key values, by the names of the parameter table.
KeyValues reconfigureValues(const BacklashServoConfig& c);
/// Every live key of the table as the generated config: a joint's parameters `p` and drive `d`, the node's settings.
BacklashServoConfig reconfigureConfig(const ServoParams& p, const DriveParams& d, const NodeConfig& node);
}  // namespace backlash_servo
