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
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/simulation/step_response.h"
#include "backlash_servo/studies/run_report.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_design [--config FILE.yaml] --motor-inertia J_m --motor-friction f_m --load-inertia J_L
                       --load-friction f_L --restitution e [--backlash D] [--gain K|LO:HI] [--gear-ratio rho|LO:HI]
                       [any servo or drive flag] [--tune KEY] [--find max-gain|gear-ratio] [--json]
Computes zeta, w_n and the chart coordinates of a motor/gear/load choice and simulates whether it falls into a
limit cycle (and how big). --find max-gain scans the tuned gain (--tune, default the servo gain K [N·m/rad]; any
gain of the pid or cascade law, given as --KEY VALUE or --KEY LO:HI) over its range (default value/1000 ..
value*1000) at 41 log-spaced values, refines every change of verdict, and reports the intervals without a limit
cycle, the largest such gain and a design 1 % inside it confirmed by simulation; --find gear-ratio does the same
for the gear ratio (default rho/10 .. rho*10) and picks the ratio closest to the candidate. Every other setting
(digital drive, dry friction, load torque, ...) is simulated as given. SI units; defaults: K = 1, rho = 1, backlash 0.3 rad.
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
    // Undecided counts as a limit cycle, and so does a convergence whose joint did not come to rest when run on:
    // a design tool must not promise what it could not show.
    return run.status.verdict != Verdict::Converged || run.steady.basis == SteadyBasis::Unsettled;
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

/// Values scanned on a log grid by --find max-gain and --find gear-ratio before each change of verdict is refined.
constexpr int SCAN_POINTS = 41;
/// Relative width to which each change of verdict is refined by bisection on log x.
constexpr double REFINE_TO = 1e-7;

/// The intervals of x in [lo, hi] without a limit cycle, in increasing order: SCAN_POINTS values on a log grid, each
/// change of verdict between neighbours refined by bisection on log x to REFINE_TO. Whether a joint hunts need not
/// be monotone in a gain or a ratio, so every change is found, not one; a window of the other verdict narrower than
/// the grid's step can still be missed.
std::vector<std::pair<double, double>> freeIntervals(double lo, double hi,
                                                     const std::function<bool(double)>& limit_cycles)
{
  std::vector<double> xs(SCAN_POINTS);
  std::vector<bool> lc(SCAN_POINTS);
  for (int i = 0; i < SCAN_POINTS; ++i)
  {
    xs[i] = i == SCAN_POINTS - 1 ? hi : lo * std::pow(hi / lo, static_cast<double>(i) / (SCAN_POINTS - 1));
    lc[i] = limit_cycles(xs[i]);
  }
  std::vector<std::pair<double, double>> free;
  double start = xs[0];
  for (int i = 1; i < SCAN_POINTS; ++i)
  {
    if (lc[i] == lc[i - 1])
    {
      continue;
    }
    double a = xs[i - 1], b = xs[i];
    for (int it = 0; it < 60 && b / a > 1.0 + REFINE_TO; ++it)
    {
      const double mid = std::sqrt(a * b);
      (limit_cycles(mid) == lc[i - 1] ? a : b) = mid;
    }
    if (lc[i])
    {
      free.emplace_back(start, a);  // the last value still free
    }
    else
    {
      start = b;  // the first value free again
    }
  }
  if (!lc[SCAN_POINTS - 1])
  {
    free.emplace_back(start, hi);
  }
  return free;
}

/// A value to design with inside a free interval: 1 % inside its top end when the interval is wide enough, else its
/// geometric middle.
double insideTop(const std::pair<double, double>& f)
{
  return f.second / f.first > 1.0201 ? std::max(f.first, f.second / 1.01) : std::sqrt(f.first * f.second);
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
  if (e.run.status.verdict == Verdict::LimitCycle)
  {
    std::snprintf(buf, sizeof buf,
                  ", error %.6g rad (%.3g × backlash), period %.6g s (%d maxima per period); load %.6g rad peak to "
                  "peak about %.9g rad",
                  e.run.status.error, e.run.status.error / p.backlash, e.run.status.period, e.run.status.multiplicity,
                  e.run.cycle.peak_to_peak, e.run.cycle.centre);
    out << buf << resolutionText(e.run.resolution);
  }
  else if (e.run.status.verdict == Verdict::Irregular)
  {
    std::snprintf(buf, sizeof buf,
                  ", largest error %.6g rad (%.3g × backlash), mean time between maxima %.6g s; load %.6g rad peak "
                  "to peak about %.9g rad",
                  e.run.status.error, e.run.status.error / p.backlash, e.run.status.period, e.run.cycle.peak_to_peak,
                  e.run.cycle.centre);
    out << buf << resolutionText(e.run.resolution);
  }
  else if (e.run.steady.basis == SteadyBasis::Unsettled)
  {
    out << ", but not at rest when run on (" << e.run.steady.note << "): counted as not free of cycles";
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
  j.field("peak_to_peak_counts", e.run.resolution.counts).field("peak_to_peak_arcmin", e.run.resolution.arcmin);
  j.field("below_encoder_resolution", lc && e.run.resolution.below_count);
  j.endObject();
}
}  // namespace

namespace
{
/// "[a, b] [c, d]" (%.6g each), or " none".
std::string intervalsText(const std::vector<std::pair<double, double>>& free)
{
  std::string out;
  char buf[80];
  for (const auto& f : free)
  {
    std::snprintf(buf, sizeof buf, " [%.6g, %.6g]", f.first, f.second);
    out += buf;
  }
  return out.empty() ? " none" : out;
}

void intervalsJson(JsonWriter& j, const char* key, const std::vector<std::pair<double, double>>& free)
{
  j.beginArray(key);
  for (const auto& f : free)
  {
    j.beginArray().field(nullptr, f.first).field(nullptr, f.second).endArray();
  }
  j.endArray();
}

/// The transient of a chosen design, as text and JSON fields.
void reportTransient(const Evaluation& chosen, std::ostream& text, JsonWriter& j)
{
  const Transient t = transient(chosen.config);
  char buf[200];
  std::snprintf(buf, sizeof buf, "  overshoot %.4g rad, settling time %.4g s into ±%.4g rad\n", t.overshoot,
                t.settling_time, t.band);
  text << buf;
  j.field("overshoot", t.overshoot).field("settling_time", t.settling_time).field("settling_band", t.band);
}

/// --find max-gain: the intervals of the tuned gain without a limit cycle, the largest such gain, and a design 1 %
/// inside it confirmed by simulation (with the value just above the largest, unless the range bounds it).
void findMaxGain(const Design& d, std::ostream& text, JsonWriter& j)
{
  const char* unit = param(d.tune).unit;
  // The smallest cycle met on the way: what the joint does where no value is free of cycles.
  Evaluation smallest;
  auto limit_cycles = [&](double k) {
    Evaluation e = evaluate(d, k, d.rho);
    const double p2p = e.run.cycle.peak_to_peak;
    if (e.limit_cycle() && std::isfinite(p2p) && !(smallest.run.cycle.peak_to_peak <= p2p))
    {
      smallest = e;
    }
    return e.limit_cycle();
  };
  const std::vector<std::pair<double, double>> free = freeIntervals(d.gain_lo, d.gain_hi, limit_cycles);
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%s without a limit cycle in [%g, %g] %s (%d log-spaced values, every change of "
                "verdict refined to %g):%s\n",
                d.tune.c_str(), d.gain_lo, d.gain_hi, unit, SCAN_POINTS, REFINE_TO, intervalsText(free).c_str());
  text << buf;
  j.beginObject("max_gain");
  if (free.empty())
  {
    j.null("gain").field("range_low", d.gain_lo).field("range_high", d.gain_hi);
    intervalsJson(j, "intervals", free);
    std::snprintf(buf, sizeof buf,
                  "max %s: none — every value scanned in [%g, %g] limit-cycles, hunts irregularly, "
                  "diverges or is undecided: no %s in this range avoids a limit cycle (change another setting, or the "
                  "range)\n",
                  d.tune.c_str(), d.gain_lo, d.gain_hi, d.tune.c_str());
    text << buf;
    if (std::isfinite(smallest.run.cycle.peak_to_peak))
    {
      describe(text, "  the smallest cycle met", smallest, d.tune);
      evaluationJson(j, "smallest_cycle", smallest, d.tune);
    }
    j.endObject();
    return;
  }
  const std::pair<double, double>& top = free.back();
  const bool bounded = top.second == d.gain_hi;
  std::snprintf(buf, sizeof buf, "max %s without a limit cycle: %.6g %s%s\n", d.tune.c_str(), top.second, unit,
                bounded ? " (bounded by the range: free of cycles up to its end)" : "");
  text << buf;
  j.field("gain", top.second).field("tuned", d.tune).field("bounded_by_range", bounded);
  j.field("range_low", d.gain_lo).field("range_high", d.gain_hi);
  intervalsJson(j, "intervals", free);
  // Below the largest value the gain is not free everywhere: what the joint does in each gap (its middle simulated).
  double from = d.gain_lo;
  j.beginArray("gaps");
  for (const auto& f : free)
  {
    if (f.first > from)
    {
      const Evaluation gap = evaluate(d, std::sqrt(from * f.first), d.rho);
      const char* verdict = gap.diverged ? "diverged" : toString(gap.run.status.verdict);
      std::snprintf(buf, sizeof buf, "  not free in (%.6g, %.6g): %s at %.6g%s\n", from, f.first, verdict, gap.tuned,
                    gap.run.status.verdict == Verdict::Undecided ? " (not settled within the run)" : "");
      text << buf;
      j.beginObject().field("from", from).field("to", f.first).field("verdict", std::string(verdict)).endObject();
    }
    from = f.second;
  }
  j.endArray();
  if (!bounded)
  {
    const Evaluation above = evaluate(d, top.second * 1.001, d.rho);
    describe(text, "  check just above (1.001 of it)", above, d.tune);
    evaluationJson(j, "check_above", above, d.tune);
  }
  // The design is confirmed by its own simulation: 1 % inside the interval, else its middle.
  Evaluation chosen = evaluate(d, insideTop(top), d.rho);
  if (chosen.limit_cycle())
  {
    chosen = evaluate(d, std::sqrt(top.first * top.second), d.rho);
  }
  if (chosen.limit_cycle())
  {
    text << "chosen design: none confirmed — the interval is too narrow for its inside to be free of cycles too\n";
    j.null("chosen");
    j.endObject();
    return;
  }
  std::snprintf(buf, sizeof buf, "chosen design (%.4g of it)", chosen.tuned / top.second);
  describe(text, buf, chosen, d.tune);
  evaluationJson(j, "chosen", chosen, d.tune);
  reportTransient(chosen, text, j);
  j.endObject();
}

/// --find gear-ratio: the intervals of ρ without a limit cycle and the ratio closest to the candidate's, 1 % inside
/// its interval.
void findGearRatio(const Design& d, std::ostream& text, JsonWriter& j)
{
  const std::vector<std::pair<double, double>> free =
      freeIntervals(d.rho_lo, d.rho_hi, [&](double rho) { return evaluate(d, d.gain, rho).limit_cycle(); });
  intervalsJson(j, "gear_ratios_without_limit_cycle", free);
  text << "gear ratios without a limit cycle in [" << d.rho_lo << ", " << d.rho_hi << "]:" << intervalsText(free)
       << "\n";
  double best = 0.0;
  for (const auto& f : free)
  {
    // Stay 1 % inside the interval (when it is wide enough) so the choice is not a boundary case.
    const double margin = f.second / f.first > 1.0201 ? 1.01 : 1.0;
    const double pick = std::min(std::max(d.rho, f.first * margin), f.second / margin);
    if (best == 0.0 || std::fabs(std::log(pick / d.rho)) < std::fabs(std::log(best / d.rho)))
    {
      best = pick;
    }
  }
  if (best > 0.0)
  {
    const Evaluation chosen = evaluate(d, d.gain, best);
    describe(text, "closest such ratio", chosen, d.tune);
    evaluationJson(j, "chosen", chosen, d.tune);
    reportTransient(chosen, text, j);
  }
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
    findMaxGain(d, text, j);
  }
  else if (d.find == "gear-ratio")
  {
    findGearRatio(d, text, j);
  }
  j.endObject();
}

int main(int argc, char** argv)
{
  Design d;
  try
  {
    d = parse(argc, argv);
    for (const std::string& w : inputWarnings(configOf(d, d.gain, d.rho)))
    {
      std::cerr << "backlash_design: warning: " << w << "\n";
    }
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
