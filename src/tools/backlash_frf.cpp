// backlash_frf: the joint's frequency response by stepped sines, from the exact motion. See
// docs/frequency_response.md.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/part_files.h"
#include "backlash_servo/files/run_program.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/frequency/broadband_response.h"
#include "backlash_servo/frequency/frequency_response.h"
#include "backlash_servo/model/constants.h"
#include "frf/broadband_report.h"
#include "progress.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_frf [--config FILE.yaml] [any servo, drive or initial-state flag] --amplitude A[,A...]
                   (--frequency W[,W...] | --frequency-range LO:HI:N) [--channel CHANNEL] [--offset U0]
                   [--injection-rate HZ] [--tolerance TOL] [--max-periods N] [--harmonics N] [--linear]
                   [--json] [--csv FILE|-] [--png FILE.png] [--jobs N]
       backlash_frf ... --excitation prbs|chirp --amplitude A[,A...] [--prbs-order N] [--prbs-hold H]
                   [--chirp LO:HI] [--chirp-samples N] [--periods P] [--settle-periods S]
       backlash_frf ... --shard K/N --csv PART.csv        backlash_frf --merge PART... --csv FILE
The joint's frequency response as a drive's commissioning tool measures it, one sine at a time, from the exact
motion: for each amplitude and frequency the periodic steady state is detected (a point that does not settle says
so), then the fundamental's gain and phase, the harmonic distortion and how often the teeth cross the backlash.
Channels: command:load_position (the command theta_R through the configured digital drive -> theta_c; the default),
motor_torque:motor_velocity and motor_torque:load_velocity (the motor torque, the drive's loop off -> omega),
torque_setpoint:motor_velocity and torque_setpoint:load_velocity (a torque injected into the digital drive's
set-point with its loops closed; the response is omega per N*m of the motor torque applied, the mechanics, and
--offset is the command's speed [rad/s] so that the joint keeps turning), load_torque:load_position (a sine torque
on the load, the sine itself, the configured loop holding the command -> theta_c: the servo's dynamic compliance;
--offset is a constant load torque added to load_torque [N*m]).
With --excitation prbs or chirp: one periodic broadband excitation instead, recorded at the samples, and the H1
estimate with its coherence per DFT line - what a drive's commissioning tool shows.
SI units: amplitudes and offsets in rad (command) or N*m (torques; the set-point's offset in rad/s), frequencies in
rad/s, phases in rad.
)";

struct Options
{
  RunConfig config;
  FrfSettings settings;
  std::vector<double> amplitudes, frequencies;
  std::string excitation = "sine";       // sine | prbs | chirp
  std::size_t shard_k = 1, shard_n = 1;  // --shard K/N
  std::string fingerprint;               // of the run's arguments (what parts of one run share)
  BroadbandSettings broadband;
  bool json = false, linear = false, dry_run = false;
  int jobs = 1;
  std::string config_path, csv_path, png_path;
};

std::vector<double> numberList(const std::string& flag, const std::string& text)
{
  std::vector<double> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ','))
  {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(v) || !(v > 0.0))
    {
      throw ConfigError("--" + flag + ": '" + item + "' is not a number > 0 (in '" + text + "')");
    }
    out.push_back(v);
  }
  if (out.empty())
  {
    throw ConfigError("--" + flag + ": no values in '" + text + "'");
  }
  return out;
}

/// LO:HI:N → N frequencies spaced logarithmically from LO to HI [rad/s].
std::vector<double> logRange(const std::string& text)
{
  double lo = 0.0, hi = 0.0;
  int n = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf:%lf:%d%c", &lo, &hi, &n, &tail) != 3 || !(lo > 0.0) || !(hi >= lo) ||
      !std::isfinite(hi) || n < 1 || n > 100000 || (n == 1 && hi != lo))
  {
    throw ConfigError("--frequency-range: '" + text +
                      "' is not LO:HI:N with 0 < LO <= HI [rad/s] and N in [1, 100000] points (N = 1: LO = HI)");
  }
  std::vector<double> out;
  for (int i = 0; i < n; ++i)
  {
    out.push_back(n == 1 ? lo : lo * std::pow(hi / lo, static_cast<double>(i) / (n - 1)));
  }
  return out;
}

/// The flags: the joint's keys and the tool's options, with their help.
FlagParser frfFlags()
{
  return FlagParser(
      "backlash_frf", HEADER,
      keysOfSections({ParamSection::Servo, ParamSection::Chart, ParamSection::Drive, ParamSection::Initial}),
      {{"config", "FILE.yaml", "the joint's keys in snake_case (flags override it)"},
       {"channel", "CHANNEL",
        "command:load_position (default), motor_torque:motor_velocity, motor_torque:load_velocity, "
        "torque_setpoint:motor_velocity, torque_setpoint:load_velocity, load_torque:load_position"},
       {"amplitude", "A[,A...]", "sine amplitudes [rad for the command, N*m for the torques]"},
       {"frequency", "W[,W...]", "frequencies [rad/s]"},
       {"frequency_range", "LO:HI:N", "N frequencies spaced logarithmically from LO to HI [rad/s]"},
       {"offset", "U0",
        "the input's constant part [rad or N*m] (default 0); set-point channels: the command's speed [rad/s]"},
       {"injection_rate", "HZ",
        "torque channels: samples per second of the injected torque (default: the drive's "
        "controller_rate, else 10000 Hz)"},
       {"tolerance", "TOL", "steady state: relative repeat of the state from one period to the next (default 1e-8)"},
       {"max_periods", "N",
        "periods run before a point is declared not periodic (default: 40 of the joint's slowest time constants, at "
        "least 1000)"},
       {"harmonics", "N", "harmonics integrated; distortion from the 2nd to the Nth (default 10)"},
       {"linear", "", "also the response with backlash 0 at every point (always drawn on --png)"},
       {"json", "", "one JSON object on stdout"},
       {"csv", "FILE|-", "the points as CSV (- for stdout)"},
       {"png", "FILE.png", "Bode chart: gain and phase against frequency, one curve per amplitude, backlash 0 dashed"},
       {"jobs", "N", "worker threads (default: all cores)"},
       {"excitation", "KIND", "sine (stepped sines, the default), prbs or chirp (broadband: H1 and coherence)"},
       {"prbs_order", "N", "prbs: a maximum-length sequence of 2^N - 1 bits, N in [3, 20] (default 10)"},
       {"prbs_hold", "H", "prbs: samples each bit is held (default 1)"},
       {"chirp", "LO:HI", "chirp: the sweep's frequencies [rad/s] (default: 0.01 to 0.25 of the sample rate)"},
       {"chirp_samples", "N", "chirp: samples a period (default 4096)"},
       {"periods", "P", "broadband: periods recorded and averaged (default 8)"},
       {"settle_periods", "S",
        "broadband: periods run first for the transient to decay (default 0: automatic, 40 of the joint's slowest "
        "time constants, at least 2)"},
       {"shard", "K/N",
        "stepped sines: compute only part K of N (contiguous points, amplitude-major) into the --csv "
        "part file, for --merge"},
       {"dry_run", "", "check every argument and point, compute and write nothing"},
       {"continuous", "",
        "torque channels: the sine itself, not sampled and held (not on rigid teeth with dry friction)"},
       {"merge", "PART...",
        "join the part files of one sharded run (any order) into --csv FILE: exactly the CSV of "
        "an unsharded run"}});
}

/// The broadband excitation's settings (--prbs-*, --chirp*, --periods, --settle-periods).
void readBroadband(const FlagParser& parser, Options* options)
{
  Options& o = *options;
  BroadbandSettings& b = o.broadband;
  b.kind = o.excitation == "prbs" ? BroadbandKind::Prbs : BroadbandKind::Chirp;
  const auto whole = [&](const char* flag, int fallback, int lo, int hi) {
    const double v = parser.optionNumber(flag, fallback);
    if (!(v >= lo && v <= hi) || v != std::floor(v))
    {
      std::string shown = std::string("--") + flag;
      std::replace(shown.begin(), shown.end(), '_', '-');
      throw ConfigError(shown + " must be a whole number in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return static_cast<int>(v);
  };
  b.prbs_order = whole("prbs_order", 10, 3, 20);
  b.prbs_hold = whole("prbs_hold", 1, 1, 1000);
  b.chirp_samples = whole("chirp_samples", 4096, 16, 1 << 20);
  b.periods = whole("periods", 8, 1, 10000);
  b.settle_periods = whole("settle_periods", 0, 0, 10000);
  if (parser.given("chirp"))
  {
    char tail = 0;
    if (std::sscanf(parser.option("chirp").c_str(), "%lf:%lf%c", &b.chirp_low, &b.chirp_high, &tail) != 2 ||
        !(b.chirp_low > 0.0) || !(b.chirp_high > b.chirp_low) || !std::isfinite(b.chirp_high))
    {
      throw ConfigError("--chirp: '" + parser.option("chirp") + "' is not LO:HI with 0 < LO < HI [rad/s]");
    }
  }
}

/// The stepped sines' settings: offset, injection, tolerance, periods, harmonics.
void readSineSettings(const FlagParser& parser, bool torque_channel, Options* options)
{
  Options& o = *options;
  o.settings.offset = parser.optionNumber("offset", 0.0);
  o.settings.continuous = parser.given("continuous");
  if (o.settings.continuous &&
      (!torque_channel || parser.given("injection_rate") || parser.option("excitation", "sine") != "sine"))
  {
    throw ConfigError(
        "--continuous is for stepped sines on the torque channels, without --injection-rate (the "
        "command takes the sine itself under the continuous law)");
  }
  o.settings.injection_rate = parser.optionNumber("injection_rate", 0.0);
  if (parser.given("injection_rate") && !(o.settings.injection_rate > 0.0))
  {
    throw ConfigError("--injection-rate must be > 0 Hz");
  }
  if (parser.given("injection_rate") && !torque_channel)
  {
    throw ConfigError("--injection-rate is for the torque channels: the command is sampled by the drive");
  }
  o.settings.tolerance = parser.optionNumber("tolerance", 1e-8);
  if (!(o.settings.tolerance > 0.0 && o.settings.tolerance < 1.0))
  {
    throw ConfigError("--tolerance must be in (0, 1)");
  }
  const double periods = parser.optionNumber("max_periods", 0.0);
  if (parser.given("max_periods") && (!(periods >= 3.0 && periods <= 1e7) || periods != std::floor(periods)))
  {
    throw ConfigError("--max-periods must be a whole number in [3, 1e7]");
  }
  o.settings.max_periods = static_cast<int>(periods);
  const double harmonics = parser.optionNumber("harmonics", 10.0);
  if (!(harmonics >= 1.0 && harmonics <= 100.0) || harmonics != std::floor(harmonics))
  {
    throw ConfigError("--harmonics must be a whole number in [1, 100]");
  }
  o.settings.harmonics = static_cast<int>(harmonics);
}

/// The outputs, the jobs and a shard.
void readOutputs(const FlagParser& parser, bool sine, Options* options)
{
  Options& o = *options;
  o.linear = parser.given("linear") || parser.given("png");
  o.json = parser.given("json");
  o.csv_path = parser.option("csv");
  o.png_path = parser.option("png");
  if (parser.given("png") && !isPngPath(o.png_path))
  {
    throw ConfigError("--png: '" + o.png_path + "' must end in .png");
  }
  if (o.json && o.csv_path == "-")
  {
    throw ConfigError("--json and --csv - both want stdout: write the CSV to a file");
  }
  const double jobs = parser.optionNumber("jobs", std::max(1u, std::thread::hardware_concurrency()));
  if (!(jobs >= 1.0 && jobs <= 4096.0) || jobs != std::floor(jobs))
  {
    throw ConfigError("--jobs must be a whole number in [1, 4096]");
  }
  o.jobs = static_cast<int>(jobs);
  if (parser.given("shard"))
  {
    unsigned long long k = 0, n = 0;
    char tail = 0;
    if (std::sscanf(parser.option("shard").c_str(), "%llu/%llu%c", &k, &n, &tail) != 2 || n < 1 || k < 1 || k > n ||
        n > 100000)
    {
      throw ConfigError("--shard: expected K/N with 1 <= K <= N <= 100000 (got '" + parser.option("shard") + "')");
    }
    if (!sine)
    {
      throw ConfigError("--shard is for stepped sines: a broadband estimate is one run");
    }
    if (o.csv_path.empty() || o.csv_path == "-" || o.json || parser.given("png"))
    {
      throw ConfigError("--shard writes its points to a part file: give --csv PART.csv (and no --json or --png)");
    }
    o.shard_k = k;
    o.shard_n = n;
  }
}

Options parse(int argc, char** argv)
{
  FlagParser parser = frfFlags();
  parser.parse(argc, argv);
  Options o;
  o.config_path = parser.option("config");
  o.settings.channel = frfChannelFrom(parser.option("channel", "command:load_position"), "--channel");
  const bool torque_channel = torqueInput(o.settings.channel);
  o.config = runConfigFrom(parser.keys(), torque_channel ? ControlMode::Effort : ControlMode::Position);
  if (!parser.given("amplitude"))
  {
    throw ConfigError("--amplitude is required: the sine amplitudes [rad for the command, N*m for the torque]");
  }
  o.amplitudes = numberList("amplitude", parser.option("amplitude"));
  o.excitation = parser.option("excitation", "sine");
  if (o.excitation != "sine" && o.excitation != "prbs" && o.excitation != "chirp")
  {
    throw ConfigError("--excitation: '" + o.excitation + "' is not sine, prbs or chirp");
  }
  const bool sine = o.excitation == "sine";
  for (const char* flag : {"prbs_order", "prbs_hold", "chirp", "chirp_samples", "periods", "settle_periods"})
  {
    const std::string f = flag;
    const bool belongs =
        !sine && (f.rfind("prbs", 0) == 0 ? o.excitation == "prbs"
                                          : (f.rfind("chirp", 0) == 0 ? o.excitation == "chirp" : true));
    if (parser.given(f) && !belongs)
    {
      std::string shown = "--" + f;
      std::replace(shown.begin(), shown.end(), '_', '-');
      throw ConfigError(shown + " does not apply to --excitation " + o.excitation);
    }
  }
  if (!sine)
  {
    if (parser.given("frequency") || parser.given("frequency_range") || parser.given("tolerance") ||
        parser.given("max_periods") || parser.given("harmonics") || parser.given("jobs"))
    {
      throw ConfigError("--excitation " + o.excitation +
                        " sets its own frequencies: --frequency, --frequency-range, --tolerance, --max-periods, "
                        "--harmonics and --jobs are for stepped sines");
    }
    readBroadband(parser, &o);
  }
  else if (parser.given("frequency") == parser.given("frequency_range"))
  {
    throw ConfigError("give exactly one of --frequency W[,W...] and --frequency-range LO:HI:N [rad/s]");
  }
  if (sine)
  {
    o.frequencies = parser.given("frequency") ? numberList("frequency", parser.option("frequency"))
                                              : logRange(parser.option("frequency_range"));
  }
  readSineSettings(parser, torque_channel, &o);
  readOutputs(parser, sine, &o);
  o.dry_run = parser.given("dry_run");
  o.broadband.channel = o.settings.channel;
  o.broadband.offset = o.settings.offset;
  o.broadband.injection_rate = o.settings.injection_rate;
  return o;
}

struct Row
{
  FrfPoint point;
  FrfPoint linear;  // backlash 0 (with --linear)
  bool has_linear = false;
  /// Why the point has no figures: its simulation exceeded the event budget or ran away (the other points go on).
  std::string stopped;
};

/// The row of a point whose simulation stopped: its amplitude and frequencies, no figures (NaN), not periodic.
Row stoppedRow(const Options& o, double amplitude, double omega, const std::string& why)
{
  Row r;
  FrfPoint& p = r.point;
  p.amplitude = amplitude;
  p.requested_frequency = omega;
  p.frequency = frfSampling(o.config, o.settings, omega).frequency;
  for (double* f : {&p.gain, &p.phase, &p.distortion, &p.mean, &p.peak_to_peak, &p.flank_changes, &p.separations})
  {
    *f = NAN;
  }
  p.response = {NAN, NAN};
  r.stopped = why;
  return r;
}

/// Every (amplitude, frequency) pair, amplitude-major, on `jobs` threads; progress on a terminal.
std::vector<Row> measureAll(const Options& o)
{
  const std::size_t total = o.amplitudes.size() * o.frequencies.size();
  const std::size_t first = (o.shard_k - 1) * total / o.shard_n, count = o.shard_k * total / o.shard_n - first;
  std::vector<Row> rows(count);
  RunConfig linear = o.config;
  linear.params.backlash = 0.0;
  std::atomic<std::size_t> next{0}, done{0};
  std::atomic<bool> failed{false};
  std::mutex lock;
  std::string error;
  Progress progress(isatty(2) != 0, 1.0);
  const auto worker = [&]() {
    for (std::size_t i = next++; i < count && !failed; i = next++)
    {
      try
      {
        const std::size_t at = first + i;  // the point's index in the whole run
        const double a = o.amplitudes[at / o.frequencies.size()], w = o.frequencies[at % o.frequencies.size()];
        const auto stop = [&]() { return failed.load(); };
        try
        {
          rows[i].point = measureFrequencyResponse(o.config, o.settings, a, w, stop);
          if (o.linear)
          {
            rows[i].linear = measureFrequencyResponse(linear, o.settings, a, w, stop);
            rows[i].has_linear = true;
          }
        }
        catch (const EventBudgetExceeded& e)  // one point's impact storm: that point has no figures, the rest go on
        {
          rows[i] = stoppedRow(o, a, w, e.what());
        }
        catch (const MotionDiverged& e)
        {
          rows[i] = stoppedRow(o, a, w, e.what());
        }
        std::lock_guard<std::mutex> g(lock);
        progress.update(++done, count);
      }
      catch (const std::exception& e)
      {
        std::lock_guard<std::mutex> g(lock);
        if (!failed)
        {
          error = e.what();
        }
        failed = true;
      }
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < std::min<int>(o.jobs, static_cast<int>(count)); ++j)
  {
    threads.emplace_back(worker);
  }
  for (std::thread& t : threads)
  {
    t.join();
  }
  progress.finish();
  if (failed)
  {
    throw std::runtime_error(error);
  }
  return rows;
}

/// FNV-1a (64 bits) of the run's arguments without --shard, --csv and --jobs (and their values): the parts of one
/// sharded run share it, so parts of different runs never merge.
std::string fingerprintOf(int argc, char** argv)
{
  std::uint64_t h = 1469598103934665603ULL;
  for (int i = 1; i < argc; ++i)
  {
    const std::string a = argv[i];
    if (a == "--shard" || a == "--csv" || a == "--jobs")
    {
      ++i;  // and its value
      continue;
    }
    if (a.rfind("--shard=", 0) == 0 || a.rfind("--csv=", 0) == 0 || a.rfind("--jobs=", 0) == 0)
    {
      continue;
    }
    for (unsigned char c : a + '\0')
    {
      h = (h ^ c) * 1099511628211ULL;
    }
  }
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

/// The first line of a part file.
std::string partLine(std::size_t k, std::size_t n, std::size_t points, const std::string& fingerprint)
{
  return "# backlash_frf part " + std::to_string(k) + "/" + std::to_string(n) + " of " + std::to_string(points) +
         " points, run " + fingerprint;
}

/// `--merge PART... --csv FILE`: the parts of one sharded run, checked (one run, every part once), joined in order.
int merge(int argc, char** argv)
{
  std::vector<std::string> parts;
  std::string output;
  if (!readMergeArguments(argc, argv, "backlash_frf", "--csv", &parts, &output))
  {
    return 2;
  }
  try
  {
    if (output.empty() || output == "-" || parts.empty())
    {
      throw ConfigError("--merge needs part files and --csv FILE");
    }
    SafeOutput file("--csv", output, parts);  // checked before the parts are read
    std::size_t n = 0, points = 0;
    std::string run, header;
    std::vector<std::string> bodies;
    std::vector<bool> seen;
    for (const std::string& path : parts)
    {
      std::ifstream in(path);
      std::string first, head;
      unsigned long long k = 0, nn = 0, pp = 0;
      char id[40] = {};
      if (!in || !std::getline(in, first) || !std::getline(in, head) ||
          std::sscanf(first.c_str(), "# backlash_frf part %llu/%llu of %llu points, run %39s", &k, &nn, &pp, id) != 4 ||
          k < 1 || k > nn)
      {
        throw ConfigError("--merge: '" + path + "' is not a backlash_frf part file");
      }
      if (bodies.empty())
      {
        n = nn;
        points = pp;
        run = id;
        header = head;
        bodies.assign(n, "");
        seen.assign(n, false);
      }
      else if (nn != n || pp != points || run != id || head != header)
      {
        throw ConfigError("--merge: '" + path + "' is a part of another run (other arguments)");
      }
      if (seen[k - 1])
      {
        throw ConfigError("--merge: part " + std::to_string(k) + " given twice ('" + path + "')");
      }
      seen[k - 1] = true;
      std::ostringstream rest;
      rest << in.rdbuf();
      bodies[k - 1] = rest.str();
    }
    for (std::size_t k = 0; k < n; ++k)
    {
      if (!seen[k])
      {
        throw ConfigError("--merge: part " + std::to_string(k + 1) + "/" + std::to_string(n) + " is missing");
      }
    }
    file.stream() << header << "\n";
    for (const std::string& b : bodies)
    {
      file.stream() << b;
    }
    file.commit();
    std::fprintf(stderr, "backlash_frf: merged %zu parts into '%s'\n", parts.size(), output.c_str());
  }
  catch (const ConfigError& e)
  {
    std::cerr << "backlash_frf: error: " << e.what() << "\n";
    return 2;
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_frf: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

/// Per frequency: the smallest amplitude whose response crosses the backlash (NaN: none of them).
std::vector<double> crossingAmplitudes(const Options& o, const std::vector<Row>& rows)
{
  std::vector<double> out(o.frequencies.size(), NAN);
  for (std::size_t i = 0; i < rows.size(); ++i)
  {
    const std::size_t f = i % o.frequencies.size();
    if (rows[i].point.flank_changes > 0.0 && !(rows[i].point.amplitude >= out[f]))
    {
      out[f] = rows[i].point.amplitude;
    }
  }
  return out;
}

/// Per frequency: the release amplitude (frequency_response.h) from the linear run, NaN without --linear.
std::vector<double> releaseAmplitudes(const Options& o, const std::vector<Row>& rows)
{
  std::vector<double> out(o.frequencies.size(), NAN);
  for (std::size_t i = 0; i < rows.size() && i < o.frequencies.size(); ++i)
  {
    if (rows[i].has_linear)
    {
      out[i] = releaseAmplitude(rows[i].linear);  // (the smallest amplitude's: any gives the same, the joint linear)
    }
  }
  return out;
}

std::string number(double v)
{
  return csvNumber(v);
}

void writeCsv(std::ostream& out, const std::vector<Row>& rows, bool linear)
{
  out << "amplitude,requested_frequency,frequency,gain,phase,distortion,mean,peak_to_peak,periodic,period_multiple,"
         "periods,flank_changes,separations,periodic_to_count,count_spread";
  if (linear)
  {
    out << ",linear_gain,linear_phase";
  }
  out << "\n";
  for (const Row& r : rows)
  {
    const FrfPoint& p = r.point;
    out << number(p.amplitude) << "," << number(p.requested_frequency) << "," << number(p.frequency) << ","
        << number(p.gain) << "," << number(p.phase) << "," << number(p.distortion) << "," << number(p.mean) << ","
        << number(p.peak_to_peak) << "," << (p.periodic ? 1 : 0) << "," << p.period_multiple << "," << p.periods << ","
        << number(p.flank_changes) << "," << number(p.separations) << "," << (p.periodic_to_count ? 1 : 0) << ","
        << number(p.count_spread);
    if (linear)
    {
      out << "," << number(r.linear.gain) << "," << number(r.linear.phase);
    }
    out << "\n";
  }
}

void writeJson(const Options& o, const std::vector<Row>& rows)
{
  std::ostringstream out;
  JsonWriter w(out);
  w.beginObject();
  w.field("channel", std::string(toString(o.settings.channel)));
  w.field("offset", o.settings.offset);
  w.beginArray("points");
  for (const Row& r : rows)
  {
    const FrfPoint& p = r.point;
    w.beginObject();
    w.field("amplitude", p.amplitude);
    w.field("frequency", p.frequency);
    w.field("requested_frequency", p.requested_frequency);
    w.field("gain", p.gain);
    w.field("phase", p.phase);
    w.field("distortion", p.distortion);
    w.field("mean", p.mean);
    w.field("peak_to_peak", p.peak_to_peak);
    w.field("periodic", p.periodic);
    w.field("period_multiple", static_cast<double>(p.period_multiple));
    w.field("periods", static_cast<double>(p.periods));
    w.field("flank_changes", p.flank_changes);
    w.field("crosses_backlash", p.flank_changes > 0.0);
    w.field("separations", p.separations);
    w.field("periodic_to_count", p.periodic_to_count);
    w.field("count_spread", p.count_spread);
    if (r.stopped.empty())
    {
      w.null("stopped");
    }
    else
    {
      w.field("stopped", r.stopped);  // why the point has no figures
    }
    if (r.has_linear)
    {
      w.field("linear_gain", r.linear.gain);
      w.field("linear_phase", r.linear.phase);
    }
    w.endObject();
  }
  w.endArray();
  w.beginArray("backlash_crossing");
  const std::vector<double> crossing = crossingAmplitudes(o, rows), release = releaseAmplitudes(o, rows);
  for (std::size_t f = 0; f < o.frequencies.size(); ++f)
  {
    w.beginObject();
    w.field("frequency", rows[f].point.frequency);
    w.field("amplitude", crossing[f]);
    if (o.linear)
    {
      w.field("release_amplitude", release[f]);
    }
    w.endObject();
  }
  w.endArray();
  w.endObject();
  std::cout << out.str() << "\n";
}

void writeText(const Options& o, const std::vector<Row>& rows)
{
  const bool torque = torqueInput(o.settings.channel), setpoint = setpointInput(o.settings.channel),
             load = loadTorqueInput(o.settings.channel);
  std::printf("channel %s, offset %g %s; gain in %s, phase in rad\n", toString(o.settings.channel), o.settings.offset,
              torque || load ? "N*m"
              : setpoint     ? "rad/s"
                             : "rad",
              torque || setpoint ? "(rad/s)/(N*m)"
              : load             ? "rad/(N*m)"
                                 : "rad/rad");
  std::printf("%12s %12s %12s %12s %10s %8s %8s %s\n", "amplitude", "w [rad/s]", "gain", "phase", "THD", "flank/T",
              "apart/T", o.linear ? "steady state           linear gain / phase" : "steady state");
  for (const Row& r : rows)
  {
    const FrfPoint& p = r.point;
    char state[64];
    if (!r.stopped.empty())
    {
      std::snprintf(state, sizeof state, "STOPPED (see below)");
    }
    else if (p.periodic_to_count)
    {
      std::snprintf(state, sizeof state, "to 1 count (%d T, %.2g %%)", p.periods, 100.0 * p.count_spread);
    }
    else if (p.periodic)
    {
      std::snprintf(state, sizeof state, p.period_multiple == 1 ? "periodic (%d T)" : "period %dT (%d T run)",
                    p.period_multiple == 1 ? p.periods : p.period_multiple, p.periods);
    }
    else
    {
      std::snprintf(state, sizeof state, "NOT periodic (%d T)", p.periods);
    }
    // (A distortion below 1e-9 is the rounding of the Fourier integrals: the table says so; CSV and JSON keep it.)
    char distortion[16];
    std::snprintf(distortion, sizeof distortion, p.distortion < 1e-9 ? "<1e-9" : "%.3g", p.distortion);
    std::printf("%12.6g %12.6g %12.6g %12.6g %10s %8.3g %8.3g %-22s", p.amplitude, p.frequency, p.gain, p.phase,
                distortion, p.flank_changes, p.separations, state);
    if (r.has_linear)
    {
      std::printf(" %12.6g %12.6g", r.linear.gain, r.linear.phase);
    }
    std::printf("\n");
  }
  const std::vector<double> crossing = crossingAmplitudes(o, rows), release = releaseAmplitudes(o, rows);
  for (std::size_t f = 0; f < o.frequencies.size(); ++f)
  {
    if (std::isfinite(crossing[f]))
    {
      std::printf("w = %.6g rad/s: the teeth cross the backlash from amplitude %.6g on (of those run)",
                  rows[f].point.frequency, crossing[f]);
    }
    else
    {
      bool any_measured = false;  // (a stopped point says nothing of the teeth)
      for (std::size_t i = f; i < rows.size(); i += o.frequencies.size())
      {
        any_measured = any_measured || rows[i].stopped.empty();
      }
      std::printf(any_measured ? "w = %.6g rad/s: the teeth do not cross the backlash at any amplitude measured"
                               : "w = %.6g rad/s: every point stopped: nothing measured",
                  rows[f].point.frequency);
    }
    if (std::isfinite(release[f]))
    {
      std::printf("; they stay on their flank up to amplitude %.6g", release[f]);
    }
    std::printf("\n");
  }
}

/// The Bode chart: data to a private directory, drawn there by frf_chart.py (run without a shell), moved into place.
void drawChart(const Options& o, const std::vector<Row>& rows, const std::string& script, SafeOutput& png)
{
  TemporaryDirectory dir("backlash_frf");
  {
    std::ofstream points(dir.file("points.csv"));
    writeCsv(points, rows, true);
    if (!points.flush())
    {
      throw std::runtime_error("--png: writing the chart data to '" + dir.path() + "' failed (disk full?)");
    }
  }
  std::ofstream meta(dir.file("channel.txt"));
  meta << toString(o.settings.channel) << "\n";
  meta.close();
  const std::string tmp = dir.file("chart.png");
  runChartScript(script, dir.path(), tmp);
  copyFileInto(tmp, png);
  std::cerr << "backlash_frf: wrote " << png.path() << "\n";
}

/// The broadband path: one estimate per amplitude (and its backlash-0 twin), written as asked.
int runBroadband(const Options& o, SafeOutput* csv, SafeOutput* png, const std::string& chart_script)
{
  BroadbandSettings b = o.broadband;
  const double rate = excitationRate(o.config, b.channel, b.injection_rate);
  if (b.kind == BroadbandKind::Chirp && !(b.chirp_low > 0.0))
  {
    b.chirp_low = 0.01 * 2.0 * PI * rate;
    b.chirp_high = 0.25 * 2.0 * PI * rate;
  }
  RunConfig linear = o.config;
  linear.params.backlash = 0.0;
  std::vector<BroadbandEstimate> estimates;
  Progress progress(isatty(2) != 0, 1.0);
  const double runs = static_cast<double>(o.amplitudes.size()) * (o.linear ? 2.0 : 1.0);
  double done = 0.0;
  const auto step = [&](double f) { progress.update((done + f) / runs); };
  for (double a : o.amplitudes)
  {
    BroadbandEstimate e;
    e.amplitude = a;
    e.response = measureBroadband(o.config, b, a, step);
    done += 1.0;
    if (o.linear)
    {
      e.linear = measureBroadband(linear, b, a, step);
      e.has_linear = true;
      done += 1.0;
    }
    estimates.push_back(std::move(e));
  }
  progress.finish();
  const std::string channel = toString(o.settings.channel);
  if (csv)
  {
    writeBroadbandCsv(csv->stream(), estimates, o.linear);
    csv->commit();
    std::cerr << "backlash_frf: wrote " << csv->path() << "\n";
  }
  if (png)
  {
    TemporaryDirectory dir("backlash_frf");
    {
      std::ofstream lines(dir.file("lines.csv"));
      writeBroadbandCsv(lines, estimates, true);
      std::ofstream meta(dir.file("channel.txt"));
      meta << channel << "\n" << o.excitation << "\n";
      if (!lines.flush() || !meta.flush())
      {
        throw std::runtime_error("--png: writing the chart data to '" + dir.path() + "' failed (disk full?)");
      }
    }
    const std::string tmp = dir.file("chart.png");
    runChartScript(chart_script, dir.path(), tmp);
    copyFileInto(tmp, *png);
    std::cerr << "backlash_frf: wrote " << png->path() << "\n";
  }
  if (o.csv_path == "-")
  {
    writeBroadbandCsv(std::cout, estimates, o.linear);
  }
  else if (o.json)
  {
    writeBroadbandJson(std::cout, channel, o.excitation, o.settings.offset, estimates);
  }
  else
  {
    writeBroadbandText(std::cout, channel, o.excitation, estimates, 25);
  }
  flushStdout();
  return 0;
}

}  // namespace

int main(int argc, char** argv)
{
  for (int i = 1; i < argc; ++i)
  {
    if (std::string(argv[i]) == "--merge")
    {
      return merge(argc, argv);
    }
  }
  Options o;
  std::unique_ptr<SafeOutput> png, csv;
  std::string chart_script;
  try
  {
    o = parse(argc, argv);
    removeTemporariesOnSignals();  // (outputs' temporaries and the work directories go with the process)
    o.fingerprint = fingerprintOf(argc, argv);
    // Outputs are checked and their temporaries created before the runs.
    if (!o.png_path.empty())
    {
      png = std::make_unique<SafeOutput>("--png", o.png_path, std::vector<std::string>{o.config_path});
      chart_script = helperBesideExecutable("frf_chart.py");
    }
    if (!o.csv_path.empty() && o.csv_path != "-")
    {
      if (!o.png_path.empty() && (o.png_path == o.csv_path || sameFile(o.png_path, o.csv_path)))
      {
        throw ConfigError("--csv: '" + o.csv_path + "' is also the --png file");
      }
      csv = std::make_unique<SafeOutput>("--csv", o.csv_path, std::vector<std::string>{o.config_path});
    }
    // Every point's settings checked before any runs (a frequency beyond the sample rate, a channel the drive
    // cannot take), by the measurement's own rule.
    for (double w : o.frequencies)
    {
      frfSampling(o.config, o.settings, w);
    }
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_frf: error: " << e.what() << "\n";
    return 2;
  }
  if (o.dry_run)
  {
    return 0;  // (the outputs' temporaries are removed unwritten)
  }
  try
  {
    if (o.excitation != "sine")
    {
      return runBroadband(o, csv.get(), png.get(), chart_script);
    }
    const std::vector<Row> rows = measureAll(o);
    for (const Row& r : rows)  // (each stopped point on one line; its row is written without figures)
    {
      if (!r.stopped.empty())
      {
        std::cerr << "backlash_frf: point A = " << r.point.amplitude << ", w = " << r.point.requested_frequency
                  << " rad/s stopped, no figures: " << r.stopped << "\n";
      }
    }
    if (o.shard_n > 1 || o.shard_k > 1)
    {
      csv->stream() << partLine(o.shard_k, o.shard_n, o.amplitudes.size() * o.frequencies.size(), o.fingerprint)
                    << "\n";
    }
    if (csv)
    {
      writeCsv(csv->stream(), rows, o.linear);
      csv->commit();
      std::cerr << "backlash_frf: wrote " << o.csv_path << "\n";
      if (o.shard_n > 1)
      {
        return 0;  // a part file only
      }
    }
    if (png)
    {
      drawChart(o, rows, chart_script, *png);
    }
    if (o.csv_path == "-")
    {
      writeCsv(std::cout, rows, o.linear);
    }
    else if (o.json)
    {
      writeJson(o, rows);
    }
    else
    {
      writeText(o, rows);
    }
    flushStdout();
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_frf: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
