// The Plant with a compliant mesh (mesh_stiffness > 0), and rigid teeth while the law carries a sine: the motion is
// the CompliantJoint's (compliant_joint.h); this file translates between the Plant's interface (State, the
// motor-torque law, the drive's watch, events, the event budget, the energy ledger) and the joint's state vector and
// mesh events.
#include <cmath>
#include <cstdio>

#include "backlash_servo/plant/plant.h"
#include "compliant/compliant_joint.h"

namespace backlash_servo
{
Plant::CompliantHolder::CompliantHolder() = default;
Plant::CompliantHolder::~CompliantHolder() = default;
Plant::CompliantHolder::CompliantHolder(const CompliantHolder& other)
    : joint(other.joint ? std::make_unique<CompliantJoint>(*other.joint) : nullptr)
{}
Plant::CompliantHolder& Plant::CompliantHolder::operator=(const CompliantHolder& other)
{
  if (this != &other)
  {
    joint = other.joint ? std::make_unique<CompliantJoint>(*other.joint) : nullptr;
  }
  return *this;
}

void Plant::beginCompliant()
{
  compliant_.joint = std::make_unique<CompliantJoint>(params_, law_);
  compliant_.joint->setLoadWave(load_wave_);
  watchCompliant();
  horizonCompliant();
  compliantEnergyTracking();
}

bool Plant::settlesForever() const
{
  return params_.compliant() && compliant_.joint->settlesForever();
}

void Plant::setLoadWave(const Waveform& wave)
{
  for (int i = 0; i < wave.count; ++i)
  {
    const Sinusoid& t = wave.tones[static_cast<std::size_t>(i)];
    requireFinite("load_wave", t.amplitude);
    requireFinite("load_wave", t.frequency);
    requireFinite("load_wave", t.phase);
    requireFinite("load_wave", t.origin);
  }
  if (params_.compliant())
  {
    compliant_.joint->setLoadWave(wave);  // (refuses more sines than the modes hold, nothing changed)
    load_wave_ = wave;
    return;
  }
  // Rigid teeth: the sine's closed forms carry the motion while any sine is on, the thesis modes otherwise.
  const bool on = wave.active() || law_.wave.active();
  if (on && !compliant_.joint)
  {
    requireExactWave(params_, "a sinusoidal load torque");
    const Waveform before = load_wave_;
    load_wave_ = wave;
    try
    {
      enterWave(law_);
    }
    catch (...)
    {
      load_wave_ = before;
      throw;
    }
    return;
  }
  if (compliant_.joint)
  {
    compliant_.joint->setLoadWave(wave);
  }
  load_wave_ = wave;
  if (!on && compliant_.joint)
  {
    leaveWave();
  }
}

void Plant::enterWave(const MotorInput& law)
{
  requireExactWave(params_, "a sinusoidal motor torque (a sine command under the continuous law, or in effort mode)");
  syncLedger();
  wave_base_ = energy_;  // the ledger so far; the joint's own adds to it
  wave_balance_ = energyBalanceError();
  law_ = law;
  restartSegment();
  flight_model_.reset();
  beginCompliant();
  stateToCompliant();
}

void Plant::leaveWave()
{
  stateFromCompliant();
  const double balance = compliantBalanceError();
  compliant_.joint.reset();
  wave_base_ = EnergyLedger();
  wave_balance_ = 0.0;
  restartSegment();
  flight_model_.reset();
  if (state_.contact != Contact::Apart)
  {
    state_.motor_position = mesh_.motorPositionOnWall(state_.load_position, state_.contact);
    state_.motor_velocity = mesh_.motorVelocityInContact(state_.load_velocity);
  }
  // The thesis modes' ledger goes on with the same balance (its kinetic reference re-based, as setParams does).
  energy_.potential = 0.0;
  energy_.initial_kinetic = kineticEnergy() - energy_.input - energy_.load_work + energy_.motor_friction +
                            energy_.load_friction + energy_.motor_dry_friction + energy_.load_dry_friction +
                            energy_.impact_loss + balance;
}

void Plant::stateToCompliant()
{
  CompliantJoint& j = *compliant_.joint;
  Eigen::VectorXd x(j.size());
  x(0) = state_.motor_position;
  x(1) = state_.motor_velocity;
  const int l = j.loadIndex();
  x(l) = state_.load_position;
  x(l + 1) = state_.load_velocity;
  if (params_.torsionalShaft())
  {
    x(2) = state_.load_position + state_.shaft_twist;
    x(3) = state_.load_velocity + state_.shaft_twist_rate;
  }
  j.setState(x, state_.time);
  stateFromCompliant();
}

void Plant::stateFromCompliant()
{
  const CompliantJoint& j = *compliant_.joint;
  const Eigen::VectorXd& x = j.state();
  const int l = j.loadIndex();
  state_.time = j.time();
  state_.motor_position = x(0);
  state_.motor_velocity = x(1);
  state_.load_position = x(l);
  state_.load_velocity = x(l + 1);
  state_.shaft_twist = params_.torsionalShaft() ? x(2) - x(l) : 0.0;
  state_.shaft_twist_rate = params_.torsionalShaft() ? x(3) - x(l + 1) : 0.0;
  const CompliantEnergy& e = j.energy();
  const EnergyLedger& b = wave_base_;  // (zero with a compliant mesh)
  energy_.input = b.input + e.input;
  energy_.input_magnitude = b.input_magnitude + e.input_magnitude;
  energy_.motor_friction = b.motor_friction + e.motor_friction;
  energy_.load_friction = b.load_friction + e.load_friction;
  energy_.load_work = b.load_work + e.load_work;
  energy_.mesh_loss = b.mesh_loss + e.mesh_loss;
  energy_.shaft_loss = b.shaft_loss + e.shaft_loss;
  energy_.motor_dry_friction = b.motor_dry_friction + e.motor_dry_friction;
  energy_.load_dry_friction = b.load_dry_friction + e.load_dry_friction;
  energy_.impact_loss = b.impact_loss + e.impact_loss;
  energy_.potential = j.potentialEnergy();
  if (!j.rigid())
  {
    energy_.initial_kinetic = j.initialKinetic();
    energy_.initial_potential = j.initialPotential();
  }
  switch (j.mode())
  {
    case MeshMode::Forward:
    case MeshMode::ForwardK2:
      state_.contact = Contact::Forward;
      break;
    case MeshMode::Backward:
    case MeshMode::BackwardK2:
      state_.contact = Contact::Backward;
      break;
    default:
      state_.contact = Contact::Apart;
  }
}

void Plant::watchCompliant()
{
  compliant_.joint->setLaw(law_);
  compliant_.joint->setWatch(watch_lo_, watch_hi_);
}

void Plant::horizonCompliant()
{
  compliant_.joint->setSearchHorizon(search_horizon_);
}

bool Plant::advanceCompliant(double t_end, EventSink* sink)
{
  CompliantJoint& j = *compliant_.joint;
  const bool stopped = j.advanceTo(t_end, [&](MeshEvent e, int) {
    stateFromCompliant();
    if (j.rigid() && e == MeshEvent::Engage)
    {
      // An impact of rigid teeth (the thesis' impact map, compliant_joint.h).
      if (++impacts_ > event_budget_ && event_budget_ != 0)
      {
        throwImpactBudget();
      }
      if (sink != nullptr && sink->wantsImpacts())
      {
        const JointImpact& i = j.lastImpact();
        ImpactInfo info;
        info.wall = i.sigma > 0 ? Contact::Forward : Contact::Backward;
        info.load_velocity_before = i.load_velocity_before;
        info.load_velocity_after = i.outcome.load_velocity;
        info.motor_velocity_before = i.motor_velocity_before;
        info.motor_velocity_after = i.outcome.motor_velocity;
        info.approach_speed = i.closing;
        info.impulse = i.outcome.impulse;
        info.energy_loss = i.outcome.energy_loss;
        info.stuck = i.stuck;
        emit(sink, EventType::Impact, &info);
      }
      return;
    }
    switch (e)
    {
      case MeshEvent::Engage:
      case MeshEvent::Reengage:
        if (event_budget_ != 0 && j.contacts() > event_budget_)
        {
          char buf[200];
          std::snprintf(buf, sizeof buf,
                        "event budget of %llu contact phases exceeded at t = %.9g s (raise max_events to go on)",
                        static_cast<unsigned long long>(event_budget_), state_.time);
          throw EventBudgetExceeded(buf);
        }
        emit(sink, EventType::Engagement);
        break;
      case MeshEvent::Release:
        emit(sink, EventType::Separation);
        break;
      case MeshEvent::Maximum:
        emit(sink, EventType::Maximum);
        break;
      case MeshEvent::Minimum:
        emit(sink, EventType::Minimum);
        break;
      case MeshEvent::Stop:
      case MeshEvent::Breakaway:
        emit(sink, EventType::Rest);
        break;
      default:
        break;  // a sub-mode switch, leaving a released flank's penetration, the drive's watch: no event of the plant
    }
  });
  stateFromCompliant();
  requireBounded();  // an unstable loop stops with MotionDiverged, as with rigid teeth
  return stopped;
}

void Plant::setCompliantParams(const ServoParams& params, EventSink* sink, bool frame)
{
  if (!compliant_.joint || !params.compliant() || compliant_.joint->rigid())
  {
    throw InvalidParameterError("mesh_stiffness", formatNumber(params.mesh_stiffness) +
                                                      ": cannot switch between rigid teeth and a compliant mesh "
                                                      "during a run (start a new run with the new parameters)");
  }
  compliant_.joint->setParams(params, frame);  // throws (keeping the old ones) when the shaft model would change
  params_ = params;
  deriveConstants();
  watchCompliant();
  stateFromCompliant();
  emit(sink, EventType::ParameterChange);
}

bool Plant::compliantHeld(double* lo, double* hi) const
{
  const CompliantJoint& j = *compliant_.joint;
  if (!j.held())
  {
    return false;
  }
  j.heldMotorTorque(lo, hi);
  const double now = law_.torque(state_.load_position);
  return *lo <= now && now <= *hi;
}

void Plant::compliantHoldTo(double t)
{
  compliant_.joint->holdTo(t);
  state_.time = t;
}

double Plant::compliantBalanceError() const
{
  return compliant_.joint->energyBalanceError() + wave_balance_;
}

void Plant::compliantEnergyTracking()
{
  compliant_.joint->setEnergyTracking(track_energy_);
}

double Plant::compliantMeshTorque() const
{
  return compliant_.joint->meshTorque();
}

double Plant::compliantKineticEnergy() const
{
  const double omega_gear = state_.load_velocity + state_.shaft_twist_rate;
  return 0.5 * params_.motor_inertia * state_.motor_velocity * state_.motor_velocity +
         0.5 * params_.load_inertia * state_.load_velocity * state_.load_velocity +
         0.5 * params_.gear_inertia * omega_gear * omega_gear;
}

}  // namespace backlash_servo
