#include "backlash_servo/simulation/simulator.h"

#include "compliant/compliant_joint.h"

#include <algorithm>
#include <cmath>
#include <limits>
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
      frame_rate_(other.frame_rate_),
      frame_start_(other.frame_start_),
      motor_bias_(other.motor_bias_),
      true_params_(other.true_params_),
      energy_valid_(other.energy_valid_),
      event_budget_(other.event_budget_),
      samples_(other.samples_),
      sample_observer_(other.sample_observer_)
{
  input_horizon_ = other.input_horizon_;
}

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
    frame_rate_ = other.frame_rate_;
    frame_start_ = other.frame_start_;
    motor_bias_ = other.motor_bias_;
    true_params_ = other.true_params_;
    energy_valid_ = other.energy_valid_;
    event_budget_ = other.event_budget_;
    samples_ = other.samples_;
    sample_observer_ = other.sample_observer_;
    input_horizon_ = other.input_horizon_;
  }
  return *this;
}

namespace
{
/// A state of the frame moving at v [rad/s] (motor: vm = v/ρ) since t_a [s], in the joint's angles.
void toJointFrame(State* s, double v, double vm, double t_a)
{
  const double tau = s->time - t_a;
  s->load_position += v * tau;
  s->load_velocity += v;
  s->motor_position += vm * tau;
  s->motor_velocity += vm;
}

/// Events of a plant running in a ramp's frame, converted to the joint's (maxima of the frame are dropped).
class FrameSink : public EventSink
{
 public:
  FrameSink(EventSink* next, double v, double rho, double t_a, double bias)
      : next_(next), v_(v), vm_(v / rho), t_a_(t_a), bias_(bias)
  {}
  void onEvent(const Event& e) override
  {
    if (e.type == EventType::Maximum || e.type == EventType::Minimum)
    {
      return;  // ẏ_c = 0 is not a turning point of θ_c
    }
    Event c = e;
    const double tau = c.state.time - t_a_;
    toJointFrame(&c.state, v_, vm_, t_a_);
    // a − b − k y_c = (a − b + k v τ) − k θ_c: the law in the joint's angles, without the frame's friction bias.
    c.law.offset += -bias_ + c.law.stiffness * v_ * tau;
    next_->onEvent(c);
  }
  bool wantsImpacts() const override { return next_->wantsImpacts(); }

 private:
  EventSink* next_;
  double v_, vm_, t_a_, bias_;
};
}  // namespace

State Simulator::state() const
{
  State s = plant_.state();
  if (frame_rate_ != 0.0)
  {
    toJointFrame(&s, frame_rate_, frame_rate_ / true_params_.gear_ratio, frame_start_);
  }
  return s;
}

double Simulator::kineticEnergy() const
{
  if (frame_rate_ == 0.0)
  {
    return plant_.kineticEnergy();
  }
  const State s = state();
  const double gear_velocity = s.load_velocity + s.shaft_twist_rate;
  return 0.5 * true_params_.motor_inertia * s.motor_velocity * s.motor_velocity +
         0.5 * true_params_.load_inertia * s.load_velocity * s.load_velocity +
         0.5 * true_params_.gear_inertia * gear_velocity * gear_velocity;
}

void Simulator::enterFrame(double v)
{
  true_params_ = plant_.params();
  const double rho = true_params_.gear_ratio;
  frame_rate_ = v;
  frame_start_ = plant_.state().time;
  plant_.shiftFrame(0.0, -v, 0.0, -v / rho);
  ServoParams p = true_params_;
  p.load_torque -= p.load_friction * v;  // J_L ÿ + f_L ẏ = Q + T_ext − f_L v
  plant_.setParams(p, nullptr, true);
  motor_bias_ = -true_params_.motor_friction * v / rho;  // J_m ÿ_m + f_m ẏ_m = T_m − f_m v/ρ − ρQ
  energy_valid_ = false;
  drive_->reevaluate(plant_.state());
  applyDriveLaw();
}

void Simulator::leaveFrame()
{
  if (frame_rate_ == 0.0)
  {
    return;
  }
  const double v = frame_rate_;
  const double vm = v / true_params_.gear_ratio;
  const double tau = plant_.state().time - frame_start_;
  plant_.shiftFrame(v * tau, v, vm * tau, vm);
  frame_rate_ = 0.0;
  motor_bias_ = 0.0;
  plant_.setParams(true_params_, nullptr, true);  // (back on the mesh: the gap is frame-independent)
  drive_->reevaluate(plant_.state());
  applyDriveLaw();
}

void Simulator::applyPiece(double t, EventSink* sink)
{
  double slope, until, base = 0.0;
  Waveform wave;
  profile_->pieceAt(t, &slope, &until, &wave, &base);
  next_change_ = until;
  if (wave.active())
  {
    // A sine segment under the continuous law: its centre, and the sine carried by the modes.
    applyCommand(base, sink, wave);
    return;
  }
  applyCommand(profile_->at(t), sink);
  if (slope != 0.0)
  {
    enterFrame(slope);
  }
}

void Simulator::setState(const State& state)
{
  leaveFrame();
  plant_.setState(state);
  energy_valid_ = true;  // a fresh ledger (a ramp in force enters its frame again below)
  if (stepped_)
  {
    applyPiece(state.time, nullptr);
  }
}

void Simulator::takeSample()
{
  if (event_budget_ != 0 && ++samples_ > event_budget_)
  {
    throw EventBudgetExceeded("event budget of " + std::to_string(event_budget_) +
                              " controller samples exceeded at t = " + std::to_string(plant_.state().time) +
                              " s (raise max_events to go on)");
  }
  drive_->sample(plant_.state());
  applyDriveLaw();
  if (sample_observer_)
  {
    sample_observer_(plant_.state(), *drive_);
  }
}

bool Simulator::atRestForever() const
{
  if (motor_bias_ != 0.0 || (profile_ && !std::isinf(profile_->nextChange(plant_.state().time))))
  {
    return false;  // (in a ramp's moving frame the law changes)
  }
  double lo, hi, until;
  if (plant_.heldTorqueRange(&lo, &hi, &until))
  {
    return std::isinf(until) && drive_->steady();
  }
  // A stuck load and a motor settling on the mesh spring: the law must stay as it is — one that reads only the stuck
  // load (or nothing) and no longer changes.
  return plant_.settlesForever() && drive_->steady() && !drive_->readsMotor();
}

bool Simulator::holdSamples(double t_end)
{
  double lo, hi, until;
  if (sample_observer_ || motor_bias_ != 0.0 || !plant_.heldTorqueRange(&lo, &hi, &until))
  {
    return false;  // an observer sees every sample; the frames of ramps belong to the continuous law
  }
  const long left = event_budget_ == 0          ? std::numeric_limits<long>::max()
                    : samples_ >= event_budget_ ? 0
                                                : static_cast<long>(event_budget_ - samples_);
  double last = 0.0;
  const long taken = drive_->holdSamples(plant_.state(), std::min(t_end, until), lo, hi, left, &last);
  if (taken == 0)
  {
    return false;
  }
  if (event_budget_ != 0)
  {
    samples_ += taken;
  }
  held_samples_ += taken;
  plant_.holdTo(last);
  applyDriveLaw();  // the last torque: the rest rule decides whether the joint breaks away
  return true;
}

void Simulator::applyDriveLaw()
{
  MotorInput law = drive_->law();
  if (motor_bias_ != 0.0)
  {
    law.offset += motor_bias_;
  }
  plant_.setLaw(law);
  double lo, hi;
  drive_->watchInterval(&lo, &hi);
  plant_.setWatch(lo, hi);
}

void Simulator::setDrive(std::unique_ptr<Drive> drive, EventSink* sink)
{
  input_horizon_ = INFINITY;
  leaveFrame();
  profile_.reset();
  stepped_ = false;
  drive->configure(plant_.params());
  drive->sample(plant_.state());
  drive->reevaluate(plant_.state());
  drive_ = std::move(drive);
  applyDriveLaw();
  plant_.emit(sink, EventType::InputChange);
}

bool Simulator::retuneDrive(const DriveParams& drive, EventSink* sink)
{
  auto* sampled = dynamic_cast<SampledDrive*>(drive_.get());
  if (sampled == nullptr)
  {
    return false;
  }
  if (!sampled->retune(drive))  // (a digital drive never runs in a ramp's moving frame)
  {
    return false;
  }
  applyDriveLaw();
  plant_.emit(sink, EventType::InputChange);
  return true;
}

void Simulator::setCommand(double command, EventSink* sink)
{
  setCommandWave(command, Sinusoid(), sink);
}

void Simulator::setCommandWave(double command, const Waveform& wave, EventSink* sink)
{
  requireFinite("command", command);
  if (wave.active())
  {
    requireExactWave(plant_.params(), "a sine command under the continuous law");
  }
  if (wave.active() && dynamic_cast<ProportionalDrive*>(drive_.get()) == nullptr)
  {
    throw InvalidParameterError("command",
                                "a sine command needs the continuous law (a digital drive samples a sine "
                                "profile; in effort mode set a sine torque)");
  }
  leaveFrame();
  if (profile_)
  {
    if (auto* sampled = dynamic_cast<SampledDrive*>(drive_.get()))
    {
      sampled->setProfile(nullptr);
    }
    profile_.reset();
    stepped_ = false;
  }
  applyCommand(command, sink, wave);
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
    profile->requireTakenBy(sampled != nullptr, params().hasDryFriction(), params().compliant(),
                            params().torsionalShaft() ? 1 : MAX_TONES);
    const auto* proportional = dynamic_cast<const ProportionalDrive*>(drive_.get());
    if (sampled == nullptr && !profile->piecewiseLinear() && (proportional == nullptr || !proportional->linear()))
    {
      throw InvalidParameterError("profile",
                                  "a sine under the continuous law needs its linear law (no torque_limit or "
                                  "compensation): set controller_rate > 0 Hz for a digital drive");
    }
  }
  leaveFrame();
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
    applyPiece(plant_.state().time, sink);
  }
}

void Simulator::applyCommand(double command, EventSink* sink, const Waveform& wave)
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
    proportional->setCommandWave(command, wave);  // keeps its torque limit (a wave needs none)
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

void Simulator::setMotorTorque(double torque, const Waveform& wave, EventSink* sink)
{
  if (wave.active())
  {
    requireExactWave(plant_.params(), "a sine torque");
  }
  setDrive(std::make_unique<EffortDrive>(torque, wave), sink);
}

void Simulator::setLoadTorqueWave(const Waveform& wave, EventSink* sink)
{
  plant_.setLoadWave(wave);
  plant_.emit(sink, EventType::InputChange);
}

void Simulator::setParams(const ServoParams& params, EventSink* sink)
{
  params.validate();
  const double v = frame_rate_;
  if (v != 0.0 && params.hasDryFriction())
  {
    throw InvalidParameterError("profile",
                                "dry friction while the continuous law runs a ramp (set it before or after "
                                "the ramp, or use a digital drive)");
  }
  leaveFrame();
  drive_->configure(params);
  drive_->reevaluate(plant_.state());
  applyDriveLaw();
  plant_.setParams(params, sink);
  if (v != 0.0)
  {
    enterFrame(v);  // the ramp goes on in the frame of the new parameters
  }
}

void Simulator::advanceTo(double t_end, EventSink* sink)
{
  const double now = plant_.state().time;
  if (!(t_end >= now) || !std::isfinite(t_end))
  {
    throw std::invalid_argument("advanceTo: target time " + std::to_string(t_end) + " s is before the current time " +
                                std::to_string(now) + " s or not finite");
  }
  while (stepped_ && next_change_ <= t_end)
  {
    const double change = next_change_;
    advanceDriveTo(change, sink);
    leaveFrame();
    applyPiece(change, sink);  // a step of θ_R, or a ramp's start or end, at its known instant
  }
  advanceDriveTo(t_end, sink);
}

void Simulator::takeSampleDue(EventSink* sink)
{
  const double slack = 1e-12 * std::max(1.0, std::fabs(plant_.state().time));
  const double next = drive_->nextEventTime(plant_.state().time);
  if (next > plant_.state().time + slack)
  {
    return;
  }
  if (next > plant_.state().time)
  {
    advanceTo(next, sink);
  }
  if (drive_->nextEventTime(plant_.state().time) <= plant_.state().time)
  {
    takeSample();
  }
}

void Simulator::advanceDriveTo(double t_end, EventSink* sink)
{
  FrameSink framed(sink, frame_rate_, params().gear_ratio, frame_start_, motor_bias_);
  if (frame_rate_ != 0.0 && sink != nullptr)
  {
    sink = &framed;
  }
  while (plant_.state().time < t_end)
  {
    const double next = drive_->nextEventTime(plant_.state().time);
    if (next <= plant_.state().time)
    {
      takeSample();  // a sample due now (at a step boundary)
      continue;
    }
    const bool sample_due = next < t_end;
    if (sample_due && plant_.holdsThrough(next))
    {
      if (!holdSamples(t_end))
      {
        plant_.holdTo(next);  // a stick phase: nothing moves until the sample
        takeSample();
      }
      continue;
    }
    plant_.setSearchHorizon(input_horizon_ > plant_.state().time ? std::min(next, input_horizon_) : next);
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

std::uint64_t Simulator::contactPhases() const
{
  return plant_.compliantJoint() ? plant_.compliantJoint()->contacts() : 0;
}

}  // namespace backlash_servo
