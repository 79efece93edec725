#include "backlash_servo/drive.h"

namespace backlash_servo
{
ProportionalDrive::ProportionalDrive(double gain, double command) : gain_(gain), command_(0.0)
{
  requireFinite("gain", gain);
  setCommand(command);
}

void ProportionalDrive::configure(const ServoParams& params)
{
  gain_ = params.gain;  // validated with the rest of the parameters by the caller
}

void ProportionalDrive::setCommand(double command)
{
  requireFinite("command", command);
  command_ = command;
}

EffortDrive::EffortDrive(double torque) : torque_(0.0)
{
  setTorque(torque);
}

void EffortDrive::setTorque(double torque)
{
  requireFinite("motor_torque", torque);
  torque_ = torque;
}

}  // namespace backlash_servo
