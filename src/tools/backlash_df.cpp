// backlash_df: the describing-function prediction of the joint's limit cycle beside the exact simulation.
// See docs/describing_function.md.
#include <cmath>
#include <complex>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/run_program.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/frequency/limit_cycle_prediction.h"
#include "backlash_servo/simulation/simulator.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_df [--config FILE.yaml] [any servo or initial-state flag] [--command THETA_R] [--json]
                  [--png FILE.png]
Predicts the joint's limit cycle by harmonic balance with the classical describing function of backlash (hysteresis
in the feedback of the linear servo G(s) = w_n²/(s² + 2 zeta w_n s)) — every intersection with its stability — and
from each, with the numerical describing function of the real element (the load's inertia, friction and impacts,
driven by an exact sine); and simulates the joint exactly beside them: the cycle's amplitude (fundamental of the
backlash input rho*theta_m about its centre), peak and frequency, and the error of each prediction. The continuous P
law (the thesis' loop), or a digital P, PID or cascade law on the load's or the motor's angle (--controller-rate,
--control-law pid|cascade, --feedback motor, optional --controller-delay 1): its sampled-and-held fundamental takes
the place of K. With a compliant mesh
(--mesh-stiffness > 0, rigid shaft) the classical element is the mesh's dead zone between the two bodies, the
numerical one the load behind the mesh's spring and damper.
SI units: amplitudes in rad, frequencies in rad/s.
)";

struct Options
{
  RunConfig config;
  bool json = false;
  std::string config_path, png_path;
};

Options parse(int argc, char** argv)
{
  FlagParser parser("backlash_df", HEADER,
                    keysOfSections({ParamSection::Servo, ParamSection::Chart, ParamSection::Drive,
                                    ParamSection::Initial, ParamSection::Run}),
                    {{"config", "FILE.yaml", "the joint's keys in snake_case (flags override it)"},
                     {"json", "", "one JSON object on stdout"},
                     {"png", "FILE.png", "the Nyquist chart: G(jw), -1/N(A), the predictions and the exact cycle"}});
  parser.parse(argc, argv);
  Options o;
  o.config = runConfigFrom(parser.keys());
  o.json = parser.given("json");
  o.config_path = parser.option("config");
  o.png_path = parser.option("png");
  if (parser.given("png") && !isPngPath(o.png_path))
  {
    throw ConfigError("--png: '" + o.png_path + "' must end in .png");
  }
  requireDescribable(o.config);  // (refused before any run, with the key named)
  return o;
}

/// The chart's data to a private directory, drawn there by df_chart.py (run without a shell), then moved into place
/// through the safe-write path.
void drawChart(const std::function<std::complex<double>(double)>& g, double wn, const ServoParams& p,
               const std::vector<HarmonicBalance>& predictions, const SimulatedCycle& sim, const std::string& script,
               SafeOutput& png)
{
  // The element whose −1/N(A) is drawn: backlash as hysteresis, or a compliant mesh's dead zone (its amplitudes are
  // the deflection's: the exact cycle's ρθ_m amplitude has no point on that locus).
  const double backlash = p.backlash;
  const bool compliant = p.mesh_stiffness > 0.0;
  const auto df = [&](double a) {
    return compliant ? std::complex<double>(deadZoneDescribingFunction(a, 0.5 * backlash), 0.0)
                     : backlashDescribingFunction(a, backlash);
  };
  TemporaryDirectory dir("backlash_df");
  {
    std::ofstream element(dir.file("element.txt"));
    element << (compliant ? "classical DF of the compliant mesh's dead zone" : "classical DF of backlash") << "\n";
    std::ofstream nyquist(dir.file("nyquist.csv")), locus(dir.file("locus.csv")), points(dir.file("points.csv"));
    nyquist.precision(10);
    locus.precision(10);
    points.precision(10);
    nyquist << "frequency,re,im\n";
    for (int i = 0; i <= 2000; ++i)
    {
      const double w = wn * std::pow(10.0, -3.0 + 6.0 * i / 2000.0);
      const std::complex<double> z = g(w);
      if (std::abs(z) < 1e3)
      {
        nyquist << w << "," << z.real() << "," << z.imag() << "\n";
      }
    }
    locus << "amplitude,re,im\n";
    for (int i = 0; i <= 2000; ++i)
    {
      const double a = 0.5 * backlash * (1.0 + std::pow(10.0, -6.0 + 9.0 * i / 2000.0));
      const std::complex<double> z = -1.0 / df(a);
      if (std::abs(z) < 1e3)
      {
        locus << a << "," << z.real() << "," << z.imag() << "\n";
      }
    }
    points << "kind,amplitude,frequency,re,im\n";
    for (const HarmonicBalance& h : predictions)
    {
      const std::complex<double> z = g(h.frequency);
      points << (h.stable ? "stable" : "unstable") << "," << h.amplitude << "," << h.frequency << "," << z.real() << ","
             << z.imag() << "\n";
    }
    if (!compliant && std::isfinite(sim.amplitude) && sim.amplitude > 0.5 * backlash)
    {
      const std::complex<double> z = -1.0 / backlashDescribingFunction(sim.amplitude, backlash);
      points << "simulated_locus," << sim.amplitude << "," << sim.frequency << "," << z.real() << "," << z.imag()
             << "\n";
    }
    if (std::isfinite(sim.frequency))
    {
      const std::complex<double> z = g(sim.frequency);
      points << "simulated_nyquist," << sim.amplitude << "," << sim.frequency << "," << z.real() << "," << z.imag()
             << "\n";
    }
    if (!nyquist.flush() || !locus.flush() || !points.flush())
    {
      throw std::runtime_error("--png: writing the chart data to '" + dir.path() + "' failed (disk full?)");
    }
  }
  const std::string tmp = dir.file("chart.png");
  runChartScript(script, dir.path(), tmp);
  copyFileInto(tmp, png);
  std::cerr << "backlash_df: wrote " << png.path() << "\n";
}

void report(const Options& o, const LimitCyclePrediction& a)
{
  const ServoParams& p = o.config.params;
  const std::vector<HarmonicBalance>& predictions = a.predictions;
  const SimulatedCycle& sim = a.simulated;
  const bool cycle = sim.verdict == Verdict::LimitCycle && std::isfinite(sim.amplitude);
  if (o.json)
  {
    std::ostringstream out;
    JsonWriter w(out);
    w.beginObject();
    w.field("zeta", a.zeta);
    w.field("natural_frequency", a.natural_frequency);
    w.field("backlash", p.backlash);
    w.beginArray("predictions");
    for (const auto* list : {&predictions, &a.numerical})
    {
      for (const HarmonicBalance& h : *list)
      {
        w.beginObject();
        w.field("amplitude", h.amplitude);
        w.field("frequency", h.frequency);
        w.field("stable", h.stable);
        w.field("method", std::string(list == &predictions ? "classical" : "numerical"));
        w.field("amplitude_error", a.amplitudeError(h));
        w.field("frequency_error", a.frequencyError(h));
        w.endObject();
      }
    }
    w.endArray();
    w.field("numerical_note", a.numerical_note);
    w.beginObject("simulated");
    w.field("verdict", std::string(toString(sim.verdict)));
    w.field("amplitude", sim.amplitude);
    w.field("peak", sim.peak);
    w.field("frequency", sim.frequency);
    w.field("centre", sim.centre);
    w.field("simulated_time", sim.simulated);
    w.endObject();
    w.endObject();
    std::cout << out.str() << "\n";
    return;
  }
  char buf[400];
  if (p.mesh_stiffness > 0.0)
  {
    std::snprintf(
        buf, sizeof buf,
        "loop: zeta = %.4g, w_n = %.4g rad/s, backlash %.4g rad (classical DF: the dead zone of the compliant "
        "mesh, c = %.6g N*m/rad, d = %.6g N*m*s/rad, between the two bodies)\n",
        a.zeta, a.natural_frequency, p.backlash, p.mesh_stiffness, p.mesh_damping);
  }
  else
  {
    const bool motor_loop = o.config.drive.sampled() && o.config.drive.feedback == "motor";
    std::snprintf(buf, sizeof buf, "loop: zeta = %.4g, w_n = %.4g rad/s, backlash %.4g rad (classical DF: %s)\n",
                  a.zeta, a.natural_frequency, p.backlash,
                  motor_loop ? "hysteresis passing the load's reaction to the motor's loop"
                             : "hysteresis in the feedback of the linear servo");
  }
  std::cout << buf;
  const DriveParams& d = o.config.drive;
  if (d.sampled())
  {
    const char* law = d.control_law == "pid" ? "PID" : d.control_law == "cascade" ? "cascade" : "P";
    std::snprintf(buf, sizeof buf,
                  "law: digital %s on the %s's angle at %.6g Hz%s, its fundamental in place of K (aliasing neglected; "
                  "frequencies below pi*f_s = %.6g rad/s)\n",
                  law, d.feedback.c_str(), d.controller_rate, d.controller_delay > 0.0 ? ", one sample late" : "",
                  3.14159265358979323846 * d.controller_rate);
    std::cout << buf;
  }
  if (predictions.empty())
  {
    std::cout << "predicted: no limit cycle (G(jw) never meets -1/N(A))\n";
  }
  for (const auto* list : {&predictions, &a.numerical})
  {
    for (const HarmonicBalance& h : *list)
    {
      std::snprintf(buf, sizeof buf, "predicted (%s): %s cycle, amplitude %.6g rad, frequency %.6g rad/s",
                    list == &predictions ? "classical" : "numerical DF of the real element",
                    h.stable ? "stable" : "unstable", h.amplitude, h.frequency);
      std::cout << buf;
      if (cycle && h.stable)
      {
        std::snprintf(buf, sizeof buf, " (%+.1f %% amplitude, %+.1f %% frequency against the exact cycle)",
                      100.0 * a.amplitudeError(h), 100.0 * a.frequencyError(h));
        std::cout << buf;
      }
      std::cout << "\n";
    }
  }
  if (!a.numerical_note.empty())
  {
    std::cout << a.numerical_note << "\n";
  }
  if (cycle)
  {
    std::snprintf(buf, sizeof buf,
                  "simulated: limit cycle, amplitude %.6g rad (fundamental of rho*theta_m about %.6g rad), peak "
                  "%.6g rad, frequency %.6g rad/s\n",
                  sim.amplitude, sim.centre, sim.peak, sim.frequency);
  }
  else
  {
    std::snprintf(buf, sizeof buf, "simulated: %s after %.6g s (no cycle to compare)\n", toString(sim.verdict),
                  sim.simulated);
  }
  std::cout << buf;
}

}  // namespace

int main(int argc, char** argv)
{
  Options o;
  std::unique_ptr<SafeOutput> png;
  std::string chart_script;
  try
  {
    o = parse(argc, argv);
    removeTemporariesOnSignals();  // (outputs' temporaries and the work directories go with the process)
    if (!o.png_path.empty())
    {
      // The output is checked and its temporary created before the run.
      png = std::make_unique<SafeOutput>("--png", o.png_path, std::vector<std::string>{o.config_path});
      chart_script = helperBesideExecutable("df_chart.py");
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_df: error: " << e.what() << "\n";
    return 2;
  }
  try
  {
    const LimitCyclePrediction analysis = predictLimitCycle(o.config);
    const ServoParams& p = o.config.params;
    if (png)
    {
      const DriveParams& d = o.config.drive;
      drawChart([&p, &d](double w) { return p.mesh_stiffness > 0.0 ? compliantLoop(p, d, w) : loopResponse(p, d, w); },
                analysis.natural_frequency, p, analysis.predictions, analysis.simulated, chart_script, *png);
    }
    report(o, analysis);
    flushStdout();
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_df: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
