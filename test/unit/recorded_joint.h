// A recording made with the simulator as the joint (the exact motion is the truth of the identification tests): a
// torque held over samples at `rate` [Hz] in effort mode, the angles recorded at the samples.
#pragma once

#include <algorithm>
#include <cmath>

#include "backlash_servo/identification/identification.h"
#include "backlash_servo/simulation/simulator.h"

namespace backlash_servo
{
/// The test joints: the thesis' D1 with dry friction on both bodies (static above the Coulomb level) and a load
/// torque.
inline ServoParams dryFrictionJoint()
{
  ServoParams p;
  p.motor_coulomb_friction = 0.05;
  p.motor_static_friction = 0.12;
  p.load_coulomb_friction = 0.1;
  p.load_static_friction = 0.25;
  p.load_torque = 0.2;
  return p;
}

/// u(t) = a (1.5 sin 1.3t + 0.8 sin(4.1t + 0.5) + 0.3 sin 11t) [N·m]: reversals that carry the motor across the free
/// play, contact motion both ways. `pauses`: times a slow envelope max(0, sin 0.7t) + 0.3, so the bodies come to rest
/// now and then and must break away (static friction).
inline Recording recordJoint(const ServoParams& p, double seconds, double rate, double a, bool pauses = false)
{
  Simulator sim(p, State(), 0.0);
  Recording r;
  const long n = static_cast<long>(seconds * rate);
  for (long k = 0; k <= n; ++k)
  {
    const double t = static_cast<double>(k) / rate;
    sim.advanceTo(t);
    const double envelope = pauses ? std::max(0.0, std::sin(0.7 * t)) + 0.3 : 1.0;
    const double u =
        a * envelope * (1.5 * std::sin(1.3 * t) + 0.8 * std::sin(4.1 * t + 0.5) + 0.3 * std::sin(11.0 * t));
    sim.setMotorTorque(u);
    r.time.push_back(t);
    r.motor_torque.push_back(u);
    r.motor_position.push_back(sim.state().motor_position);
    r.load_position.push_back(sim.state().load_position);
  }
  return r;
}

}  // namespace backlash_servo
