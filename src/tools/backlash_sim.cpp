// backlash_sim: one exact run of the backlash servo from the command line (see docs/cli.md).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/rigid/modes.h"
#include "backlash_servo/studies/run_report.h"
#include "progress.h"
#include "sim_robot.h"

using namespace backlash_servo;

namespace
{
const char* HEADER = R"(usage: backlash_sim [parameters] [options]
Simulates a unit step (or any command) of the geared servo with backlash exactly and reports whether it settles
or falls into a limit cycle. Defaults: the thesis' limit-cycle case (App. D1). Physical and chart forms cannot be
mixed; the chart form needs --zeta --inertia-ratio --friction-ratio.
)";

FlagParser makeParser()
{
  return FlagParser(
      "backlash_sim", HEADER,
      keysOfSections(
          {ParamSection::Servo, ParamSection::Chart, ParamSection::Drive, ParamSection::Initial, ParamSection::Run}),
      {{"config", "FILE.yaml",
        "the same keys in snake_case (the YAML the node loads; flags override it); a robot file (`joints:`, "
        "docs/robot.md) runs every joint of the arm together, a verdict each"},
       {"json", "", "one JSON object on stdout"},
       {"csv", "FILE", "trajectory samples plus one row per event"},
       {"sample_rate", "HZ", "CSV sample rate [Hz] in (0, 1e6] (default 100)"}});
}

/// Writes trajectory samples and event rows as CSV.
class CsvWriter : public EventSink
{
 public:
  CsvWriter(std::ostream& out, const ServoParams& params) : out_(out), params_(params), mesh_(params)
  {
    out_ << "time,load_position,load_velocity,motor_position,motor_velocity,gap,contact,mesh_torque,motor_torque,"
            "event\n";
  }
  void onEvent(const Event& e) override
  {
    // A compliant mesh's torque depends on its deflection: the plant's own, at the event (rigid teeth: from the law).
    const double mesh_torque = params_.compliant() ? e.mesh_torque : meshTorque(params_, e.law, e.state);
    row(e.state, mesh_torque, e.law.torque(e.state.load_position), toString(e.type));
  }
  void sample(const Simulator& sim) { row(sim.state(), sim.meshTorque(), sim.motorTorque(), ""); }

 private:
  void row(const State& s, double mesh_torque, double motor_torque, const char* event)
  {
    char buf[512];
    std::snprintf(buf, sizeof buf, "%.15g,%.15g,%.15g,%.15g,%.15g,%.15g,%s,%.15g,%.15g,%s\n", s.time, s.load_position,
                  s.load_velocity, s.motor_position, s.motor_velocity,
                  mesh_.gap(s.load_position + s.shaft_twist, s.motor_position), toString(s.contact), mesh_torque,
                  motor_torque, event);
    out_ << buf;
  }

  std::ostream& out_;
  ServoParams params_;
  GearMesh mesh_;
};

/// The tracking figures' line (RunSummary::tracking).
void writeTracking(std::ostream& out, const TrackingFigures& t, double rate)
{
  char settle[64] = "- (still outside at the end)";
  if (!std::isnan(t.settling_time))
  {
    std::snprintf(settle, sizeof settle, "%.6g s", t.settling_time);
  }
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "tracking (sampled at %.4g Hz): settling time %s into ±%.4g rad, steady-state RMS error %.4g rad, "
                "RMS error %.4g rad, overshoot %.4g rad\n",
                rate, settle, t.band, t.steady_rms_error, t.rms_error, t.overshoot);
  out << buf;
}

/// Where a converged joint comes to rest and why that figure: the steady answer in words.
std::string steadyLine(const RunConfig& c, const RunSummary& r)
{
  const SteadyAnswer& s = r.steady;
  char buf[320];
  const char* why = s.basis == SteadyBasis::Held ? "held there by dry friction"
                    : s.basis == SteadyBasis::Limit
                        ? "where it settles: run on until its remaining travel was within rounding"
                    : r.equilibrium != c.command ? "the loop's equilibrium under the load torque"
                                                 : "the loop's equilibrium";
  if (s.basis == SteadyBasis::Unsettled)
  {
    std::snprintf(buf, sizeof buf, "steady error n/a: not at rest (%s); at the end theta_c = %.9g rad", s.note.c_str(),
                  r.final_state.load_position);
  }
  else
  {
    std::snprintf(buf, sizeof buf, "comes to rest at theta_c = %.9g rad, steady error %.6g rad (%s)", s.position,
                  s.error, why);
  }
  return buf;
}

void writeSummary(std::ostream& out, const RunConfig& c, const RunSummary& r, double wall_seconds)
{
  const ServoParams& p = c.params;
  char buf[512];
  // ζ and ω_n are those of the continuous P law (the thesis' chart form); for any other loop they describe the gain K
  // alone, and are labelled so.
  const std::string chart =
      c.drive.thesisLaw() ? "chart"
                          : "chart of the continuous P law with this K (not this " + c.drive.control_law + " loop)";
  std::snprintf(buf, sizeof buf,
                "servo: J_m=%g J_L=%g kg·m², f_m=%g f_L=%g N·m·s/rad, K=%g N·m/rad, rho=%g, backlash=%g rad, e=%g\n"
                "%s: zeta=%.4g  w_n=%.4g rad/s  rho²J_L/J_m=%.4g  rho²f_L/F_T=%.4g;  command %g -> %g rad%s\n",
                p.motor_inertia, p.load_inertia, p.motor_friction, p.load_friction, p.gain, p.gear_ratio, p.backlash,
                p.restitution, chart.c_str(), p.dampingRatio(), p.naturalFrequency(), p.inertiaRatio(),
                p.frictionRatio(), c.initial.load_position, c.command,
                c.profile ? " (final value of the profile)" : "");
  out << buf;
  if (p.compliant())
  {
    std::snprintf(buf, sizeof buf,
                  "compliant mesh (%s): c=%g N·m/rad, d=%g N·m·s/rad, J_g=%g kg·m²; shaft k_s=%g N·m/rad, d_s=%g "
                  "N·m·s/rad%s (e is not used)\n",
                  p.mesh_law.c_str(), p.mesh_stiffness, p.mesh_damping, p.gear_inertia, p.shaft_stiffness,
                  p.shaft_damping, p.torsionalShaft() ? "" : " (rigid shaft)");
    out << buf;
  }
  if (r.status.verdict == Verdict::LimitCycle)
  {
    std::snprintf(buf, sizeof buf,
                  "verdict: LIMIT CYCLE, error %.6g rad, period %.6g s (%d maxima per period); load %.6g rad peak to "
                  "peak about %.9g rad%s\n",
                  r.status.error, r.status.period, r.status.multiplicity, r.cycle.peak_to_peak, r.cycle.centre,
                  resolutionText(r.resolution).c_str());
  }
  else if (r.status.verdict == Verdict::Irregular)
  {
    std::snprintf(buf, sizeof buf,
                  "verdict: IRREGULAR sustained oscillation (maxima never settle), largest error %.6g rad, "
                  "mean time between maxima %.6g s; load %.6g rad peak to peak about %.9g rad%s\n",
                  r.status.error, r.status.period, r.cycle.peak_to_peak, r.cycle.centre,
                  resolutionText(r.resolution).c_str());
  }
  else if (r.status.verdict == Verdict::Converged)
  {
    std::snprintf(buf, sizeof buf, "verdict: converges (no limit cycle); %s\n", steadyLine(c, r).c_str());
  }
  else if (r.status.verdict == Verdict::Diverged)
  {
    std::snprintf(buf, sizeof buf, "verdict: DIVERGED after %g s (the loop is unstable)\n", r.simulated);
  }
  else
  {
    if (r.maxima.size() >= 3)
    {
      std::snprintf(buf, sizeof buf, "verdict: undecided after %g s (latest fixed-point estimate %.6g rad)\n",
                    r.simulated, r.status.extrapolated);
    }
    else
    {
      std::snprintf(buf, sizeof buf, "verdict: undecided after %g s (%zu positive maxima so far)\n", r.simulated,
                    r.maxima.size());
    }
  }
  out << buf;
  out << "positive maxima (t [s], theta_c [rad]):";
  for (std::size_t i = 0; i < r.maxima.size(); ++i)
  {
    if (i == 6 && r.maxima.size() > 8)
    {
      out << "  ...";
      i = r.maxima.size() - 2;
    }
    std::snprintf(buf, sizeof buf, "  (%.4f, %.6f)", r.maxima[i].time, r.maxima[i].position);
    out << buf;
  }
  if (p.compliant())
  {
    std::snprintf(buf, sizeof buf,
                  "\ncontact phases: %llu; simulated %.6g s in %.3g ms wall; energy balance residual %.3g J of %.3g J "
                  "input (mesh losses %.3g J, shaft losses %.3g J)\n",
                  static_cast<unsigned long long>(r.contact_phases), r.simulated, wall_seconds * 1e3, r.balance_error,
                  r.energy.input, r.energy.mesh_loss, r.energy.shaft_loss);
  }
  else
  {
    std::snprintf(buf, sizeof buf,
                  "\nimpacts: %llu; simulated %.6g s in %.3g ms wall; energy balance residual %.3g J of %.3g J input\n",
                  static_cast<unsigned long long>(r.impacts), r.simulated, wall_seconds * 1e3, r.balance_error,
                  r.energy.input);
  }
  out << buf;
}
}  // namespace

int main(int argc, char** argv)
{
  FlagParser options = makeParser();
  RunConfig config;
  std::string csv_path;
  double sample_rate = 100.0;
  try
  {
    options.acceptRobotFiles();
    options.parse(argc, argv);
    csv_path = options.option("csv");
    sample_rate = options.optionNumber("sample_rate", sample_rate);
    // Above 1 MHz the sample period nears the rounding of the time itself (a rate of 1e308 Hz never advances).
    if (!(sample_rate > 0.0 && sample_rate <= 1e6))
    {
      throw ConfigError("--sample-rate must be in (0, 1e6] Hz (got " + options.option("sample_rate") + ")");
    }
    if (options.robotConfig())
    {
      return simulateRobot(options, sample_rate);
    }
    config = runConfigFrom(options.keys());
    config.tracking = true;
    if (!options.given("json"))
    {
      for (const std::string& w : inputWarnings(config))
      {
        std::cerr << "backlash_sim: warning: " << w << "\n";
      }
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_sim: error: " << e.what() << "\n";
    return 2;
  }
  try
  {
    std::unique_ptr<SafeOutput> csv_file;
    std::unique_ptr<CsvWriter> csv;
    SampleCallback on_sample;
    double sample_period = 0.0;
    if (!csv_path.empty())
    {
      // Streamed to a private temporary beside FILE and renamed only when complete: a failed or interrupted run
      // never leaves a half-written FILE (nor its temporary).
      removeTemporariesOnSignals();
      csv_file = std::make_unique<SafeOutput>(
          "--csv", csv_path, std::vector<std::string>{options.option("config"), options.keys().text("profile", "")});
      csv = std::make_unique<CsvWriter>(csv_file->stream(), config.params);
      sample_period = 1.0 / sample_rate;
      on_sample = [&](const Simulator& sim) { csv->sample(sim); };
    }
    Progress progress(isatty(2) != 0, 1.0);
    const auto start = std::chrono::steady_clock::now();
    const RunSummary result =
        runResponse(config, csv.get(), sample_period, on_sample, [&](double done) { progress.update(done); });
    progress.finish();
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (csv_file)
    {
      csv_file->commit();
    }
    if (result.stopped_by == "event_budget" || result.stopped_by == "diverged")
    {
      std::cerr << "backlash_sim: stopped: " << result.message << "\n";
    }
    if (options.given("json"))
    {
      writeRunJson(std::cout, config, result, wall);
    }
    else
    {
      writeSummary(std::cout, config, result, wall);
      writeTracking(std::cout, result.tracking, result.tracking_rate);
    }
    flushStdout();
  }
  catch (const ConfigError& e)
  {
    std::cerr << "backlash_sim: error: " << e.what() << "\n";
    return 2;
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_sim: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
