// The node's messages built from the core's events and judge, shared by the single joint's node and the arm's.
#pragma once

#include <ros/time.h>

#include <string>

#include "backlash_servo/BacklashState.h"
#include "backlash_servo/ImpactEvent.h"
#include "backlash_servo/LimitCycleStatus.h"
#include "backlash_servo/simulation/response_monitor.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/step_response.h"

namespace backlash_servo
{
/// An impact event (e.type == Impact) as published, stamped `stamp`, on the joint named `joint`.
ImpactEvent impactMessage(const Event& e, const ros::Time& stamp, const std::string& joint);

/// The judge's fields of a status: verdict, cycle (error, period, maxima per period, peak to peak and centre, in
/// counts of `resolution` and arcmin), equilibrium and the latest maximum. The rest (steady answer, tracking,
/// command, reason) is the caller's.
/// The joint's backlash_state at its current state: contact, gap [rad], torques [N·m], θ_R = `command` [rad], mode,
/// the energy ledger [J] (NaN while a ramp's moving frame holds it) and the impact count; stamped `stamp`.
BacklashState backlashStateMessage(const Simulator& sim, double command, const ros::Time& stamp);

void fillVerdict(const ResponseMonitor& monitor, const CycleResolution& resolution, LimitCycleStatus* m);

}  // namespace backlash_servo
