// backlash_sim with a robot file (`joints:`): every joint of the arm in one simulated time, a verdict per joint.
#pragma once

#include "backlash_servo/config/flag_parser.h"

namespace backlash_servo
{
/// Runs the arm of --config (a robot file) as the options ask, a --csv row every 1/sample_rate [s] (at most at the
/// fastest controller's rate); returns the tool's exit code (2: bad input, 1: the run failed).
int simulateRobot(const FlagParser& options, double sample_rate);
}  // namespace backlash_servo
