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
    : plant_(other.plant_),
      drive_(other.drive_->clone()),
      command_(other.command_),
      profile_(other.profile_),
      stepped_(other.stepped_),
      next_change_(other.next_change_),
      event_budget_(other.event_budget_),
      samples_(other.samples_),
      sample_observer_(other.sample_observer_)
{}

Simulator& Simulator::operator=(const Simulator& other)
{
  if (this != &other)
  {
    plant_ = other.plant_;
    drive_ = other.drive_->clone();
    command_ = other.command_;
    profile_ = other.profile_;
    stepped_ = other.stepped_;
    next_change_ = other.next_change_;
    event_budget_ = other.event_budget_;
    samples_ = other.samples_;
    sample_observer_ = other.sample_observer_;
  }
  return *this;
}

void Simulator::takeSample()
{
  if (event_budget_ != 0 && ++samples_ > event_budget_)
  {
    throw EventBudgetExceeded("event budget of " + std::to_string(event_budget_) +
                              " controller samples exceeded at t = " + std::to_string(state().time) +
                              " s (raise max_events to go on)");
  }
  drive_->sample(plant_.state());
  applyDriveLaw();
  if (sample_observer_)
  {
    sample_observer_(plant_.state(), *drive_);
  }
}

void Simulator::applyDriveLaw()
{
  plant_.setLaw(drive_->law());
  double lo, hi;
  drive_->watchInterval(&lo, &hi);
  plant_.setWatch(lo, hi);
}

void Simulator::setDrive(std::unique_ptr<Drive> drive, EventSink* sink)
{
  profile_.reset();
  stepped_ = false;
  drive->configure(plant_.params());
  drive->sample(plant_.state());
  drive->reevaluate(plant_.state());
  drive_ = std::move(drive);
  applyDriveLaw();
  plant_.emit(sink, EventType::InputChange);
}

void Simulator::setCommand(double command, EventSink* sink)
{
  requireFinite("command", command);
  if (profile_)
  {
    if (auto* sampled = dynamic_cast<SampledDrive*>(drive_.get()))
    {
      sampled->setProfile(nullptr);
    }
    profile_.reset();
    stepped_ = false;
  }
  applyCommand(command, sink);
}

void Simulator::setProfile(std::shared_ptr<const CommandProfile> profile, EventSink* sink)
{
  if (drive_->mode() != ControlMode::Position)
  {
    throw InvalidParameterError("profile", "a command profile needs position mode (the drive is in effort mode)");
  }
  auto* sampled = dynamic_cast<SampledDrive*>(drive_.get());
  if (profile)
  {
    profile->requireTakenBy(sampled != nullptr);
  }
  profile_ = std::move(profile);
  stepped_ = profile_ && sampled == nullptr;
  if (sampled != nullptr)
  {
    sampled->setProfile(profile_);  // read from the next sample on
    plant_.emit(sink, EventType::InputChange);
    return;
  }
  if (stepped_)
  {
    next_change_ = profile_->nextChange(state().time);
    applyCommand(profile_->at(state().time), sink);
  }
}

void Simulator::applyCommand(double command, EventSink* sink)
{
  command_ = command;
  if (auto* sampled = dynamic_cast<SampledDrive*>(drive_.get()))
  {
    sampled->setCommand(command);  // read at the next sample; the held torque stays until then
    plant_.emit(sink, EventType::InputChange);
    return;
  }
  if (auto* proportional = dynamic_cast<ProportionalDrive*>(drive_.get()))
  {
    proportional->setCommand(command);  // keeps its torque limit
    proportional->reevaluate(plant_.state());
    applyDriveLaw();
    plant_.emit(sink, EventType::InputChange);
    return;
  }
  setDrive(std::make_unique<ProportionalDrive>(plant_.params().gain, command), sink);
}

void Simulator::setMotorTorque(double torque, EventSink* sink)
{
  // (setDrive ends a profile)
  setDrive(std::make_unique<EffortDrive>(torque), sink);
}

void Simulator::setParams(const ServoParams& params, EventSink* sink)
{
  params.validate();
  drive_->configure(params);
  drive_->reevaluate(plant_.state());
  applyDriveLaw();
  plant_.setParams(params, sink);
}

void Simulator::advanceTo(double t_end, EventSink* sink)
{
  if (!(t_end >= state().time) || !std::isfinite(t_end))
  {
    throw std::invalid_argument("advanceTo: target time " + std::to_string(t_end) + " s is before the current time " +
                                std::to_string(state().time) + " s or not finite");
  }
  while (stepped_ && next_change_ <= t_end)
  {
    const double change = next_change_;
    advanceDriveTo(change, sink);
    next_change_ = profile_->nextChange(change);
    applyCommand(profile_->at(change), sink);  // a step of θ_R at its known instant
  }
  advanceDriveTo(t_end, sink);
}

void Simulator::advanceDriveTo(double t_end, EventSink* sink)
{
  while (state().time < t_end)
  {
    const double next = drive_->nextEventTime(state().time);
    if (next <= state().time)
    {
      takeSample();  // a sample due now (at a step boundary)
      continue;
    }
    const bool sample_due = next < t_end;
    if (sample_due && plant_.holdsThrough(next))
    {
      plant_.holdTo(next);  // a stick phase: nothing moves until the sample
      takeSample();
      continue;
    }
    plant_.setSearchHorizon(next);
    if (plant_.advanceTo(sample_due ? next : t_end, sink))
    {
      drive_->reevaluate(plant_.state());  // the load left the law's interval: switch (saturation)
      applyDriveLaw();
      continue;
    }
    if (!sample_due)
    {
      break;
    }
    takeSample();
  }
}

}  // namespace backlash_servo
