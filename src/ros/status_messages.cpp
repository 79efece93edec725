#include "status_messages.h"

namespace backlash_servo
{
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
