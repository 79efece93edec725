// backlash_sweep: the thesis' parameter study (and finer ones) in parallel, one CSV row per point, resumable.
// See docs/design.md. The pieces: sweep/sweep_grid (points by index), sweep/sweep_runner (threads, rows
// in order), sweep/sweep_csv (rows, resume), sweep/progress.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <thread>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/files/part_files.h"
#include "backlash_servo/files/run_program.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/studies/monte_carlo.h"
#include "backlash_servo/studies/sweep_csv.h"
#include "backlash_servo/studies/sweep_grid.h"
#include "backlash_servo/studies/sweep_runner.h"
#include "progress.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_sweep [axes] [--config FILE.yaml] [--preset thesis] [--output FILE|-] [--jobs N] [--resume]
Runs every combination of the axes (by default the chart form, w_n = 1 rad/s, J = 1 kg·m², rho = 1, unit step from
rest in forward contact), each until its limit-cycle verdict is settled, and writes one CSV row per point in a fixed
order. Any numeric parameter below is an axis when given a list "0.1,0.2,0.5", a range "start:stop:count" or
"log:start:stop:count"; given one value (or in --config FILE) it is a setting every point shares. Physical keys
(--motor-inertia ... --gain) switch to the physical form. Defaults: App. D1.
)";

std::atomic<bool> g_stop{false};               // no further points: interrupted, or the output failed
volatile std::sig_atomic_t g_interrupted = 0;  // SIGINT/SIGTERM/SIGHUP seen
void onSignal(int)
{
  g_interrupted = 1;
  g_stop = true;
}

struct SweepOptions
{
  SweepGrid grid;
  std::string output = "-";
  std::vector<std::string> inputs;  ///< files the run reads (--config, profile): never an output
  int jobs = 1;
  bool resume = false;
  double max_duration = 0.0;
  std::size_t shard_k = 1, shard_n = 1;  // --shard K/N
  std::string png;                       ///< --png FILE (a tolerance study's chart), "" = none
};

/// --vary KEY=DIST[;KEY=DIST] and --monte-carlo N --seed S into the grid (a key given its own flag as well is
/// refused, naming both).
void addVaried(const FlagParser& parser, SweepGrid* grid)
{
  if (parser.given("vary"))
  {
    std::stringstream items(parser.option("vary"));
    std::string item;
    while (std::getline(items, item, ';'))
    {
      const std::size_t eq = item.find('=');
      const std::string key = item.substr(0, eq);
      if (eq == std::string::npos || !isDistributionText(item.substr(eq + 1)))
      {
        throw ConfigError(
            "--vary: expected KEY=uniform(a,b), KEY=normal(mean,sigma) or KEY=lognormal(mu,sigma) (got '" + item +
            "')");
      }
      if (parser.keys().has(key))
      {
        throw ConfigError("--vary draws " + key + ", which is also given as " + flagName(key) + " (or in --config)");
      }
      if (findParam(key) == nullptr)
      {
        throw ConfigError("--vary: unknown key '" + key + "'" + didYouMean(key));
      }
      grid->addDraw(parseDistribution(key, item.substr(eq + 1)));
    }
  }
  if (parser.given("monte_carlo") || !grid->draws().empty())
  {
    const double n = parser.optionNumber("monte_carlo", 0.0), seed = parser.optionNumber("seed", 1.0);
    if (parser.given("monte_carlo") && !(n >= 1.0 && n <= 1e9 && n == std::floor(n)))
    {
      throw ConfigError("--monte-carlo: a whole number of joints in [1, 1e9] (got " + parser.option("monte_carlo") +
                        ")");
    }
    if (!(seed >= 0.0 && seed < 0x1p64 && seed == std::floor(seed)))
    {
      throw ConfigError("--seed: a whole number in [0, 2^64) (got " + parser.option("seed") + ")");
    }
    grid->setMonteCarlo(static_cast<std::size_t>(n), static_cast<std::uint64_t>(seed));
    grid->size();  // its checks: draws without N, N without draws, other axes with several values
  }
  else if (parser.given("seed"))
  {
    throw ConfigError("--seed needs --monte-carlo N");
  }
}

SweepOptions parse(int argc, char** argv)
{
  std::vector<std::string> keys =
      keysOfSections({ParamSection::Servo, ParamSection::Chart, ParamSection::Drive, ParamSection::Initial});
  keys.push_back("max_duration");
  keys.push_back("max_events");
  keys.push_back("settling_band");
  FlagParser parser(
      "backlash_sweep", HEADER, keys,
      {{"config", "FILE.yaml",
        "the shared settings in snake_case (the YAML backlash_sim and the node load); flags override it"},
       {"preset", "thesis",
        "the 1961 grid: zeta {.1,.2,.3,.4,.5,.6,.8,1}, friction {0,.2,.4,.6,.8,1}, inertia {0.04,0.1,1/9,0.25,1,4,9}, "
        "e {0,.6,.8,1}, backlash 0.3 (1344 points); axes given as flags replace its axes"},
       {"output", "FILE", "CSV file, '-' = stdout (default)"},
       {"jobs", "N", "worker threads (default: all cores)"},
       {"resume", "", "keep the rows already in FILE (same grid only) and compute the missing points"},
       {"tracking", "",
        "also the tracking figures of every point: settling_band, settling_time, steady_rms_error (a sampled replay "
        "of each run, as backlash_sim reports them; about twice the time)"},
       {"shard", "K/N", "compute only part K of N (contiguous points by grid index) into a part file for --merge"},
       {"merge", "PART...", "join part files (any order) into --output: exactly the CSV of an unsharded run"},
       {"monte_carlo", "N",
        "a tolerance study: N joints whose drawn keys (KEY 'uniform(a,b)', 'normal(mean,sigma)', "
        "'lognormal(mu,sigma)', truncated to the key's range) are drawn anew for each; every other key one value; "
        "a summary follows the CSV"},
       {"vary", "KEY=DIST[;KEY=DIST]",
        "keys drawn for --monte-carlo, as an alternative to giving KEY its distribution"},
       {"seed", "S", "the draws' seed (default 1): joint i of seed S is the same in every shard, resume and rerun"},
       {"png", "FILE",
        "with --monte-carlo: also chart the study (verdict shares, cycle sizes and periods, the best-separating keys); "
        "FILE.svg beside it"}});
  parser.parse(argc, argv);
  SweepOptions o;
  if (parser.given("preset"))
  {
    if (parser.option("preset") != "thesis")
    {
      throw ConfigError("--preset: the only preset is 'thesis'");
    }
    o.grid = SweepGrid::thesis();
  }
  const KeyValues& kv = parser.keys();
  addSweepKeys(kv, &o.grid);
  addVaried(parser, &o.grid);
  o.output = parser.option("output", "-");
  o.inputs = {parser.option("config"), kv.text("profile", "")};
  o.jobs = static_cast<int>(parser.optionNumber("jobs", std::max(1u, std::thread::hardware_concurrency())));
  if (o.jobs < 1 || o.jobs > 4096)
  {
    throw ConfigError("--jobs must be in [1, 4096]");
  }
  o.resume = parser.given("resume");
  o.png = parser.option("png");
  if (!o.png.empty() && o.grid.draws().empty())
  {
    throw ConfigError("--png charts a tolerance study: it needs --monte-carlo N and a drawn key");
  }
  if (!o.png.empty() && !isPngPath(o.png))
  {
    throw ConfigError("--png: '" + o.png + "' must end in .png (the SVG is written beside it)");
  }
  o.grid.setTracking(parser.given("tracking"));
  if (parser.given("shard"))
  {
    unsigned long long k = 0, n = 0;
    char tail = 0;
    if (std::sscanf(parser.option("shard").c_str(), "%llu/%llu%c", &k, &n, &tail) != 2 || n < 1 || k < 1 || k > n ||
        n > 100000)
    {
      throw ConfigError("--shard: expected K/N with 1 <= K <= N <= 100000 (got '" + parser.option("shard") + "')");
    }
    o.shard_k = k;
    o.shard_n = n;
    if (!o.png.empty())
    {
      throw ConfigError("--png charts a whole study: run it without --shard (or chart the merged CSV's study again)");
    }
  }
  o.max_duration = parser.keys().number("max_duration", 0.0);
  param("max_duration").check(o.max_duration);
  // Parts made with another run-length cap or another profile content must not merge or resume together.
  std::string signature;
  if (o.max_duration > 0.0)
  {
    char buf[40];
    std::snprintf(buf, sizeof buf, "max_duration=%.17g;", o.max_duration);
    signature += buf;
  }
  if (kv.has("profile"))
  {
    signature += "profile=" + readRegularFile("--profile", kv.text("profile", ""), std::size_t(1) << 30) + ";";
  }
  if (o.grid.tracking())
  {
    signature += "tracking;";
  }
  o.grid.setRunSignature(signature);
  if (o.resume && o.output == "-")
  {
    throw ConfigError("--resume needs --output FILE");
  }
  o.grid.requireValidPoints();  // before any output: one clear line on the first bad point
  return o;
}

}  // namespace

/// --png: the chart's outputs, checked and created before the study runs, and its script and data directory.
struct BatchChart
{
  explicit BatchChart(const SweepOptions& o)
      : png("--png", o.png, o.inputs),
        svg("--png", o.png.substr(0, o.png.size() - 4) + ".svg", o.inputs),
        script(helperBesideExecutable("batch_chart.py")),
        dir("backlash_sweep")
  {
    if (o.output != "-" && (o.output == o.png || o.output == svg.path() || sameFile(o.output, o.png)))
    {
      throw ConfigError("--png: '" + o.png + "' (or its SVG) is also the --output file");
    }
  }
  SafeOutput png, svg;
  std::string script;
  TemporaryDirectory dir;
};

/// The study's rows and summary into the chart's directory, drawn there by its script, then moved into place.
void drawBatchChart(BatchChart& chart, const std::string& batch, const MonteCarloSummary& s)
{
  {
    std::ofstream(chart.dir.file("batch.csv")) << batch;
    std::ofstream v(chart.dir.file("verdicts.csv"));
    v << "verdict,count,fraction,low,high\n";
    v.precision(10);
    for (const MonteCarloSummary::Share& share : s.verdicts)
    {
      v << share.verdict << "," << share.count << "," << share.fraction << "," << share.low << "," << share.high
        << "\n";
    }
    std::ofstream k(chart.dir.file("influences.csv"));
    k << "key,unit,rank_correlation,threshold,above,accuracy\n";
    k.precision(10);
    for (const KeyInfluence& i : s.influences)
    {
      k << i.key << "," << param(i.key).unit << "," << csvNumber(i.rank_correlation) << "," << csvNumber(i.threshold)
        << "," << i.above << "," << i.accuracy << "\n";
    }
    if (!v.flush() || !k.flush())
    {
      throw std::runtime_error("--png: writing the chart data to '" + chart.dir.path() + "' failed (disk full?)");
    }
  }
  const std::string png_tmp = chart.dir.file("chart.png"), svg_tmp = chart.dir.file("chart.svg");
  runChartScript(chart.script, chart.dir.path(), png_tmp);
  for (auto* to : {&chart.png, &chart.svg})
  {
    copyFileInto(to == &chart.png ? png_tmp : svg_tmp, *to);
    std::cerr << "backlash_sweep: wrote " << to->path() << "\n";
  }
}

/// `--merge PART... --output FILE`: the parts of a sharded sweep joined into the unsharded CSV.
int merge(int argc, char** argv)
{
  std::vector<std::string> parts;
  std::string output;
  if (!readMergeArguments(argc, argv, "backlash_sweep", "--output", &parts, &output))
  {
    return 2;
  }
  try
  {
    if (output.empty() || output == "-")
    {
      throw ConfigError("--merge needs --output FILE");
    }
    SafeOutput file("--output", output, parts);  // checked before the parts are read
    const std::string csv = mergeParts(parts);
    file.stream() << csv;
    file.commit();
  }
  catch (const ConfigError& e)
  {
    std::cerr << "backlash_sweep: error: " << e.what() << "\n";
    return 2;
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_sweep: error: " << e.what() << "\n";
    return 1;
  }
  std::fprintf(stderr, "backlash_sweep: merged %zu parts into '%s'\n", parts.size(), output.c_str());
  return 0;
}

/// How the run ended, as the exit code: a write that failed (the partial file removed), the output committed, a
/// point's error, an interruption (--resume finishes it), or the figures of a complete run.
struct RunEnd
{
  bool write_failed = false;
  std::size_t written = 0, first = 0, last = 0, kept = 0;
  double elapsed = 0.0;  ///< [s] wall
};

int endRun(const SweepOptions& o, const SweepShard& shard, SafeOutput* file, const SweepRunResult& run,
           const RunEnd& end)
{
  const std::size_t written = end.written, first = end.first, last = end.last;
  if (end.write_failed)
  {
    if (file)
    {
      file->discard();
    }
    std::cerr << "backlash_sweep: error: writing " << (file ? "'" + o.output + "'" : std::string("standard output"))
              << " failed after " << written << " of " << last - first << " rows (disk full?); stopped computing"
              << (file ? "; the partial file was removed and '" + o.output + "' is as before" : std::string()) << "\n";
    return 1;
  }
  if (file)
  {
    try
    {
      file->commit();
    }
    catch (const std::exception& e)
    {
      std::cerr << "backlash_sweep: error: " << e.what() << "\n";
      return 1;
    }
  }
  if (!run.failure.empty())
  {
    std::cerr << "backlash_sweep: error at " << run.failure << "\n";
    return 1;
  }
  if (g_interrupted)
  {
    std::cerr << "backlash_sweep: interrupted: " << end.kept + run.delivered << " of " << last - first
              << " points written; rerun with --resume to finish\n";
    return 130;
  }
  std::fprintf(
      stderr, "backlash_sweep: %zu points (%zu computed) in %.3f s wall with %d jobs%s\n", last - first,
      last - first - end.kept, end.elapsed, o.jobs,
      shard.whole() ? "" : (" (part " + std::to_string(shard.k) + "/" + std::to_string(shard.n) + ")").c_str());
  return 0;
}

int main(int argc, char** argv)
{
  for (int i = 1; i < argc; ++i)
  {
    if (std::string(argv[i]) == "--merge")
    {
      return merge(argc, argv);
    }
  }
  SweepOptions o;
  SweepShard shard;
  std::vector<std::string> kept;
  try
  {
    o = parse(argc, argv);
    shard = shardOf(o.shard_k, o.shard_n, o.grid.size());
    if (o.resume)
    {
      kept = resumableRows(o.output, o.grid, shard);
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_sweep: error: " << e.what() << "\n";
    return 2;
  }
  const std::size_t total = o.grid.size();

  // An interrupted run keeps the rows it completed (--resume continues them): the handlers only stop the pool.
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::signal(SIGHUP, onSignal);
  std::unique_ptr<SafeOutput> file;
  std::ostream* out = &std::cout;
  if (o.output != "-")
  {
    try
    {
      // Checked and created before the first point: the rows go to a private temporary beside the target, which
      // replaces it only when the run ends (complete, interrupted or stopped by a point's error).
      file = std::make_unique<SafeOutput>("--output", o.output, o.inputs);
    }
    catch (const std::exception& e)
    {
      std::cerr << "backlash_sweep: error: " << e.what() << "\n";
      return 2;
    }
    out = &file->stream();
  }
  std::unique_ptr<BatchChart> chart;
  if (!o.png.empty())
  {
    try
    {
      if (total > MAX_SUMMARY_JOINTS)
      {
        throw ConfigError("--png: a study of more than " + std::to_string(MAX_SUMMARY_JOINTS) +
                          " joints is not charted (its summary is not kept)");
      }
      chart = std::make_unique<BatchChart>(o);
    }
    catch (const std::exception& e)
    {
      std::cerr << "backlash_sweep: error: " << e.what() << "\n";
      return 2;
    }
  }
  SweepCsvWriter csv(*out);
  if (!shard.whole())
  {
    *out << shard.headerLine(o.grid) << "\n";
  }
  csv.header(o.grid);
  // A tolerance study's rows, kept for its summary (a whole study of at most MAX_SUMMARY_JOINTS).
  const bool summarised = !o.grid.draws().empty() && shard.whole() && total <= MAX_SUMMARY_JOINTS;
  std::string batch = summarised ? o.grid.header() + "\n" : "";
  for (const std::string& line : kept)
  {
    csv.row(line);
    batch += summarised ? line + "\n" : "";
  }
  bool write_failed = !csv.flush();
  std::size_t written = write_failed ? 0 : kept.size();

  Progress progress(isatty(2) && o.output != "-");
  const std::size_t first = shard.whole() ? 0 : shard.first;
  const std::size_t last = shard.whole() ? total : shard.last;
  SweepRunResult run;
  if (!write_failed)
  {
    run = runSweepPoints(
        first + kept.size(), last, o.jobs,
        [&](std::size_t i) { return evaluateSweepPoint(o.grid.point(i), o.max_duration, o.grid.tracking()); },
        [&](std::size_t i, const std::string& row) {
          if (write_failed)
          {
            return;  // rows computed before the pool saw the stop
          }
          csv.row(row);
          batch += summarised ? row + "\n" : "";
          if (!csv.flush())
          {
            write_failed = true;
            g_stop = true;  // no point computing what cannot be written
            return;
          }
          ++written;
          progress.update(i + 1 - first, last - first);
        },
        g_stop);
  }
  progress.finish();
  RunEnd end;
  end.write_failed = write_failed;
  end.written = written;
  end.first = first;
  end.last = last;
  end.kept = kept.size();
  end.elapsed = progress.elapsed();
  const int code = endRun(o, shard, file.get(), run, end);
  if (code == 0 && shard.whole() && !o.grid.draws().empty() && !summarised)
  {
    std::cerr << "backlash_sweep: no summary of more than " << MAX_SUMMARY_JOINTS
              << " joints (the CSV holds every draw and verdict)\n";
  }
  if (code == 0 && summarised)
  {
    std::vector<std::string> drawn;
    for (const Distribution& d : o.grid.draws())
    {
      drawn.push_back(d.key);
    }
    const MonteCarloSummary summary = summarizeBatch(batch, drawn);
    // The summary goes beside the CSV: after it on standard output when the CSV is a file, else to stderr.
    (o.output == "-" ? std::cerr : std::cout) << summaryText(summary) << std::flush;
    if (chart)
    {
      try
      {
        drawBatchChart(*chart, batch, summary);
      }
      catch (const std::exception& e)
      {
        std::cerr << "backlash_sweep: error: " << e.what() << "\n";
        return 1;
      }
    }
  }
  return code;
}
