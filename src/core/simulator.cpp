#include "backlash_servo/simulator.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace backlash_servo
{
Simulator::Simulator(const ServoParams& params, const State& initial, double command)
    : plant_(params, initial, MotorInput{}),
      drive_(std::make_unique<ProportionalDrive>(params.gain, command)),
      command_(command)
{
  plant_.setLaw(drive_->law());
}

Simulator::Simulator(const Simulator& other)
    : plant_(other.plant_), drive_(other.drive_->clone()), command_(other.command_)
{}

Simulator& Simulator::operator=(const Simulator& other)
{
  if (this != &other)
  {
    plant_ = other.plant_;
    drive_ = other.drive_->clone();
    command_ = other.command_;
  }
  return *this;
}

void Simulator::setDrive(std::unique_ptr<Drive> drive, EventSink* sink)
{
  drive->configure(plant_.params());
  drive->sample(plant_.state());
  drive_ = std::move(drive);
  plant_.setLaw(drive_->law());
  plant_.emit(sink, EventType::InputChange);
}

void Simulator::setCommand(double command, EventSink* sink)
{
  requireFinite("command", command);
  command_ = command;
  if (auto* sampled = dynamic_cast<SampledDrive*>(drive_.get()))
  {
    sampled->setCommand(command);  // read at the next sample; the held torque stays until then
    plant_.emit(sink, EventType::InputChange);
    return;
  }
  setDrive(std::make_unique<ProportionalDrive>(plant_.params().gain, command), sink);
}

void Simulator::setMotorTorque(double torque, EventSink* sink)
{
  setDrive(std::make_unique<EffortDrive>(torque), sink);
}

void Simulator::setParams(const ServoParams& params, EventSink* sink)
{
  params.validate();
  drive_->configure(params);
  plant_.setLaw(drive_->law());
  plant_.setParams(params, sink);
}

void Simulator::advanceTo(double t_end, EventSink* sink)
{
  if (!(t_end >= state().time) || !std::isfinite(t_end))
  {
    throw std::invalid_argument("advanceTo: target time " + std::to_string(t_end) + " s is before the current time " +
                                std::to_string(state().time) + " s or not finite");
  }
  while (state().time < t_end)
  {
    const double next = drive_->nextEventTime(state().time);
    if (next <= state().time)
    {
      drive_->sample(plant_.state());  // a sample due now (at a step boundary)
      plant_.setLaw(drive_->law());
      continue;
    }
    if (!(next < t_end))
    {
      plant_.advanceTo(t_end, sink);
      break;
    }
    plant_.advanceTo(next, sink);
    drive_->sample(plant_.state());
    plant_.setLaw(drive_->law());
  }
}

}  // namespace backlash_servo
