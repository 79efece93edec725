// backlash_compare: the compensation workbench — one joint, one command profile, N strategies side by side.
// See docs/workbench.md. The experiment file: include/backlash_servo/config/compare_config.h.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "backlash_servo/config/compare_config.h"
#include "backlash_servo/config/key_values.h"
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/part_files.h"
#include "backlash_servo/files/run_program.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/studies/compare_metrics.h"
#include "progress.h"

using namespace backlash_servo;

namespace
{
const char* USAGE = R"(usage: backlash_compare --config FILE.yaml [--vary KEY=START:STOP:COUNT [--absolute]] [--json]
                        [--csv FILE] [--png FILE] [--jobs N]
Runs every strategy of the experiment file (one joint, one command profile, a list of control laws and
compensators) and prints a table of metrics (SI units): verdict, limit-cycle error [rad], period [s] of the whole
pattern and the load's peak-to-peak amplitude [rad] in the cycle (the JSON and CSV also its centre), steady error
[rad], settling time [s] into the settling band (`settling_band`, default the joint's resolution), RMS tracking error
over the run and after the transient, max tracking error [rad], overshoot [rad], impacts per second, impact energy
per second [W], peak and RMS motor torque [N·m]. A strategy the duration leaves undecided is run on until its
verdict settles (capped by max_duration): a note says what it becomes and the duration that would decide it.
  --json       print {"strategies": [{...}, ...]} instead of the table (null where a metric does not apply)
  --csv FILE   also write the table as CSV
  --png FILE   also draw trajectories, tracking errors and one bar chart per metric (matplotlib)
  --jobs N     strategies run in parallel (default: all cores)
  --vary KEY=START:STOP:COUNT
               robustness of each strategy: re-run it with KEY (any numeric parameter, e.g. the plant's backlash)
               at COUNT evenly spaced factors START…STOP of its value in the file (the strategies' own settings,
               e.g. compensation_backlash, stay): one row per strategy and value; the PNG charts each metric
               against the value
  --absolute   with --vary: START…STOP are the values themselves [SI], not factors
)";

/// --vary KEY=START:STOP:COUNT.
struct Vary
{
  std::string key;
  std::vector<double> steps;  ///< factors (or values with --absolute)
  bool absolute = false;
};

Vary parseVary(const std::string& text)
{
  Vary v;
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
  {
    throw ConfigError("--vary: expected KEY=START:STOP:COUNT (got '" + text + "')");
  }
  v.key = text.substr(0, eq);
  const ParamSpec* spec = findParam(v.key);
  if (spec == nullptr || spec->type != ParamType::Real)
  {
    throw ConfigError("--vary: '" + v.key + "' is not a numeric parameter (see backlash_params)");
  }
  KeyValues kv;
  std::stringstream parts(text.substr(eq + 1));
  std::string a, b, n, extra;
  if (!std::getline(parts, a, ':') || !std::getline(parts, b, ':') || !std::getline(parts, n, ':') ||
      std::getline(parts, extra, ':'))
  {
    throw ConfigError("--vary: expected KEY=START:STOP:COUNT (got '" + text + "')");
  }
  kv.set("start", a);
  kv.set("stop", b);
  kv.set("count", n);
  const double start = kv.number("start"), stop = kv.number("stop"), count = kv.number("count");
  if (!(count >= 2.0 && count <= 1000.0 && count == std::floor(count)))
  {
    throw ConfigError("--vary: COUNT must be a whole number in [2, 1000] (got '" + n + "')");
  }
  for (int i = 0; i < static_cast<int>(count); ++i)
  {
    v.steps.push_back(start + (stop - start) * i / (count - 1.0));
  }
  return v;
}

std::string cell(double v)
{
  if (std::isnan(v))
  {
    return "-";
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string csvText(const std::string& s);

/// The metrics table as CSV (--csv, and the chart script's input): name, [the varied key's value,] verdict, then
/// metricNames().
void writeMetricsCsv(std::ostream& out, const std::vector<CompareMetrics>& metrics, const std::string& vary_key,
                     const std::vector<double>& values)
{
  out << "name," << (vary_key.empty() ? "" : vary_key + ",") << "verdict";
  for (const std::string& k : metricNames())
  {
    out << "," << k;
  }
  out << "\n";
  for (std::size_t i = 0; i < metrics.size(); ++i)
  {
    const CompareMetrics& m = metrics[i];
    out << csvText(m.name) << "," << (vary_key.empty() ? "" : csvNumber(values[i]) + ",") << m.verdict;
    for (double v : metricValues(m))
    {
      out << "," << csvNumber(v);
    }
    out << "\n";
  }
}

std::string csvText(const std::string& s)
{
  if (s.find_first_of(",\"\n") == std::string::npos)
  {
    return s;
  }
  std::string out = "\"";
  for (char c : s)
  {
    out += c == '"' ? std::string("\"\"") : std::string(1, c);
  }
  return out + "\"";
}
}  // namespace

namespace
{
/// Copies a finished file into a SafeOutput (checked writes, then commit).
void copyInto(const std::string& from, SafeOutput& to)
{
  copyFileInto(from, to);
  std::cerr << "backlash_compare: wrote " << to.path() << "\n";
}

/// Trajectories and the table to a private temporary directory, drawn there by the chart script (run without a
/// shell), then moved into place through the safe-write path; exactly the files made are removed afterwards.
void drawCharts(const std::string& script, TemporaryDirectory& dir,
                const std::vector<std::vector<CompareSample>>& trajectories, const std::vector<CompareMetrics>& metrics,
                const std::string& vary_key, const std::vector<double>& run_values, SafeOutput& png, SafeOutput& svg)
{
  {
    // (--vary: no trajectories; the script then charts the metrics against the varied value)
    std::ofstream t(dir.file(vary_key.empty() ? "trajectories.csv" : "no_trajectories.csv"));
    t << "strategy,time,reference,load_position,motor_position,motor_torque\n";
    t.precision(10);
    for (std::size_t i = 0; i < trajectories.size(); ++i)
    {
      for (const CompareSample& s : trajectories[i])
      {
        t << i << "," << s.time << "," << s.reference << "," << s.load_position << "," << s.motor_position << ","
          << s.motor_torque << "\n";
      }
    }
    std::ofstream m(dir.file("metrics.csv"));
    writeMetricsCsv(m, metrics, vary_key, run_values);
    if (!t.flush() || !m.flush())
    {
      throw std::runtime_error("--png: writing the chart data to '" + dir.path() + "' failed (disk full?)");
    }
  }
  const std::string png_tmp = dir.file("chart.png");
  const std::string svg_tmp = dir.file("chart.svg");
  runChartScript(script, dir.path(), png_tmp);
  copyInto(png_tmp, png);
  copyInto(svg_tmp, svg);
}
}  // namespace

/// The command line: the options, or an exit code (0 after --help, 2 on a bad option) in `exit_code`.
struct Options
{
  std::string config_path, csv_path, png_path, vary_text;
  bool json = false, absolute = false;
  int jobs = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
};

bool parseOptions(int argc, char** argv, Options* o, int* exit_code)
{
  for (int i = 1; i < argc; ++i)
  {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc)
      {
        std::cerr << "backlash_compare: error: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--config")
      o->config_path = value();
    else if (a == "--csv")
      o->csv_path = value();
    else if (a == "--png")
      o->png_path = value();
    else if (a == "--json")
      o->json = true;
    else if (a == "--vary")
      o->vary_text = value();
    else if (a == "--absolute")
      o->absolute = true;
    else if (a == "--jobs")
    {
      const std::string v = value();
      char* end = nullptr;
      const long n = std::strtol(v.c_str(), &end, 10);
      if (*end != '\0' || n < 1 || n > 4096)
      {
        std::cerr << "backlash_compare: error: --jobs must be a whole number in [1, 4096] (got '" << v << "')\n";
        *exit_code = 2;
        return false;
      }
      o->jobs = static_cast<int>(n);
    }
    else if (a == "--help" || a == "-h")
    {
      std::cout << USAGE;
      *exit_code = 0;
      return false;
    }
    else
    {
      std::cerr << "backlash_compare: error: unknown option '" << a << "' (see --help)\n";
      *exit_code = 2;
      return false;
    }
  }
  return true;
}

/// What is run: the strategies, or with --vary each strategy at each varied value (`values` [SI]).
std::vector<CompareStrategy> planRuns(const CompareConfig& config, const Vary& vary, bool varied,
                                      std::vector<double>* run_values)
{
  std::vector<CompareStrategy> runs = config.strategies;
  if (!varied)
  {
    return runs;
  }
  runs.clear();
  for (const CompareStrategy& s : config.strategies)
  {
    const double base = vary.absolute ? 1.0 : valueOf(s, vary.key);
    if (!vary.absolute && base == 0.0)
    {
      throw ConfigError("--vary: '" + vary.key + "' is 0 in strategy '" + s.name +
                        "': factors of 0 are all 0; give values with --absolute");
    }
    for (double step : vary.steps)
    {
      runs.push_back(withValue(s, vary.key, step * base, config));
      run_values->push_back(step * base);
    }
  }
  return runs;
}

/// The run-on of an undecided run (CompareMetrics::run_on_verdict) as the JSON field "run_on", null for any other.
void writeRunOn(JsonWriter& j, const CompareMetrics& m)
{
  if (m.run_on_verdict.empty())
  {
    j.null("run_on");
    return;
  }
  j.beginObject("run_on")
      .field("verdict", m.run_on_verdict)
      .field("time", m.run_on_time)
      .field("stopped_by", m.run_on_stopped_by)
      .endObject();
}

/// --json with --vary: each strategy's points, its metrics at each value.
void writeVariedJson(std::ostream& out, const std::vector<CompareStrategy>& runs, const std::vector<double>& run_values,
                     const std::vector<CompareMetrics>& metrics, const Vary& vary)
{
  const std::vector<std::string>& names = metricNames();
  const std::size_t n = runs.size();
  JsonWriter j(out);
  j.beginObject().beginObject("vary").field("key", vary.key).field("absolute", vary.absolute).endObject();
  j.beginArray("strategies");
  for (std::size_t i = 0; i < n; ++i)
  {
    if (i % vary.steps.size() == 0)
    {
      j.beginObject().field("name", runs[i].name).beginArray("points");
    }
    j.beginObject().field("value", run_values[i]).field("verdict", metrics[i].verdict);
    const std::vector<double> values = metricValues(metrics[i]);
    for (std::size_t k = 0; k < names.size(); ++k)
    {
      j.field(names[k].c_str(), values[k]);
    }
    writeRunOn(j, metrics[i]);
    j.endObject();
    if ((i + 1) % vary.steps.size() == 0)
    {
      j.endArray().endObject();
    }
  }
  j.endArray().endObject();
}

/// --json: each strategy's metrics (NaN as null).
void writeJson(std::ostream& out, const std::vector<CompareMetrics>& metrics)
{
  const std::vector<std::string>& names = metricNames();
  JsonWriter j(out);
  j.beginObject().beginArray("strategies");
  for (const CompareMetrics& m : metrics)
  {
    j.beginObject().field("name", m.name).field("verdict", m.verdict);
    const std::vector<double> values = metricValues(m);
    for (std::size_t k = 0; k < names.size(); ++k)
    {
      j.field(names[k].c_str(), values[k]);  // NaN is written as null
    }
    writeRunOn(j, m);
    j.endObject();
  }
  j.endArray().endObject();
}

/// What ended a run-on that did not settle, and what would look further.
std::string runOnEnd(const CompareMetrics& m, const RunConfig& config)
{
  if (m.run_on_stopped_by == "max_duration")
  {
    return config.max_duration > 0.0 ? "the run-on's cap ended it (max_duration)"
                                     : "the run-on's cap ended it (set max_duration to look further)";
  }
  if (m.run_on_stopped_by == "wall_time")
  {
    return "its wall-time budget ended it (" + cell(RUN_ON_WALL_FACTOR) +
           " × the strategy's own run: the motion there costs more to simulate; a longer duration looks further)";
  }
  return "it ended: " + m.run_on_stopped_by;
}

/// Under the table, a line for each run the duration left undecided: what it became when run on, and when.
void writeRunOnNotes(std::ostream& out, const std::vector<CompareStrategy>& runs, const std::vector<double>& run_values,
                     const std::vector<CompareMetrics>& metrics, const Vary& vary, bool varied)
{
  for (std::size_t i = 0; i < runs.size(); ++i)
  {
    const CompareMetrics& m = metrics[i];
    if (m.run_on_verdict.empty())
    {
      continue;
    }
    out << "note: '" << m.name << "'" << (varied ? " at " + vary.key + " = " + formatNumber(run_values[i]) : "")
        << " is undecided within duration " << cell(runs[i].config.duration) << " s; run on until settled, ";
    if (m.run_on_stopped_by != "settled")
    {
      out << "it is " << (m.run_on_verdict == "undecided" ? "still " : "") << m.run_on_verdict << " at "
          << cell(m.run_on_time) << " s, where " << runOnEnd(m, runs[i].config) << "\n";
    }
    else
    {
      out << "it is " << m.run_on_verdict << " at " << cell(m.run_on_time) << " s (a duration of "
          << formatNumber(std::ceil(m.run_on_time)) << " s decides it here)\n";
    }
  }
}

/// The text table: a row a run, the units under the header.
void writeTable(std::ostream& out, const std::vector<CompareStrategy>& runs, const std::vector<double>& run_values,
                const std::vector<CompareMetrics>& metrics, const Vary& vary, bool varied_run)
{
  const std::size_t n = runs.size();
  const bool varied = varied_run;
  char buf[400];
  std::snprintf(buf, sizeof buf, "%-28s %-11s%-22s %9s %8s %9s %9s %8s %9s %9s %9s %9s %9s %9s %8s %8s\n", "strategy",
                varied ? vary.key.substr(0, 10).c_str() : "", "verdict", "lc err", "period", "p-p", "steady", "settle",
                "rms err", "steady rms", "max err", "overshoot", "impacts/s", "E_imp/s", "peak T", "rms T");
  out << buf;
  out << "  (" << (varied ? "value in SI units; " : "")
      << "rad, s, rad, rad, s, rad, rad, rad, rad, 1/s, W, N·m, N·m; '-': does not apply; settling band "
      << cell(metrics.empty() ? NAN : metrics.front().settling_band) << " rad)\n";
  for (std::size_t i = 0; i < n; ++i)
  {
    const CompareMetrics& m = metrics[i];
    std::snprintf(buf, sizeof buf, "%-28s %-11s%-22s %9s %8s %9s %9s %8s %9s %9s %9s %9s %9s %9s %8s %8s\n",
                  m.name.substr(0, 28).c_str(), varied ? cell(run_values[i]).c_str() : "", m.verdict.c_str(),
                  cell(m.limit_cycle_error).c_str(), cell(m.period).c_str(), cell(m.peak_to_peak).c_str(),
                  cell(m.steady_error).c_str(), cell(m.settling_time).c_str(), cell(m.rms_error).c_str(),
                  cell(m.steady_rms_error).c_str(), cell(m.max_error).c_str(), cell(m.overshoot).c_str(),
                  cell(m.impacts_per_second).c_str(), cell(m.impact_energy_per_second).c_str(),
                  cell(m.peak_torque).c_str(), cell(m.rms_torque).c_str());
    out << buf;
  }
  writeRunOnNotes(out, runs, run_values, metrics, vary, varied);
}

/// The outputs, checked and their temporaries created before any strategy runs.
struct Outputs
{
  std::unique_ptr<SafeOutput> csv, png, svg;
  std::string chart_script;
  std::unique_ptr<TemporaryDirectory> chart_dir;  // the chart's data, drawn there and removed file by file
};

Outputs openOutputs(const Options& o)
{
  Outputs out;
  if (!o.csv_path.empty())
  {
    out.csv = std::make_unique<SafeOutput>("--csv", o.csv_path, std::vector<std::string>{o.config_path});
  }
  if (!o.png_path.empty())
  {
    if (!isPngPath(o.png_path))
    {
      throw ConfigError("--png: '" + o.png_path + "' must end in .png (the SVG is written beside it)");
    }
    const std::string svg_path = o.png_path.substr(0, o.png_path.size() - 4) + ".svg";
    for (const std::string& other : {svg_path, o.png_path})
    {
      if (!o.csv_path.empty() && (other == o.csv_path || sameFile(other, o.csv_path)))
      {
        throw ConfigError("--png: '" + other + "' is also the --csv file");
      }
    }
    out.png = std::make_unique<SafeOutput>("--png", o.png_path, std::vector<std::string>{o.config_path});
    out.svg = std::make_unique<SafeOutput>("--png", svg_path, std::vector<std::string>{o.config_path});
    out.chart_script = helperBesideExecutable("compare_chart.py");
    out.chart_dir = std::make_unique<TemporaryDirectory>("backlash_compare");
  }
  return out;
}

int main(int argc, char** argv)
{
  Options options;
  int exit_code = 0;
  if (!parseOptions(argc, argv, &options, &exit_code))
  {
    return exit_code;
  }
  const std::string &config_path = options.config_path, &csv_path = options.csv_path, &png_path = options.png_path,
                    &vary_text = options.vary_text;
  const bool json = options.json, absolute = options.absolute;
  const int jobs = options.jobs;
  if (config_path.empty())
  {
    std::cerr << "backlash_compare: error: --config FILE.yaml is required (see --help)\n";
    return 2;
  }
  removeTemporariesOnSignals();
  CompareConfig config;
  Outputs outputs;
  Vary vary;
  std::vector<CompareStrategy> runs;  // what is run: the strategies, or each strategy at each varied value
  std::vector<double> run_values;     // --vary: the value [SI] of each run
  try
  {
    if (absolute && vary_text.empty())
    {
      throw ConfigError("--absolute needs --vary");
    }
    config = loadCompareConfig(config_path);
    if (!vary_text.empty())
    {
      vary = parseVary(vary_text);
      vary.absolute = absolute;
    }
    runs = planRuns(config, vary, !vary_text.empty(), &run_values);
    // Every output is checked and its temporary created before any strategy runs.
    outputs = openOutputs(options);
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_compare: error: " << e.what() << "\n";
    return 2;
  }
  const std::size_t n = runs.size();
  Progress progress(isatty(2) != 0, 0.5);
  StrategyRuns done = runStrategies(runs, config.sample_rate, jobs, !png_path.empty() && vary_text.empty(),
                                    [&](std::size_t k, std::size_t total) { progress.update(k, total); });
  progress.finish();
  const std::vector<CompareMetrics>& metrics = done.metrics;
  const std::vector<std::vector<CompareSample>>& trajectories = done.trajectories;
  const std::vector<std::string>& errors = done.errors;
  for (std::size_t i = 0; i < n; ++i)
  {
    if (!errors[i].empty())
    {
      std::cerr << "backlash_compare: error in strategy '" << runs[i].name << "'"
                << (vary_text.empty() ? "" : " with " + vary.key + " = " + formatNumber(run_values[i])) << ": "
                << errors[i] << "\n";
      return 1;
    }
  }
  try
  {
    if (outputs.csv)
    {
      writeMetricsCsv(outputs.csv->stream(), metrics, vary_text.empty() ? "" : vary.key, run_values);
      outputs.csv->commit();
      std::cerr << "backlash_compare: wrote " << csv_path << "\n";
    }
    if (outputs.png)
    {
      drawCharts(outputs.chart_script, *outputs.chart_dir, trajectories, metrics, vary_text.empty() ? "" : vary.key,
                 run_values, *outputs.png, *outputs.svg);
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_compare: error: " << e.what() << "\n";
    return 1;
  }
  std::ostringstream out;
  if (json && !vary_text.empty())
  {
    writeVariedJson(out, runs, run_values, metrics, vary);
    out << "\n";
  }
  else if (json)
  {
    writeJson(out, metrics);
    out << "\n";
  }
  else
  {
    writeTable(out, runs, run_values, metrics, vary, !vary_text.empty());
  }
  std::cout << out.str();
  try
  {
    flushStdout();
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_compare: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
