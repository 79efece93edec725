#include "status_messages.h"

namespace backlash_servo
{
namespace
{
uint8_t contactCode(Contact c)
{
  switch (c)
  {
    case Contact::Forward:
      return BacklashState::FORWARD;
    case Contact::Backward:
      return BacklashState::BACKWARD;
    default:
      return BacklashState::APART;
  }
}
}  // namespace

BacklashState backlashStateMessage(const Simulator& sim, double command, const ros::Time& stamp)
{
  const State& s = sim.state();
  BacklashState b;
  b.header.stamp = stamp;
  b.sim_time = s.time;
  b.contact = contactCode(s.contact);
  b.gap = sim.gap();
  b.mesh_torque = sim.meshTorque();
  b.motor_torque = sim.motorTorque();
  b.command = command;
  b.control_mode = sim.controlMode() == ControlMode::Effort ? BacklashState::EFFORT : BacklashState::POSITION;
  const EnergyLedger& e = sim.energy();
  b.energy_input = e.input;
  b.energy_motor_friction = e.motor_friction;
  b.energy_load_friction = e.load_friction;
  b.energy_impact_loss = e.impact_loss;
  b.energy_motor_dry_friction = e.motor_dry_friction;
  b.energy_load_dry_friction = e.load_dry_friction;
  b.energy_load_work = e.load_work;
  if (!sim.energyValid())
  {
    // A ramp of the continuous law ran in its moving frame: the ledger is the frame's (NaN: unknown).
    b.energy_input = b.energy_motor_friction = b.energy_load_friction = b.energy_impact_loss =
        b.energy_motor_dry_friction = b.energy_load_dry_friction = b.energy_load_work = NAN;
  }
  b.energy_kinetic = sim.kineticEnergy();
  b.impacts = sim.impactCount();
  return b;
}

ImpactEvent impactMessage(const Event& e, const ros::Time& stamp, const std::string& joint)
{
  ImpactEvent m;
  m.header.stamp = stamp;
  m.sim_time = e.state.time;
  m.wall = e.impact.wall == Contact::Backward ? ImpactEvent::BACKWARD : ImpactEvent::FORWARD;
  m.motor_velocity_before = e.impact.motor_velocity_before;
  m.motor_velocity_after = e.impact.motor_velocity_after;
  m.load_velocity_before = e.impact.load_velocity_before;
  m.load_velocity_after = e.impact.load_velocity_after;
  m.approach_speed = e.impact.approach_speed;
  m.impulse = e.impact.impulse;
  m.energy_loss = e.impact.energy_loss;
  m.stuck = e.impact.stuck;
  m.joint = joint;
  return m;
}

void fillVerdict(const ResponseMonitor& monitor, const CycleResolution& resolution, LimitCycleStatus* m)
{
  const LimitCycleReport& st = monitor.status();
  m->verdict = toString(st.verdict);
  m->detected = monitor.oscillating();
  m->error = m->detected ? st.error : 0.0;
  m->period = m->detected ? st.period : 0.0;
  m->maxima_per_period = m->detected ? static_cast<uint32_t>(st.multiplicity) : 0;
  const CycleShape cycle = monitor.cycleShape();
  m->peak_to_peak = m->detected ? cycle.peak_to_peak : 0.0;
  m->cycle_centre = m->detected ? cycle.centre : 0.0;
  m->peak_to_peak_counts = m->detected ? resolution.counts : NAN;
  m->peak_to_peak_arcmin = m->detected ? resolution.arcmin : NAN;
  m->below_encoder_resolution = m->detected && resolution.below_count;
  m->equilibrium = monitor.equilibrium();
  m->maxima_observed = static_cast<uint32_t>(monitor.maxima().size());
  if (!monitor.maxima().empty())
  {
    const Maximum& last = monitor.maxima().back();
    m->last_maximum_time = last.time;
    m->last_maximum_position = last.position;
    m->last_maximum_velocity = last.velocity;
  }
}
}  // namespace backlash_servo
