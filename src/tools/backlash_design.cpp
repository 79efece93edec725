// backlash_design: the thesis' Section 6 design procedure, by simulation instead of chart reading.
// See docs/design.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/param_table.h"
#include "backlash_servo/step_response.h"
#include "json_writer.h"
#include "safe_output.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_design [--config FILE.yaml] --motor-inertia J_m --motor-friction f_m --load-inertia J_L
                       --load-friction f_L --restitution e [--backlash D] [--gain K|LO:HI] [--gear-ratio rho|LO:HI]
                       [any servo or drive flag] [--tune KEY] [--find max-gain|gear-ratio] [--json]
Computes zeta, w_n and the chart coordinates of a motor/gear/load choice and simulates whether it falls into a
limit cycle (and how big). --find max-gain bisects the largest value of the tuned gain (--tune, default the servo
gain K [N·m/rad]; any gain of the pid or cascade law, given as --KEY VALUE or --KEY LO:HI) without a limit cycle in
its range (default value/1000 .. value*1000); --find gear-ratio scans the gear-ratio range (default rho/10 ..
rho*10) for ratios without a limit cycle. Every other setting (digital drive, dry friction, load torque, ...) is
simulated as given. SI units; defaults: K = 1, rho = 1, backlash 0.3 rad.
)";

/// The gains --find max-gain can search (--tune KEY): the P gain and every gain of the sampled laws.
const std::vector<std::string>& tunableGains()
{
  static const std::vector<std::string> keys = {"gain",
                                                "integral_gain",
                                                "derivative_gain",
                                                "position_loop_gain",
                                                "velocity_loop_gain",
                                                "velocity_loop_integral_gain"};
  return keys;
}

struct Design
{
  KeyValues base;             // every setting given (motor, load, drive, dry friction …) except the searched ones
  std::string tune = "gain";  // the gain --find max-gain searches
  double gain = 1.0, gain_lo = 0.0, gain_hi = 0.0;  // value and range of the tuned gain
  double rho = 1.0, rho_lo = 0.0, rho_hi = 0.0;
  std::string find;
  bool json = false;
};

struct Evaluation
{
  RunConfig config;
  double tuned = 0.0;  // value of the tuned gain
  RunSummary run;
  bool diverged = false;  // the loop is unstable: the motion overflowed (counts as not free of limit cycles)
  bool limit_cycle() const
  {
    // Undecided counts as a limit cycle: a design tool must not promise what it could not show.
    return run.status.verdict != Verdict::Converged;
  }
};

RunConfig configOf(const Design& d, double tuned, double rho)
{
  KeyValues kv = d.base;
  kv.setNumber(d.tune, tuned);
  kv.setNumber("gear_ratio", rho);
  return runConfigFrom(kv);
}

Evaluation evaluate(const Design& d, double tuned, double rho)
{
  Evaluation e;
  e.config = configOf(d, tuned, rho);
  e.tuned = tuned;
  RunConfig c = e.config;
  c.track_energy = false;  // verdicts only
  try
  {
    e.run = runResponse(c);
    e.diverged = e.run.status.verdict == Verdict::Diverged;
  }
  catch (const std::domain_error&)
  {
    e.diverged = true;  // an unstable digital loop runs off to infinity
  }
  return e;
}

struct Transient
{
  double overshoot = 0.0;      // first maximum above the command minus the command [rad]
  double settling_time = 0.0;  // last time outside the settling band (settlingBand) [s]; inf if never settled
  double band = 0.0;           // that band [rad]
};

Transient transient(const RunConfig& config)
{
  Transient t;
  // Sampled finely (2000 samples per natural period): the figures of the tracking replay at a finer rate.
  const double dt = 2.0 * 3.14159265358979 / config.params.naturalFrequency() / 2000.0;
  TrackingMetrics tracking = trackingOf(config, dt, INFINITY);
  const RunSummary r = runResponse(config, nullptr, dt, [&](const Simulator& sim) {
    tracking.add(sim.state().time, config.command, sim.state().load_position, sim.motorTorque());
  });
  const TrackingFigures f = tracking.figures(config.initial.time + r.simulated, dt);
  t.overshoot = r.maxima.empty() ? 0.0 : r.maxima.front().position - config.command;
  t.settling_time = r.status.verdict == Verdict::Converged && !std::isnan(f.settling_time) ? f.settling_time : INFINITY;
  t.band = f.band;
  return t;
}

void parseRange(const KeyValues& kv, const std::string& key, double* value, double* lo, double* hi)
{
  const std::string text = kv.text(key, "");
  const auto colon = text.find(':');
  if (colon == std::string::npos)
  {
    *value = kv.has(key) ? kv.number(key) : *value;
    return;
  }
  KeyValues part;
  part.set(key, text.substr(0, colon));
  *lo = part.number(key);
  part.set(key, text.substr(colon + 1));
  *hi = part.number(key);
  // Both ends must be values the key accepts (a search never leaves the key's valid range).
  param(key).check(*lo);
  param(key).check(*hi);
  if (!(*lo > 0.0 && *hi > *lo))
  {
    throw ConfigError(flagName(key) + ": a range LO:HI needs 0 < LO < HI");
  }
  *value = std::sqrt(*lo * *hi);
}

Design parse(int argc, char** argv)
{
  std::vector<std::string> keys = keysOfSections({ParamSection::Servo, ParamSection::Drive});
  keys.push_back("command");
  FlagParser parser("backlash_design", HEADER, keys,
                    {{"config", "FILE.yaml",
                      "the joint's keys in snake_case (the YAML backlash_sim and the node load; flags override it; "
                      "a YAML value LO:HI is a range as on the command line)"},
                     {"find", "max-gain|gear-ratio", "what to search (see above)"},
                     {"tune", "KEY",
                      "the gain --find max-gain searches: gain (default), integral_gain, "
                      "derivative_gain, position_loop_gain, velocity_loop_gain, "
                      "velocity_loop_integral_gain"},
                     {"json", "", "one JSON object on stdout"}});
  parser.parse(argc, argv);
  const KeyValues& kv = parser.keys();
  Design d;
  d.json = parser.given("json");
  d.find = parser.option("find");
  if (parser.given("find") && d.find != "max-gain" && d.find != "gear-ratio")
  {
    throw ConfigError("--find must be max-gain or gear-ratio");
  }
  d.tune = parser.option("tune", "gain");
  std::replace(d.tune.begin(), d.tune.end(), '-', '_');
  if (std::find(tunableGains().begin(), tunableGains().end(), d.tune) == tunableGains().end())
  {
    throw ConfigError(
        "--tune must be one of gain, integral_gain, derivative_gain, position_loop_gain, "
        "velocity_loop_gain, velocity_loop_integral_gain (got '" +
        parser.option("tune") + "')");
  }
  for (const char* required : {"motor_inertia", "motor_friction", "load_inertia", "load_friction", "restitution"})
  {
    if (!kv.has(required))
    {
      throw ConfigError(flagName(required) + " is required");
    }
  }
  for (const auto& item : kv.keys())
  {
    if (item.first != d.tune && item.first != "gear_ratio")
    {
      d.base.set(item.first, kv.text(item.first, ""));
    }
  }
  d.base.nameKeysAsFlags(true);
  d.gain = kv.has(d.tune) || d.tune == "gain" ? 1.0 : 0.0;
  parseRange(kv, d.tune, &d.gain, &d.gain_lo, &d.gain_hi);
  parseRange(kv, "gear_ratio", &d.rho, &d.rho_lo, &d.rho_hi);
  if (d.gain_lo == 0.0)
  {
    if (!(d.gain > 0.0))
    {
      throw ConfigError(flagName(d.tune) + ": give a positive value or a range LO:HI to search");
    }
    d.gain_lo = d.gain / 1000.0;
    d.gain_hi = d.gain * 1000.0;
    if (d.tune == "gain")
    {
      // The default search range stays inside the validated envelope (ω_n ≤ NATURAL_FREQUENCY_MAX, K in the table).
      const ServoParams p = configOf(d, d.gain, d.rho).params;
      const double j = p.totalInertia();
      d.gain_lo = std::max(d.gain_lo, NATURAL_FREQUENCY_MIN * NATURAL_FREQUENCY_MIN * j / d.rho);
      d.gain_hi = std::min({d.gain_hi, 1e12, NATURAL_FREQUENCY_MAX * NATURAL_FREQUENCY_MAX * j / d.rho});
    }
  }
  if (d.rho_lo == 0.0)
  {
    d.rho_lo = d.rho / 10.0;
    d.rho_hi = d.rho * 10.0;
  }
  // Default ranges are clipped to what each key accepts.
  auto clip = [](const std::string& key, double* lo, double* hi) {
    const ParamRange& r = param(key).range;
    *lo = std::max(*lo, r.lower);
    *hi = std::min(*hi, r.upper);
    while (!r.contains(*lo) && *lo < *hi)
    {
      *lo = std::nextafter(*lo, *hi);
    }
    while (!r.contains(*hi) && *hi > *lo)
    {
      *hi = std::nextafter(*hi, *lo);
    }
  };
  clip(d.tune, &d.gain_lo, &d.gain_hi);
  clip("gear_ratio", &d.rho_lo, &d.rho_hi);
  configOf(d, d.gain, d.rho);  // the candidate must be valid (one clear line otherwise)
  return d;
}

/// Largest x in [lo, hi] with no limit cycle, by bisection on log x (verdict assumed monotone: LC above).
/// Returns {boundary, status}: status 0 found, -1 every value limit-cycles, +1 none does.
std::pair<double, int> bisect(double lo, double hi, const std::function<bool(double)>& limit_cycles)
{
  if (limit_cycles(lo))
  {
    return {lo, -1};
  }
  if (!limit_cycles(hi))
  {
    return {hi, 1};
  }
  for (int i = 0; i < 60 && hi / lo > 1.0 + 1e-7; ++i)
  {
    const double mid = std::sqrt(lo * hi);
    (limit_cycles(mid) ? hi : lo) = mid;
  }
  return {lo, 0};
}

void describe(std::ostream& out, const char* title, const Evaluation& e, const std::string& tune)
{
  const ServoParams& p = e.config.params;
  char buf[600];
  std::string tuned;
  if (tune != "gain")
  {
    std::snprintf(buf, sizeof buf, ", %s = %.6g %s", tune.c_str(), e.tuned, param(tune).unit);
    tuned = buf;
  }
  // ζ and ω_n are the continuous P law's; for any other loop they describe the gain K alone, and are labelled so.
  const DriveParams& d = e.config.drive;
  const std::string chart = d.thesisLaw() ? "" : "chart of the continuous P law with this K (not this loop): ";
  std::snprintf(buf, sizeof buf,
                "%s: K = %.6g N·m/rad%s, rho = %.6g\n  %szeta = %.4g, w_n = %.4g rad/s, rho²J_L/J_m = %.4g, "
                "rho²f_L/F_T = %.4g\n  simulated: %s",
                title, p.gain, tuned.c_str(), p.gear_ratio, chart.c_str(), p.dampingRatio(), p.naturalFrequency(),
                p.inertiaRatio(), p.frictionRatio(),
                e.diverged ? "diverged (unstable loop)" : toString(e.run.status.verdict));
  out << buf;
  if (e.run.status.verdict == Verdict::LimitCycle || e.run.status.verdict == Verdict::Irregular)
  {
    std::snprintf(buf, sizeof buf,
                  ", error %.6g rad (%.3g × backlash), period %.6g s (%d maxima per period); load %.6g rad peak to "
                  "peak about %.9g rad",
                  e.run.status.error, e.run.status.error / p.backlash, e.run.status.period, e.run.status.multiplicity,
                  e.run.cycle.peak_to_peak, e.run.cycle.centre);
    out << buf;
  }
  out << "\n";
}

void evaluationJson(JsonWriter& j, const char* key, const Evaluation& e, const std::string& tune)
{
  const ServoParams& p = e.config.params;
  const bool lc = e.run.status.verdict == Verdict::LimitCycle || e.run.status.verdict == Verdict::Irregular;
  j.beginObject(key).field("gain", p.gain);
  if (tune != "gain")
  {
    j.field(tune.c_str(), e.tuned);
  }
  j.field("gear_ratio", p.gear_ratio)
      .field("zeta", p.dampingRatio())
      .field("natural_frequency", p.naturalFrequency())
      .field("inertia_ratio", p.inertiaRatio())
      .field("friction_ratio", p.frictionRatio())
      .field("verdict", std::string(e.diverged ? "diverged" : toString(e.run.status.verdict)))
      .field("limit_cycle", lc)
      .field("limit_cycle_error", lc ? e.run.status.error : 0.0)
      .field("period", lc ? e.run.status.period : 0.0)
      .field("maxima_per_period", static_cast<long long>(lc ? e.run.status.multiplicity : 0));
  if (lc)
  {
    j.field("peak_to_peak", e.run.cycle.peak_to_peak).field("cycle_centre", e.run.cycle.centre);
  }
  else
  {
    j.null("peak_to_peak").null("cycle_centre");
  }
  j.endObject();
}
}  // namespace

/// Evaluates the candidate and runs the search asked for, writing the text and JSON reports.
void design(const Design& d, std::ostringstream& text, std::ostringstream& json_text)
{
  JsonWriter j(json_text);
  j.beginObject();
  const Evaluation candidate = evaluate(d, d.gain, d.rho);
  describe(text, "candidate", candidate, d.tune);
  evaluationJson(j, "candidate", candidate, d.tune);
  if (d.find == "max-gain")
  {
    // A candidate without a limit cycle is a known lower bracket (slow integral gains at the range's low end may not
    // settle within the run and would count as limit cycles).
    const double lo = !candidate.limit_cycle() && d.gain > d.gain_lo && d.gain < d.gain_hi ? d.gain : d.gain_lo;
    const auto found = bisect(lo, d.gain_hi, [&](double k) { return evaluate(d, k, d.rho).limit_cycle(); });
    char buf[300];
    j.beginObject("max_gain").field("range_low", d.gain_lo).field("range_high", d.gain_hi);
    if (found.second == -1)
    {
      std::snprintf(buf, sizeof buf, "max %s: every value in [%g, %g] limit-cycles\n", d.tune.c_str(), d.gain_lo,
                    d.gain_hi);
      text << buf;
      j.null("gain");
    }
    else if (found.second == 1)
    {
      std::snprintf(buf, sizeof buf, "max %s: no limit cycle anywhere up to %g (range end)\n", d.tune.c_str(),
                    d.gain_hi);
      text << buf;
      j.field("gain", d.gain_hi).field("bounded_by_range", true);
    }
    else
    {
      const double k = found.first;
      const Evaluation below = evaluate(d, k * 0.999, d.rho);
      const Evaluation above = evaluate(d, k * 1.001, d.rho);
      const Transient t = transient(below.config);
      std::snprintf(buf, sizeof buf, "max %s without a limit cycle: %.6g %s (bisection to 1e-7)\n", d.tune.c_str(), k,
                    param(d.tune).unit);
      text << buf;
      describe(text, "  check just below (0.999 of it)", below, d.tune);
      describe(text, "  check just above (1.001 of it)", above, d.tune);
      std::snprintf(buf, sizeof buf,
                    "chosen design (0.999 of it): overshoot %.4g rad (%.3g %%), settling time %.4g s into ±%.4g rad\n",
                    t.overshoot, 100.0 * t.overshoot, t.settling_time, t.band);
      text << buf;
      j.field("gain", k).field("tuned", d.tune);
      evaluationJson(j, "check_below", below, d.tune);
      evaluationJson(j, "check_above", above, d.tune);
      j.field("overshoot", t.overshoot).field("settling_time", t.settling_time).field("settling_band", t.band);
    }
    j.endObject();
  }
  else if (d.find == "gear-ratio")
  {
    // Scan on a log grid, then refine each change of verdict by bisection.
    const int n = 41;
    std::vector<double> rhos(n);
    std::vector<bool> lc(n);
    for (int i = 0; i < n; ++i)
    {
      rhos[i] = d.rho_lo * std::pow(d.rho_hi / d.rho_lo, static_cast<double>(i) / (n - 1));
      lc[i] = evaluate(d, d.gain, rhos[i]).limit_cycle();
    }
    std::vector<std::pair<double, double>> free;
    double start = lc[0] ? -1.0 : rhos[0];
    for (int i = 1; i < n; ++i)
    {
      if (lc[i] == lc[i - 1])
      {
        continue;
      }
      double a = rhos[i - 1], b = rhos[i];
      for (int it = 0; it < 40 && b / a > 1.0 + 1e-7; ++it)
      {
        const double mid = std::sqrt(a * b);
        (evaluate(d, d.gain, mid).limit_cycle() == lc[i - 1] ? a : b) = mid;
      }
      if (lc[i])
      {
        free.emplace_back(start, a);
      }
      else
      {
        start = b;
      }
    }
    if (!lc[n - 1])
    {
      free.emplace_back(start, rhos[n - 1]);
    }
    j.beginArray("gear_ratios_without_limit_cycle");
    text << "gear ratios without a limit cycle in [" << d.rho_lo << ", " << d.rho_hi << "]:";
    double best = 0.0;
    for (const auto& f : free)
    {
      text << " [" << f.first << ", " << f.second << "]";
      j.beginArray().field(nullptr, f.first).field(nullptr, f.second).endArray();
      // Stay 1 % inside the interval (when it is wide enough) so the choice is not a boundary case.
      const double margin = f.second / f.first > 1.0201 ? 1.01 : 1.0;
      const double pick = std::min(std::max(d.rho, f.first * margin), f.second / margin);
      if (best == 0.0 || std::fabs(std::log(pick / d.rho)) < std::fabs(std::log(best / d.rho)))
      {
        best = pick;
      }
    }
    j.endArray();
    text << (free.empty() ? " none\n" : "\n");
    if (best > 0.0)
    {
      const Evaluation chosen = evaluate(d, d.gain, best);
      describe(text, "closest such ratio", chosen, d.tune);
      const Transient t = transient(chosen.config);
      char buf[200];
      std::snprintf(buf, sizeof buf, "  overshoot %.4g rad, settling time %.4g s into ±%.4g rad\n", t.overshoot,
                    t.settling_time, t.band);
      text << buf;
      evaluationJson(j, "chosen", chosen, d.tune);
      j.field("overshoot", t.overshoot).field("settling_time", t.settling_time).field("settling_band", t.band);
    }
  }
  j.endObject();
}

int main(int argc, char** argv)
{
  Design d;
  try
  {
    d = parse(argc, argv);
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_design: error: " << e.what() << "\n";
    return 2;
  }
  std::ostringstream text;
  std::ostringstream json_text;
  try
  {
    design(d, text, json_text);
  }
  catch (const std::exception& e)  // a candidate the search reached that the model refuses: one line, never abort
  {
    std::cerr << "backlash_design: error: " << e.what() << "\n";
    return 1;
  }
  std::cout << (d.json ? json_text.str() + "\n" : text.str());
  try
  {
    flushStdout();
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_design: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
