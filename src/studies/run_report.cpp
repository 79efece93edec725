#include "backlash_servo/studies/run_report.h"

#include <cmath>
#include <cstdio>

#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/model/param_table.h"

namespace backlash_servo
{
namespace
{
/// "params": the joint's keys, the drive's, the command and the loop's chart numbers.
void writeParamsJson(JsonWriter& j, const RunConfig& c)
{
  const ServoParams& p = c.params;
  j.beginObject("params");
  for (const ParamSpec* spec : paramsIn(ParamSection::Servo))
  {
    if (const auto* text = std::get_if<std::string ServoParams::*>(&spec->field))
    {
      j.field(spec->key, p.*(*text));
    }
    else
    {
      j.field(spec->key, p.*std::get<double ServoParams::*>(spec->field));
    }
  }
  j.beginObject("drive");
  for (const ParamSpec* spec : paramsIn(ParamSection::Drive))
  {
    if (const auto* f = std::get_if<double DriveParams::*>(&spec->field))
    {
      j.field(spec->key, c.drive.*(*f));
    }
  }
  j.field("control_law", c.drive.control_law).field("feedback", c.drive.feedback);
  j.field("compensation", c.drive.compensation).field("dither_shape", c.drive.dither_shape);
  j.endObject();
  j.field("command", c.command)
      .field("zeta", p.dampingRatio())
      .field("natural_frequency", p.naturalFrequency())
      .field("inertia_ratio", p.inertiaRatio())
      .field("friction_ratio", p.frictionRatio())
      // ζ and ω_n describe the continuous P law (the thesis' chart); for a digital, saturated or compensated loop
      // they are those of its gain K alone, and this says so.
      .field("zeta_describes_the_loop", c.drive.thesisLaw())
      .endObject();
}

/// The verdict, the cycle's size and centre, the equilibrium, the warnings and the steady answer.
void writeVerdictJson(JsonWriter& j, const RunConfig& c, const RunSummary& r)
{
  const bool lc = r.status.verdict == Verdict::LimitCycle || r.status.verdict == Verdict::Irregular;
  j.field("verdict", std::string(toString(r.status.verdict)));
  j.field("settled", r.settled);
  j.field("stopped_by", r.stopped_by);
  j.field("limit_cycle", lc);
  j.field("limit_cycle_error", lc ? r.status.error : 0.0);
  if (lc)
  {
    j.field("period", r.status.period);
  }
  else
  {
    j.null("period");
  }
  j.field("maxima_per_period", static_cast<long long>(r.status.multiplicity));
  // The load's peak-to-peak amplitude in the cycle and the cycle's centre [rad] (sustained oscillations only).
  if (lc)
  {
    j.field("peak_to_peak", r.cycle.peak_to_peak).field("cycle_centre", r.cycle.centre);
  }
  else
  {
    j.null("peak_to_peak").null("cycle_centre");
  }
  // The cycle in counts of the encoder the loop reads and in arcmin at the load; whether it is below one count.
  j.field("peak_to_peak_counts", r.resolution.counts).field("peak_to_peak_arcmin", r.resolution.arcmin);
  if (lc && std::isfinite(r.resolution.counts))
  {
    j.field("below_encoder_resolution", r.resolution.below_count);
  }
  else
  {
    j.null("below_encoder_resolution");
  }
  j.field("equilibrium", r.equilibrium);
  j.beginArray("warnings");  // valid values that are probably not what was meant (inputWarnings)
  for (const std::string& w : inputWarnings(c))
  {
    j.field(nullptr, w);
  }
  j.endArray();  // where the loop rests [rad]; the verdict judges maxima against it
  // Where a converged joint comes to rest and θ_∞ − θ_R [rad] (null unless found), and how it was found.
  j.field("steady_position", r.steady.position).field("steady_error", r.steady.error);
  if (r.steady.basis == SteadyBasis::None)
  {
    j.null("steady_basis");
  }
  else
  {
    j.field("steady_basis", std::string(steadyBasisName(r.steady.basis)));
  }
}

/// The impacts, the energy ledger [J] and the final state.
void writeEnergyJson(JsonWriter& j, const RunConfig& c, const RunSummary& r)
{
  j.field("impacts", static_cast<long long>(r.impacts));
  if (c.params.compliant())
  {
    j.field("contact_phases", static_cast<long long>(r.contact_phases));
  }
  j.beginObject("energy")
      .field("input", r.energy.input)
      .field("motor_friction", r.energy.motor_friction)
      .field("load_friction", r.energy.load_friction)
      .field("impact_loss", r.energy.impact_loss)
      .field("load_work", r.energy.load_work)
      .field("motor_dry_friction", r.energy.motor_dry_friction)
      .field("load_dry_friction", r.energy.load_dry_friction)
      .field("kinetic", r.kinetic)
      .field("initial_kinetic", r.energy.initial_kinetic)
      .field("balance_error", r.balance_error);
  if (c.params.compliant())
  {
    j.field("mesh_loss", r.energy.mesh_loss)
        .field("shaft_loss", r.energy.shaft_loss)
        .field("potential", r.energy.potential)
        .field("initial_potential", r.energy.initial_potential);
  }
  j.endObject();
  const State& s = r.final_state;
  j.beginObject("final_state")
      .field("time", s.time)
      .field("load_position", s.load_position)
      .field("load_velocity", s.load_velocity)
      .field("motor_position", s.motor_position)
      .field("motor_velocity", s.motor_velocity)
      .field("contact", std::string(toString(s.contact)));
  if (c.params.torsionalShaft())
  {
    j.field("shaft_twist", s.shaft_twist).field("shaft_twist_rate", s.shaft_twist_rate);
  }
  j.endObject();
}
}  // namespace

void writeRunJson(std::ostream& out, const RunConfig& c, const RunSummary& r, double wall_seconds)
{
  const TrackingFigures& tracking = r.tracking;
  JsonWriter j(out);
  j.beginObject();
  writeParamsJson(j, c);
  writeVerdictJson(j, c, r);
  // Tracking figures from a sampled replay of the run (null where they do not apply).
  j.field("settling_band", tracking.band)
      .field("settling_time", tracking.settling_time)
      .field("rms_error", tracking.rms_error)
      .field("steady_rms_error", tracking.steady_rms_error)
      .field("max_error", tracking.max_error)
      .field("overshoot", tracking.overshoot)
      .field("tracking_sample_rate", r.tracking_rate);
  j.beginArray("maxima");
  for (const Maximum& m : r.maxima)
  {
    j.beginObject().field("time", m.time).field("position", m.position).field("velocity", m.velocity).endObject();
  }
  j.endArray();
  writeEnergyJson(j, c, r);
  j.field("simulated_time", r.simulated);
  j.field("wall_time", wall_seconds);
  j.endObject();
  out << "\n";
}

std::string resolutionText(const CycleResolution& r)
{
  if (!std::isfinite(r.arcmin))
  {
    return "";
  }
  char buf[200];
  if (!std::isfinite(r.counts))
  {
    std::snprintf(buf, sizeof buf, " (%.3g arcmin at the load)", r.arcmin);
    return buf;
  }
  std::snprintf(buf, sizeof buf, " (%.3g counts of the encoder the loop reads, %.3g arcmin at the load)%s", r.counts,
                r.arcmin, r.below_count ? " — below one count: a hunt the loop cannot see" : "");
  return buf;
}

void writeRobotRunJson(std::ostream& out, const std::string& robot_name, const RobotRunResult& r, double wall_seconds)
{
  JsonWriter w(out);
  w.beginObject().field("robot", robot_name).field("simulated", r.simulated).field("stopped_by", r.stopped_by);
  w.field("wall_time", wall_seconds).beginArray("joints");
  for (const RobotJointResult& j : r.joints)
  {
    w.beginObject().field("name", j.name).field("verdict", std::string(toString(j.status.verdict)));
    w.field("error", j.status.error).field("period", j.status.period).field("peak_to_peak", j.cycle.peak_to_peak);
    w.field("impacts", static_cast<long long>(j.impacts)).field("load_position", j.state.load_position);
    w.field("motor_position", j.state.motor_position).field("load_torque", j.load_torque);
    w.field("load_inertia", j.load_inertia).endObject();
  }
  w.endArray().endObject();
  out << "\n";
}

}  // namespace backlash_servo
