// backlash_servo.core — the Python API: a thin adapter over the same library the command-line tools use (no physics
// here). run() returns what `backlash_sim --json` prints, sweep() the rows of `backlash_sweep`, compare() the
// metrics of `backlash_compare`, and Simulator steps a joint from Python. Configurations are the YAML keys (a dict,
// or a path to a YAML file); errors are Python exceptions carrying the tools' one-line message. The GIL is released
// while the core computes. See docs/python.md.
#include <pybind11/complex.h>
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <unistd.h>
#include <algorithm>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "backlash_servo/config/compare_config.h"
#include "backlash_servo/config/key_values.h"
#include "backlash_servo/config/robot_config.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/drive/drive.h"
#include "backlash_servo/frequency/broadband_response.h"
#include "backlash_servo/frequency/describing_function.h"
#include "backlash_servo/frequency/driven_backlash.h"
#include "backlash_servo/frequency/driven_mesh.h"
#include "backlash_servo/frequency/frequency_response.h"
#include "backlash_servo/frequency/limit_cycle_prediction.h"
#include "backlash_servo/identification/identification.h"
#include "backlash_servo/identification/identify_joint.h"
#include "backlash_servo/model/constants.h"
#include "backlash_servo/model/gear_mesh.h"
#include "backlash_servo/model/param_table.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/step_response.h"
#include "backlash_servo/studies/compare_metrics.h"
#include "backlash_servo/studies/monte_carlo.h"
#include "backlash_servo/studies/run_report.h"
#include "backlash_servo/studies/sweep_csv.h"
#include "backlash_servo/studies/sweep_grid.h"
#include "backlash_servo/studies/sweep_runner.h"

namespace py = pybind11;
using namespace backlash_servo;

namespace
{
/// Ctrl-C while the core computes without the GIL: interrupted() checks Python's signals (taking the GIL) at most
/// every 50 ms of wall time and keeps the error a handler raised (KeyboardInterrupt); the caller stops its work and,
/// with the GIL held again, raiseIfInterrupted() raises that error.
class SignalWatch
{
 public:
  /// Thrown out of a computation that cannot be stopped by returning (runResponse's progress callback).
  struct Interrupted
  {};
  /// Whether a Python signal handler raised, now or before (call without the GIL).
  bool interrupted()
  {
    const auto now = std::chrono::steady_clock::now();
    if (error_ || now - last_ < std::chrono::milliseconds(50))
    {
      return error_ != nullptr;
    }
    last_ = now;
    py::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0)
    {
      error_ = std::make_unique<py::error_already_set>();  // (fetches the pending Python error)
    }
    return error_ != nullptr;
  }
  /// Raises the Python error interrupted() kept, if any (call with the GIL, after the computation).
  void raiseIfInterrupted()
  {
    if (error_)
    {
      throw *error_;
    }
  }

 private:
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
  std::unique_ptr<py::error_already_set> error_;
};

/// A dict with an inline profile (`profile: [{step: …}, …]`) is written as the YAML file it stands for, which the
/// profile loader reads as it reads a config file's `profile:` list; removed when this goes out of scope.
struct InlineYaml
{
  std::string path;
  InlineYaml() = default;
  InlineYaml(const InlineYaml&) = delete;
  InlineYaml& operator=(const InlineYaml&) = delete;
  ~InlineYaml()
  {
    if (!path.empty())
    {
      std::remove(path.c_str());
    }
  }
};

/// `v` as a double: any Python or numpy number (int, float, np.float32, np.int64, anything with __float__ or
/// __index__), not a boolean or text. ConfigError naming `key` otherwise, or when it does not fit a double (10**400).
double numberOf(const std::string& key, const py::handle& v)
{
  const std::string type = py::str(py::type::handle_of(v).attr("__name__"));
  if (py::isinstance<py::str>(v) || py::isinstance<py::bytes>(v) || py::isinstance<py::bool_>(v) ||
      !(py::hasattr(v, "__float__") || py::hasattr(v, "__index__")))
  {
    throw ConfigError(key + ": expected a number (got " + type + ")");
  }
  try
  {
    return py::float_(py::reinterpret_borrow<py::object>(v)).cast<double>();
  }
  catch (const py::error_already_set&)
  {
    throw ConfigError(key + ": the number does not fit a double (got a " + type + " of " +
                      std::to_string(std::string(py::str(v)).size()) + " digits)");
  }
}

/// Whether `v` is a sequence of values for an axis: a list, a tuple, a range or a 1-D numpy array (ConfigError
/// naming `key` for an array of more dimensions).
bool isAxis(const std::string& key, const py::handle& v)
{
  if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v) ||
      py::isinstance(v, py::module_::import("builtins").attr("range")))
  {
    return true;
  }
  if (py::hasattr(v, "ndim") && py::hasattr(v, "shape") && !py::isinstance<py::str>(v))
  {
    if (py::int_(v.attr("ndim")).cast<long>() == 0)
    {
      return false;  // (a numpy scalar)
    }
    if (py::int_(v.attr("ndim")).cast<long>() != 1)
    {
      throw ConfigError(key + ": an axis must be a flat list of numbers (got an array of " +
                        std::string(py::str(v.attr("ndim"))) + " dimensions)");
    }
    return true;
  }
  return false;
}

/// An axis as the flags' text "a,b,c", every value exact (numberOf each).
std::string axisText(const std::string& key, const py::handle& values)
{
  std::string text;
  for (const auto& v : values)
  {
    if (isAxis(key, v))
    {
      throw ConfigError(key + ": an axis must be a flat list of numbers (got a nested list)");
    }
    text += (text.empty() ? "" : ",") + formatNumber(numberOf(key, v));
  }
  return text;
}

/// A dict of YAML keys (numbers, booleans, text; a list of numbers for a sweep axis; a list of segments for an
/// inline profile) or a YAML file path as the key values the tools read. Keys are checked against the parameter
/// table as a config file's are. `inline_yaml` keeps the file of an inline profile while the values are in use.
KeyValues keyValuesOf(const py::object& config, InlineYaml* inline_yaml = nullptr)
{
  KeyValues kv;
  kv.nameKeysAsFlags(false);
  if (py::isinstance<py::dict>(config) && config.cast<py::dict>().contains("profile") &&
      py::isinstance<py::list>(config.cast<py::dict>()["profile"]))
  {
    if (inline_yaml == nullptr)
    {
      throw ConfigError("profile: an inline profile is taken by run(), sweep() and Simulator(), not here");
    }
    char name[] = "/tmp/backlash_servo_profile_XXXXXX";
    const int fd = mkstemp(name);
    if (fd < 0)
    {
      throw std::runtime_error("profile: cannot create a temporary file for the inline profile");
    }
    close(fd);
    inline_yaml->path = name;
    py::dict copy;  // sweep axes as the flags' text ("a,b,c"); the profile as its list of segments
    for (const auto& item : config.cast<py::dict>())
    {
      const std::string key = py::str(item.first);
      const bool axis = key != "profile" && isAxis(key, item.second);
      copy[item.first] =
          axis ? py::object(py::str(axisText(key, item.second))) : py::reinterpret_borrow<py::object>(item.second);
    }
    const std::string text = py::str(py::module_::import("json").attr("dumps")(copy));  // JSON is YAML
    std::FILE* f = std::fopen(name, "w");
    if (f == nullptr || std::fputs(text.c_str(), f) < 0 || std::fclose(f) != 0)
    {
      throw std::runtime_error("profile: cannot write the inline profile's temporary file");
    }
    kv.loadYaml(name);
  }
  else if (py::isinstance<py::str>(config) || py::hasattr(config, "__fspath__"))
  {
    kv.loadYaml(py::str(py::module_::import("os").attr("fspath")(config)).cast<std::string>());
  }
  else if (py::isinstance<py::dict>(config))
  {
    for (const auto& item : config.cast<py::dict>())
    {
      const std::string key = py::str(item.first);
      const py::handle value = item.second;
      if (py::isinstance<py::bool_>(value) || py::isinstance(value, py::module_::import("numpy").attr("bool_")))
      {
        kv.setBoolean(key, py::bool_(py::reinterpret_borrow<py::object>(value)).cast<bool>());
      }
      else if (py::isinstance<py::str>(value))
      {
        kv.set(key, value.cast<std::string>());
      }
      else if (isAxis(key, value))
      {
        kv.set(key, axisText(key, value));  // an axis: "a,b,c" with every value exact
      }
      else if (py::hasattr(value, "__float__") || py::hasattr(value, "__index__"))
      {
        kv.setNumber(key, numberOf(key, value));
      }
      else
      {
        throw ConfigError(key + ": expected a number, a boolean, text or a list of numbers (got " +
                          std::string(py::str(py::type::handle_of(value).attr("__name__"))) + ")");
      }
    }
  }
  else if (!config.is_none())
  {
    throw ConfigError("config: expected a dict of keys or the path of a YAML file");
  }
  requireKnownKeys(
      kv, py::isinstance<py::dict>(config) || config.is_none()
              ? std::string("config")
              : "config file '" + std::string(py::str(py::module_::import("os").attr("fspath")(config))) + "'");
  return kv;
}

RunConfig runConfigOf(const py::object& config)
{
  InlineYaml inline_yaml;  // the profile is read into the RunConfig here
  return runConfigFrom(keyValuesOf(config, &inline_yaml));
}

/// JSON text → Python object (the json module parses what the tools print: bit for bit the same numbers).
py::object parseJson(const std::string& text)
{
  return py::module_::import("json").attr("loads")(text);
}

py::object run(const py::object& config)
{
  RunConfig c = runConfigOf(config);
  c.tracking = true;
  std::ostringstream out;
  SignalWatch watch;
  {
    py::gil_scoped_release release;
    const auto start = std::chrono::steady_clock::now();
    try
    {
      const RunSummary r = runResponse(c, nullptr, 0.0, nullptr, [&](double) {
        if (watch.interrupted())
        {
          throw SignalWatch::Interrupted();
        }
      });
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      writeRunJson(out, c, r, wall);
    }
    catch (const SignalWatch::Interrupted&)
    {}
  }
  watch.raiseIfInterrupted();
  return parseJson(out.str());
}

py::object robot(const std::string& path, double duration, double max_duration)
{
  RobotModel model = loadRobot(path);
  if (!(duration >= 0.0) || !(max_duration >= 0.0) || !std::isfinite(duration) || !std::isfinite(max_duration))
  {
    throw ConfigError("duration and max_duration must be finite and >= 0 s (got " + formatNumber(duration) + ", " +
                      formatNumber(max_duration) + ")");
  }
  const double check_period = robotCheckPeriod(model.joints);
  RobotSimulator sim(model.joints, model.arm.get(), check_period);
  std::ostringstream out;
  SignalWatch watch;
  {
    py::gil_scoped_release release;
    const auto start = std::chrono::steady_clock::now();
    try
    {
      const RobotRunResult r = runRobot(&sim, duration, max_duration, check_period, {}, [&](double) {
        if (watch.interrupted())
        {
          throw SignalWatch::Interrupted();
        }
      });
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      writeRobotRunJson(out, model.arm ? model.arm->robotName() : path, r, wall);
    }
    catch (const SignalWatch::Interrupted&)
    {}
  }
  watch.raiseIfInterrupted();
  return parseJson(out.str());
}

/// The configuration for a frequency-response channel: the torque channels drive the joint in effort mode.
RunConfig frfConfigOf(const py::object& config, FrfChannel channel)
{
  InlineYaml inline_yaml;
  return runConfigFrom(keyValuesOf(config, &inline_yaml),
                       torqueInput(channel) ? ControlMode::Effort : ControlMode::Position);
}

py::dict frequencyResponse(const py::object& config, double amplitude, double frequency, const std::string& channel,
                           double offset, double injection_rate, double tolerance, int max_periods, int harmonics,
                           bool continuous)
{
  FrfSettings s;
  s.continuous = continuous;
  s.channel = frfChannelFrom(channel, "channel");
  s.offset = offset;
  s.injection_rate = injection_rate;
  s.tolerance = tolerance;
  s.max_periods = max_periods;
  s.harmonics = harmonics;
  const RunConfig c = frfConfigOf(config, s.channel);
  FrfPoint p;
  SignalWatch watch;
  {
    py::gil_scoped_release release;
    p = measureFrequencyResponse(c, s, amplitude, frequency, [&]() { return watch.interrupted(); });
  }
  watch.raiseIfInterrupted();
  py::dict d;
  d["amplitude"] = p.amplitude;
  d["frequency"] = p.frequency;
  d["requested_frequency"] = p.requested_frequency;
  d["response"] = p.response;
  d["gain"] = p.gain;
  d["phase"] = p.phase;
  d["periodic_to_count"] = p.periodic_to_count;
  d["count_spread"] = p.count_spread;
  d["distortion"] = p.distortion;
  d["mean"] = p.mean;
  d["peak_to_peak"] = p.peak_to_peak;
  d["periodic"] = p.periodic;
  d["period_multiple"] = p.period_multiple;
  d["periods"] = p.periods;
  d["flank_changes"] = p.flank_changes;
  d["separations"] = p.separations;
  d["samples_per_period"] = p.samples_per_period;
  d["mesh_torque_mean"] = p.mesh_torque_mean;
  d["mesh_torque_min"] = p.mesh_torque_min;
  d["mesh_torque_max"] = p.mesh_torque_max;
  // (the release amplitude is read off the joint without backlash: None for a joint with backlash)
  d["release_amplitude"] =
      c.params.backlash == 0.0 ? py::object(py::float_(releaseAmplitude(p))) : py::object(py::none());
  return d;
}

py::dict broadbandResponse(const py::object& config, double amplitude, const std::string& excitation,
                           const std::string& channel, double offset, double injection_rate, int prbs_order,
                           int prbs_hold, const py::object& chirp, int chirp_samples, int periods, int settle_periods)
{
  BroadbandSettings s;
  s.channel = frfChannelFrom(channel, "channel");
  if (excitation != "prbs" && excitation != "chirp")
  {
    throw InvalidParameterError("excitation", "'" + excitation + "' is not prbs or chirp");
  }
  s.kind = excitation == "prbs" ? BroadbandKind::Prbs : BroadbandKind::Chirp;
  s.offset = offset;
  s.injection_rate = injection_rate;
  s.prbs_order = prbs_order;
  s.prbs_hold = prbs_hold;
  s.chirp_samples = chirp_samples;
  s.periods = periods;
  s.settle_periods = settle_periods;
  const RunConfig c = frfConfigOf(config, s.channel);
  if (s.kind == BroadbandKind::Chirp)
  {
    const double rate = excitationRate(c, s.channel, injection_rate);
    const auto range = chirp.is_none() ? std::pair<double, double>{0.01 * 2.0 * backlash_servo::PI * rate,
                                                                   0.25 * 2.0 * backlash_servo::PI * rate}
                                       : chirp.cast<std::pair<double, double>>();
    s.chirp_low = range.first;
    s.chirp_high = range.second;
  }
  BroadbandResponse r;
  {
    py::gil_scoped_release release;
    r = measureBroadband(c, s, amplitude);
  }
  const std::size_t n = r.lines.size();
  py::array_t<double> frequency(n), coherence(n), power(n);
  py::array_t<std::complex<double>> h1(n);
  for (std::size_t i = 0; i < n; ++i)
  {
    frequency.mutable_at(i) = r.lines[i].frequency;
    h1.mutable_at(i) = r.lines[i].h1;
    coherence.mutable_at(i) = r.lines[i].coherence;
    power.mutable_at(i) = r.lines[i].input_power;
  }
  py::dict d;
  d["frequency"] = frequency;
  d["h1"] = h1;
  d["coherence"] = coherence;
  d["input_power"] = power;
  d["sample_rate"] = r.sample_rate;
  d["samples_per_period"] = r.samples_per_period;
  return d;
}

/// backlash_df's analysis: the classical and numerical DFs' predictions beside the exact cycle.
py::dict predictCycle(const py::object& config)
{
  const RunConfig c = runConfigOf(config);
  LimitCyclePrediction a;
  {
    py::gil_scoped_release release;
    a = predictLimitCycle(c);
  }
  py::dict d;
  d["zeta"] = a.zeta;
  d["natural_frequency"] = a.natural_frequency;
  d["backlash"] = c.params.backlash;
  py::list predictions;
  for (const auto* list : {&a.predictions, &a.numerical})
  {
    for (const HarmonicBalance& h : *list)
    {
      py::dict p;
      p["amplitude"] = h.amplitude;
      p["frequency"] = h.frequency;
      p["stable"] = h.stable;
      p["method"] = list == &a.predictions ? "classical" : "numerical";
      p["amplitude_error"] = a.amplitudeError(h);
      p["frequency_error"] = a.frequencyError(h);
      predictions.append(p);
    }
  }
  d["predictions"] = predictions;
  d["numerical_note"] = a.numerical_note;
  py::dict sim;
  sim["verdict"] = toString(a.simulated.verdict);
  sim["amplitude"] = a.simulated.amplitude;
  sim["peak"] = a.simulated.peak;
  sim["frequency"] = a.simulated.frequency;
  sim["centre"] = a.simulated.centre;
  sim["simulated_time"] = a.simulated.simulated;
  d["simulated"] = sim;
  return d;
}

/// backlash_identify's identification from arrays (time, motor_torque, motor_position, load_position).
py::dict identify(const std::vector<double>& time, const std::vector<double>& motor_torque,
                  const std::vector<double>& motor_position, const std::vector<double>& load_position,
                  double gear_ratio, double contact_band, int smoothing, double still_speed, double load_torque,
                  const std::string& joint_fit, const std::vector<std::string>& keys, int windows,
                  const py::object& prior_config)
{
  // What is known of the joint: the prior's keys (its mesh_stiffness > 0: a compliant mesh), the gear ratio given.
  KeyValues kv;
  InlineYaml inline_yaml;
  if (!prior_config.is_none())
  {
    kv = keyValuesOf(prior_config, &inline_yaml);
  }
  if (std::isfinite(gear_ratio))
  {
    kv.setNumber("gear_ratio", gear_ratio);
  }
  else if (!kv.has("gear_ratio"))
  {
    throw InvalidParameterError("gear_ratio", "must be known: give gear_ratio= or gear_ratio in the prior");
  }
  const IdentificationPrior prior = identificationPriorFrom(kv);
  gear_ratio = prior.params.gear_ratio;
  // The settings as the CLI checks its flags: 0 means "from the recording", a value must be a positive number.
  for (const auto& [key, value, unit] :
       {std::make_tuple("contact_band", contact_band, "rad"), std::make_tuple("still_speed", still_speed, "rad/s")})
  {
    if (!(value >= 0.0 && std::isfinite(value)))
    {
      throw ConfigError(std::string(key) + ": must be 0 (from the recording) or > 0 " + unit + " (got " +
                        formatNumber(value) + ")");
    }
  }
  if (!std::isnan(load_torque))
  {
    param("load_torque").check(load_torque);  // (NaN: unknown)
  }
  Recording r{time, motor_torque, motor_position, load_position};
  IdentificationSettings s;
  s.gear_ratio = gear_ratio;
  s.contact_band = contact_band;
  s.smoothing = smoothing;
  s.still_speed = still_speed;
  s.load_torque_fallback = load_torque;
  IdentifyOptions options;
  options.keys.insert(keys.begin(), keys.end());
  if (joint_fit != "on" && joint_fit != "off" && joint_fit != "auto")
  {
    throw InvalidParameterError("joint_fit", "must be 'on', 'off' or 'auto' (got '" + joint_fit + "')");
  }
  options.joint = joint_fit == "on" ? JointFitMode::On : joint_fit == "off" ? JointFitMode::Off : JointFitMode::Auto;
  options.fit.windows = windows;
  options.stated = prior.stated;
  JointIdentification result;
  {
    py::gil_scoped_release release;
    result = identifyJoint(r, s, prior.params, options);
  }
  py::dict d;
  py::dict reasons;
  for (const IdentifiedParameter& p : result.parameters)
  {
    d[p.key.c_str()] = p.value.value;
    d[(p.key + "_standard_error").c_str()] = p.value.standard_error;
    d[(p.key + "_initial").c_str()] = p.initial.value;
    if (!p.identifiable)
    {
      reasons[p.key.c_str()] = p.reason;
    }
  }
  d["not_identifiable"] = reasons;
  const MeasuredAngles& m = result.measurement;
  py::dict measurement;
  measurement["motor_encoder_resolution"] = m.motor.resolution;
  measurement["motor_noise"] = m.motor.noise;
  measurement["load_encoder_resolution"] = m.load.resolution;
  measurement["load_noise"] = m.load.noise;
  measurement["smoothing"] = m.smoothing;
  measurement["contact_band"] = m.contact_band;
  d["measurement"] = measurement;
  py::list warnings;
  for (const std::string& w : result.warnings)
  {
    warnings.append(w);
  }
  d["warnings"] = warnings;
  d["zero_offset"] = result.initial.zero_offset;
  d["load_torque_given"] = result.initial.load_torque_given;
  d["contact_samples"] = result.initial.contact_samples;
  d["apart_samples"] = result.initial.apart_samples;
  d["joint_fit"] = result.joint_fit;
  if (result.joint_fit)
  {
    py::list fitted, informed;
    for (const FittedParameter& f : result.fit.parameters)
    {
      fitted.append(f.key);
      informed.append(f.informed);
    }
    d["fitted"] = fitted;
    d["informed"] = informed;
    d["correlation"] = result.fit.correlation;
    d["rms_residual"] = result.fit.rms;
    d["start_rms_residual"] = result.fit.start_rms;
  }
  return d;
}

/// A tolerance study's size and seed (SweepGrid::setMonteCarlo); n = 0: a grid sweep.
struct Batch
{
  std::size_t n = 0;
  std::uint64_t seed = 1;
};

/// The points' CSV as `backlash_sweep` writes it (header and rows, in point order): a grid, or a batch of draws.
std::string pointsCsv(const KeyValues& kv, bool thesis, int jobs, double max_duration, bool tracking,
                      const Batch& batch)
{
  SweepGrid grid = thesis ? SweepGrid::thesis() : SweepGrid();
  grid.setTracking(tracking);
  addSweepKeys(kv, &grid);
  if (batch.n > 0)
  {
    grid.setMonteCarlo(batch.n, batch.seed);
  }
  if (kv.has("max_duration"))
  {
    max_duration = kv.number("max_duration");
  }
  param("max_duration").check(max_duration);
  grid.requireValidPoints();  // before any work: one clear message on the first bad point
  const std::size_t n = grid.size();
  const int threads = jobs > 0 ? jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::string csv = grid.header() + "\n";
  std::atomic<bool> stop{false};
  SweepRunResult result;
  {
    py::gil_scoped_release release;
    result = runSweepPoints(
        0, n, threads, [&](std::size_t i) { return evaluateSweepPoint(grid.point(i), max_duration, tracking); },
        [&](std::size_t, const std::string& row) { csv += row + "\n"; }, stop);
  }
  if (!result.failure.empty())
  {
    throw std::runtime_error("sweep: " + result.failure);
  }
  return csv;
}

/// The sweep's CSV as `backlash_sweep` writes it (header and rows, in grid order).
std::string sweepCsv(const py::object& settings, bool thesis, int jobs, double max_duration, bool tracking)
{
  InlineYaml inline_yaml;  // every point reads the profile: kept for the whole sweep
  return pointsCsv(keyValuesOf(settings, &inline_yaml), thesis, jobs, max_duration, tracking, Batch());
}

/// A sweep CSV as columns: numbers as float arrays, the verdict as a list of text.
py::dict columnsOf(const std::string& csv)
{
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> names = splitCsvCells(line);
  std::vector<std::vector<std::string>> cells(names.size());
  while (std::getline(in, line))
  {
    const std::vector<std::string> row = splitCsvCells(line);
    for (std::size_t i = 0; i < names.size() && i < row.size(); ++i)
    {
      cells[i].push_back(row[i]);
    }
  }
  py::dict out;
  for (std::size_t i = 0; i < names.size(); ++i)
  {
    if (names[i] == "verdict")
    {
      out[py::str(names[i])] = cells[i];
      continue;
    }
    py::array_t<double> column(static_cast<py::ssize_t>(cells[i].size()));
    auto v = column.mutable_unchecked<1>();
    for (std::size_t k = 0; k < cells[i].size(); ++k)
    {
      v(static_cast<py::ssize_t>(k)) = cells[i][k].empty() ? NAN : std::stod(cells[i][k]);
    }
    out[py::str(names[i])] = column;
  }
  return out;
}

/// The sweep as columns.
py::dict sweep(const py::object& settings, bool thesis, int jobs, double max_duration, bool tracking)
{
  return columnsOf(sweepCsv(settings, thesis, jobs, max_duration, tracking));
}

/// A distribution from Python: "uniform(a,b)" as text, or a tuple ("uniform", a, b).
std::string distributionText(const std::string& key, const py::handle& v)
{
  if (py::isinstance<py::str>(v))
  {
    return v.cast<std::string>();
  }
  if (py::isinstance<py::tuple>(v) && py::len(v) == 3 && py::isinstance<py::str>(v.cast<py::tuple>()[0]))
  {
    const py::tuple t = v.cast<py::tuple>();
    return t[0].cast<std::string>() + "(" + formatNumber(numberOf(key, t[1])) + "," +
           formatNumber(numberOf(key, t[2])) + ")";
  }
  throw ConfigError(key +
                    ": a distribution is 'uniform(a,b)', 'normal(mean,sigma)', 'lognormal(mu,sigma)' or a "
                    "tuple such as ('uniform', a, b)");
}

/// A tolerance study (`backlash_sweep --monte-carlo N --seed S`): the columns, and the summary under "summary".
py::dict monteCarlo(const py::object& config, const py::dict& draws, long long n, long long seed, int jobs,
                    double max_duration)
{
  if (n < 1 || n > 1000000000LL)
  {
    throw ConfigError("n: a whole number of joints in [1, 1e9] (got " + std::to_string(n) + ")");
  }
  if (seed < 0)
  {
    throw ConfigError("seed: a whole number >= 0 (got " + std::to_string(seed) + ")");
  }
  InlineYaml inline_yaml;
  KeyValues kv = keyValuesOf(config, &inline_yaml);
  std::vector<std::string> drawn;
  for (const auto& item : draws)
  {
    const std::string key = py::str(item.first);
    if (kv.has(key))
    {
      throw ConfigError(key + " is both in config and drawn");
    }
    const std::string text = distributionText(key, item.second);
    parseDistribution(key, text);  // (a malformed one named here, with its key)
    kv.set(key, text);
    drawn.push_back(key);
  }
  if (drawn.empty())
  {
    throw ConfigError("draws: give at least one key a distribution, e.g. {'backlash': 'uniform(0.002,0.006)'}");
  }
  Batch batch;
  batch.n = static_cast<std::size_t>(n);
  batch.seed = static_cast<std::uint64_t>(seed);
  const std::string csv = pointsCsv(kv, false, jobs, max_duration, false, batch);
  py::dict out = columnsOf(csv);
  const MonteCarloSummary s = summarizeBatch(csv, drawn);
  py::dict summary, shares;
  for (const MonteCarloSummary::Share& v : s.verdicts)
  {
    shares[py::str(v.verdict)] = py::make_tuple(v.fraction, v.low, v.high);
  }
  summary["verdicts"] = shares;
  summary["quantile_levels"] = s.quantile_levels;
  summary["peak_to_peak_quantiles"] = s.peak_to_peak_quantiles;
  summary["period_quantiles"] = s.period_quantiles;
  py::list influences;
  for (const KeyInfluence& k : s.influences)
  {
    py::dict d;
    d["key"] = k.key;
    d["rank_correlation"] = k.rank_correlation;
    d["threshold"] = k.threshold;
    d["hunts_above"] = k.above;
    d["accuracy"] = k.accuracy;
    influences.append(d);
  }
  summary["influences"] = influences;
  summary["text"] = summaryText(s);
  out["summary"] = summary;
  return out;
}

/// The workbench: every strategy of the experiment file run with its metrics (as `backlash_compare --json`).
py::list compare(const std::string& path, int jobs)
{
  const CompareConfig config = loadCompareConfig(path);
  StrategyRuns runs;
  {
    py::gil_scoped_release release;
    const int threads = jobs > 0 ? jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    runs = runStrategies(config.strategies, config.sample_rate, threads, false, nullptr);
  }
  for (std::size_t i = 0; i < runs.errors.size(); ++i)
  {
    if (!runs.errors[i].empty())
    {
      throw std::runtime_error(config.strategies[i].name + ": " + runs.errors[i]);
    }
  }
  const std::vector<CompareMetrics>& metrics = runs.metrics;
  py::list out;
  for (const CompareMetrics& m : metrics)
  {
    py::dict d;
    d["name"] = m.name;
    d["verdict"] = m.verdict;
    const std::vector<double> values = metricValues(m);
    const std::vector<std::string>& names = metricNames();
    for (std::size_t i = 0; i < values.size(); ++i)
    {
      d[py::str(names[names.size() - values.size() + i])] =
          std::isnan(values[i]) ? py::object(py::none()) : py::object(py::float_(values[i]));
    }
    d["run_on"] = py::none();
    if (!m.run_on_verdict.empty())
    {
      py::dict on;
      on["verdict"] = m.run_on_verdict;
      on["time"] = m.run_on_time;
      on["stopped_by"] = m.run_on_stopped_by;
      d["run_on"] = on;
    }
    out.append(d);
  }
  return out;
}

py::dict stateDict(const State& s)
{
  py::dict d;
  d["time"] = s.time;
  d["load_position"] = s.load_position;
  d["load_velocity"] = s.load_velocity;
  d["motor_position"] = s.motor_position;
  d["motor_velocity"] = s.motor_velocity;
  d["contact"] = std::string(toString(s.contact));
  return d;
}

/// A joint to step from Python: the configured drive (continuous P law or digital drive) on the configured plant.
class PySimulator
{
 public:
  explicit PySimulator(const py::object& config) : config_(runConfigOf(config)), sim_(makeSimulator(config_)) {}

  /// Advances to t_end [s] in pieces of a natural period (the motion does not depend on how it is cut), checking
  /// for Ctrl-C between them.
  void advance(double t_end)
  {
    SignalWatch watch;
    {
      py::gil_scoped_release release;
      const double piece = 2.0 * 3.14159265358979323846 / sim_.params().naturalFrequency();
      while (sim_.state().time < t_end && !watch.interrupted())
      {
        const double next = sim_.state().time + piece;
        sim_.advanceTo(next > sim_.state().time ? std::min(t_end, next) : t_end);  // (a piece below rounding)
      }
    }
    watch.raiseIfInterrupted();
  }

  /// Samples from now to t_end [s] at `rate` [Hz] (the first sample now): numpy arrays of the state, the gap and
  /// the torques — the columns of `backlash_sim --csv` without its event rows.
  py::dict sample(double t_end, double rate)
  {
    if (!(rate > 0.0 && rate <= 1e6) || !std::isfinite(t_end))
    {
      throw ConfigError("sample: rate must be in (0, 1e6] Hz and t_end finite");
    }
    // The sample times of `backlash_sim --csv`: t₀ + k·(1/rate), the last one at t_end.
    const double t0 = sim_.state().time;
    const double period = 1.0 / rate;
    const double count = t_end >= t0 ? std::ceil((t_end - t0) / period - 1e-9) + 1.0 : 0.0;
    // Each sample holds 9 doubles, then once more in the numpy arrays: 144 bytes.
    constexpr double MAX_SAMPLES = 1e7, BYTES_PER_SAMPLE = 144.0;
    if (count > MAX_SAMPLES)
    {
      char buf[300];
      std::snprintf(buf, sizeof buf,
                    "sample: %.4g samples (%.3g GB) exceed the limit of %.0e samples (%.3g GB): lower the rate or "
                    "sample a shorter stretch at a time",
                    count, count * BYTES_PER_SAMPLE / 1e9, MAX_SAMPLES, MAX_SAMPLES * BYTES_PER_SAMPLE / 1e9);
      throw ConfigError(buf);
    }
    const long n = static_cast<long>(count);
    std::vector<double> cols[9];
    for (std::vector<double>& col : cols)
    {
      col.reserve(static_cast<std::size_t>(n));
    }
    SignalWatch watch;
    {
      py::gil_scoped_release release;
      const GearMesh mesh(sim_.params().gear_ratio, sim_.params().backlash);
      for (long k = 0; k < n && !watch.interrupted(); ++k)
      {
        sim_.advanceTo(std::min(t0 + static_cast<double>(k) * period, t_end));
        sim_.takeSampleDue();  // (the torque applied from this sample on, as the CLI's CSV has it)
        const State& s = sim_.state();
        const double values[9] = {s.time,
                                  s.load_position,
                                  s.load_velocity,
                                  s.motor_position,
                                  s.motor_velocity,
                                  mesh.gap(s.load_position, s.motor_position),
                                  sim_.meshTorque(),
                                  sim_.motorTorque(),
                                  static_cast<double>(s.contact == Contact::Forward    ? 1
                                                      : s.contact == Contact::Backward ? -1
                                                                                       : 0)};
        for (int c = 0; c < 9; ++c)
        {
          cols[c].push_back(values[c]);
        }
      }
    }
    watch.raiseIfInterrupted();
    static const char* names[9] = {"time", "load_position", "load_velocity", "motor_position", "motor_velocity",
                                   "gap",  "mesh_torque",   "motor_torque",  "contact"};
    py::dict out;
    for (int c = 0; c < 9; ++c)
    {
      out[names[c]] = py::array_t<double>(static_cast<py::ssize_t>(cols[c].size()), cols[c].data());
    }
    return out;
  }

  void setCommand(double command)
  {
    param("command").check(command);
    sim_.setCommand(command);
  }

  void setMotorTorque(double torque)
  {
    param("motor_effort").check(torque);  // finite and inside the envelope, as the node's motor_effort topic
    sim_.setMotorTorque(torque);
  }
  void setLoadTorqueWave(double amplitude, double frequency, double phase)
  {
    sim_.setLoadTorqueWave(Sinusoid{amplitude, frequency, phase, 0.0});
  }

  /// Live changes, as the node applies them: plant keys at once; drive keys retune a digital drive without a bump
  /// (or start a fresh drive for a new law). Other keys are refused.
  void set(const py::dict& changes)
  {
    const KeyValues kv = keyValuesOf(changes);
    bool drive_changed = false;
    for (const auto& [key, text] : kv.keys())
    {
      const ParamSection section = param(key).section;
      if (section != ParamSection::Servo && section != ParamSection::Drive)
      {
        throw ConfigError(key + ": not a plant or drive key (set it when building the Simulator)");
      }
      drive_changed = drive_changed || section == ParamSection::Drive;
    }
    ServoParams p = sim_.params();
    updateServoKeys(kv, &p);
    DriveParams d = config_.drive;
    readDriveKeys(kv, true, &d);
    p.validate();
    d.validate();
    sim_.setParams(p);
    config_.params = p;
    if (drive_changed && !sim_.retuneDrive(d))
    {
      sim_.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, command(), sim_.state().time));
    }
    config_.drive = d;
  }

  double command() const
  {
    const auto* sampled = dynamic_cast<const SampledDrive*>(&sim_.drive());
    return sampled ? sampled->command() : config_.command;
  }

  py::dict state() const { return stateDict(sim_.state()); }
  double time() const { return sim_.state().time; }
  double motorTorque() const { return sim_.motorTorque(); }
  double meshTorque() const { return sim_.meshTorque(); }
  double gap() const { return sim_.gap(); }
  unsigned long long impacts() const { return sim_.impactCount(); }

 private:
  RunConfig config_;
  Simulator sim_;
};
}  // namespace

/// Runs, sweeps and the workbench.
void bindStudies(py::module_& m)
{
  m.def("run", &run, py::arg("config") = py::none(),
        "One run until its verdict is settled (or for `duration` [s]): the dict `backlash_sim --json` prints.");
  m.def("robot", &robot, py::arg("path"), py::kw_only(), py::arg("duration") = 0.0, py::arg("max_duration") = 0.0,
        "An arm's robot file (joints:, urdf:; docs/robot.md) run as `backlash_sim --config PATH --json` runs it: every "
        "joint in one simulated time for `duration` [s] (0: until every verdict is settled, at most `max_duration`), "
        "a verdict per joint.");
  m.def("sweep", &sweep, py::arg("settings") = py::none(), py::kw_only(), py::arg("thesis") = false,
        py::arg("jobs") = 0, py::arg("max_duration") = 0.0, py::arg("tracking") = false,
        "A parameter study as `backlash_sweep` runs it: keys given a list (or 'a:b:n', 'log:a:b:n') are axes, the "
        "others shared settings; thesis=True starts from the 1961 grid; tracking=True adds the tracking figures "
        "(--tracking). Returns the CSV's columns (numpy arrays; `verdict` a list).");
  m.def("sweep_csv", &sweepCsv, py::arg("settings") = py::none(), py::kw_only(), py::arg("thesis") = false,
        py::arg("jobs") = 0, py::arg("max_duration") = 0.0, py::arg("tracking") = false,
        "The same sweep as `backlash_sweep`'s CSV text.");
  m.def("monte_carlo", &monteCarlo, py::arg("config"), py::arg("draws"), py::arg("n"), py::arg("seed") = 1,
        py::kw_only(), py::arg("jobs") = 0, py::arg("max_duration") = 0.0,
        "A tolerance study as `backlash_sweep --monte-carlo N --seed S` runs it: config's keys shared, each key of "
        "`draws` drawn per joint from its distribution ('uniform(a,b)', 'normal(mean,sigma)', 'lognormal(mu,sigma)' "
        "or a tuple ('uniform', a, b); truncated to the key's range). Returns the CSV's columns (numpy arrays; "
        "`verdict` a list) and `summary`: verdict fractions with 95 % intervals, quantiles of the hunting joints' "
        "peak to peak [rad] and period [s], each drawn key's rank correlation with hunting and best split, the text.");
  m.def("compare", &compare, py::arg("path"), py::kw_only(), py::arg("jobs") = 0,
        "The compensation workbench (`backlash_compare --config PATH`): one dict of metrics per strategy.");
}

/// Describing functions, the driven elements and frequency responses.
void bindFrequency(py::module_& m)
{
  m.def("backlash_df", &backlashDescribingFunction, py::arg("amplitude"), py::arg("backlash"),
        "The classical describing function of backlash as hysteresis (complex) at input amplitude A [rad] about its "
        "centre for a full backlash Δ [rad]; 0 for A ≤ Δ/2 (docs/describing_function.md).");
  m.def("dead_zone_df", &deadZoneDescribingFunction, py::arg("amplitude"), py::arg("half_width"),
        "The describing function of a unit-slope dead zone of half-width δ [rad] at input amplitude A [rad].");
  m.def("limit_cycle_prediction", &predictCycle, py::arg("config") = py::none(),
        "backlash_df's analysis of a configuration (a dict or a YAML path; the continuous P law or a digital P, PID "
        "or cascade drive on the load or the motor, rigid teeth or a compliant mesh): the classical and "
        "the real element's numerical describing functions' predictions [{amplitude [rad], frequency [rad/s], stable, "
        "method ('classical' | 'numerical'), amplitude_error, frequency_error}], numerical_note, beside the exact "
        "cycle {verdict, amplitude, peak, frequency, centre, simulated_time} (docs/describing_function.md).");
  m.def(
      "driven_backlash",
      [](const py::object& config, double amplitude, double frequency) {
        const DrivenBacklash e = drivenElement(runConfigOf(config).params, amplitude, frequency);
        py::dict d;
        d["position"] = e.position;
        d["torque"] = e.torque;
        d["periodic"] = e.periodic;
        d["periods"] = e.periods;
        d["impacts"] = e.impacts;
        return d;
      },
      py::arg("config") = py::none(), py::kw_only(), py::arg("amplitude"), py::arg("frequency"),
      "The real backlash element of a configuration (its load, backlash and restitution) driven by ρθ_m = A sin ωt "
      "(amplitude [rad], frequency ω [rad/s]): its describing functions from the exact periodic steady state — "
      "position N_θ [-] and torque N_T [N·m/rad] (complex), periodic, periods, impacts a period "
      "(docs/describing_function.md).");
  m.def(
      "harmonic_balance",
      [](const py::function& g, double backlash, double omega_lo, double omega_hi, int points) {
        // G(jω) as the user's callable gives it: a complex number (or a real one), finite; ConfigError naming g,
        // the frequency and what it returned otherwise.
        const auto transfer = [&g](double omega) {
          const py::object value = g(omega);
          std::complex<double> z(NAN, NAN);
          if (PyComplex_Check(value.ptr()) || PyFloat_Check(value.ptr()) || PyLong_Check(value.ptr()) ||
              py::hasattr(value, "__complex__"))
          {
            z = value.cast<std::complex<double>>();
          }
          if (!std::isfinite(z.real()) || !std::isfinite(z.imag()))
          {
            std::string shown = py::repr(value).cast<std::string>();
            if (shown.size() > 60)
            {
              shown = shown.substr(0, 57) + "...";
            }
            throw ConfigError("g: must return a finite complex G(jω) (got " + shown + " at ω = " + formatNumber(omega) +
                              " rad/s)");
          }
          return z;
        };
        py::list out;
        for (const HarmonicBalance& h : backlashHarmonicBalance(transfer, backlash, omega_lo, omega_hi, points))
        {
          py::dict d;
          d["amplitude"] = h.amplitude;
          d["frequency"] = h.frequency;
          d["stable"] = h.stable;
          out.append(d);
        }
        return out;
      },
      py::arg("g"), py::arg("backlash"), py::arg("omega_lo"), py::arg("omega_hi"), py::arg("points") = 2000,
      "The solutions of G(jω)·N(A) = −1 for the classical backlash DF with ω in [omega_lo, omega_hi] [rad/s]: g is "
      "a callable ω → complex G(jω) (from the element's output back to its input). A list of dicts amplitude [rad], "
      "frequency [rad/s], stable (Loeb), in order of frequency.");
  m.def("frequency_response", &frequencyResponse, py::arg("config") = py::none(), py::kw_only(), py::arg("amplitude"),
        py::arg("frequency"), py::arg("channel") = "command:load_position", py::arg("offset") = 0.0,
        py::arg("injection_rate") = 0.0, py::arg("tolerance") = 1e-8, py::arg("max_periods") = 0,
        py::arg("harmonics") = 10, py::arg("continuous") = false,
        "One stepped-sine point as `backlash_frf` measures it: amplitude [rad or N·m] at frequency [rad/s] on the "
        "channel; a dict with the frequency used, the complex response, gain, phase [rad], distortion, periodic, "
        "flank_changes, … (docs/frequency_response.md). continuous=True: the torque's sine itself (not on rigid "
        "teeth with dry friction); the command takes the sine itself under the continuous law.");
}

/// Identification from a recording.
void bindIdentification(py::module_& m)
{
  m.def("identify", &identify, py::arg("time"), py::arg("motor_torque"), py::arg("motor_position"),
        py::arg("load_position"), py::kw_only(), py::arg("gear_ratio") = NAN, py::arg("contact_band") = 0.0,
        py::arg("smoothing") = 0, py::arg("still_speed") = 0.0, py::arg("load_torque") = NAN,
        py::arg("joint_fit") = "auto", py::arg("keys") = std::vector<std::string>{}, py::arg("windows") = 40,
        py::arg("prior") = py::none(),
        "backlash_identify's identification from a recording given as arrays (SI; the torque held from each sample "
        "to the next): a dict of each parameter, its `_standard_error` and `_initial` estimate, `zero_offset`, sample "
        "counts and, when the joint fit ran, `fitted` (its keys), `informed`, `correlation` (a matrix in that order), "
        "`rms_residual` [rad] (docs/identification.md). load_torque: used only when the contact motion goes one way; "
        "joint_fit: 'auto', 'on' or 'off'; keys: what is estimated (default all that describe the joint); prior: what "
        "is known (a dict of keys or a YAML path, like Simulator's config; mesh_stiffness > 0 fits a compliant mesh); "
        "gear_ratio: required unless the prior gives it.");
  m.def("broadband_response", &broadbandResponse, py::arg("config") = py::none(), py::kw_only(), py::arg("amplitude"),
        py::arg("excitation") = "prbs", py::arg("channel") = "command:load_position", py::arg("offset") = 0.0,
        py::arg("injection_rate") = 0.0, py::arg("prbs_order") = 10, py::arg("prbs_hold") = 1,
        py::arg("chirp") = py::none(), py::arg("chirp_samples") = 4096, py::arg("periods") = 8,
        py::arg("settle_periods") = 0,
        "The H1 estimate and coherence of a PRBS or chirp excitation (`backlash_frf --excitation`): numpy arrays "
        "frequency [rad/s], h1 (complex), coherence, input_power; chirp = (low, high) [rad/s].");
}

/// The Simulator stepped from Python.
void bindSimulator(py::module_& m)
{
  py::class_<PySimulator>(m, "Simulator", "A joint stepped from Python (the configured plant and drive).")
      .def(py::init<const py::object&>(), py::arg("config") = py::none())
      .def("advance", &PySimulator::advance, py::arg("t_end"), "Advances exactly to t_end [s].")
      .def("sample", &PySimulator::sample, py::arg("t_end"), py::arg("rate") = 100.0,
           "Samples from now to t_end [s] at rate [Hz]: numpy arrays time, load_position, load_velocity, "
           "motor_position, motor_velocity, gap [rad, rad/s], mesh_torque, motor_torque [N·m], contact (+1 forward, "
           "−1 backward, 0 apart).")
      .def("set_command", &PySimulator::setCommand, py::arg("command"), "A new set-point θ_R [rad] from now on.")
      .def("set_motor_torque", &PySimulator::setMotorTorque, py::arg("torque"),
           "Effort mode: the motor torque T_m [N·m] from now on (the drive's loop off), e.g. a recorded torque "
           "replayed sample by sample.")
      .def("set_load_torque_wave", &PySimulator::setLoadTorqueWave, py::arg("amplitude"), py::arg("frequency"),
           py::arg("phase") = 0.0,
           "A sine torque on the load from now on, added to load_torque: B sin(ωt + φ) [N·m], t the simulated time "
           "[s], ω [rad/s], φ [rad] — exact (amplitude 0: none).")
      .def("set", &PySimulator::set, py::arg("changes"),
           "Live changes of plant and drive keys (a dict), applied now as the node applies them.")
      .def_property_readonly("state", &PySimulator::state,
                             "The state: time [s], positions [rad], velocities "
                             "[rad/s], contact.")
      .def_property_readonly("time", &PySimulator::time, "Simulated time [s].")
      .def_property_readonly("motor_torque", &PySimulator::motorTorque, "T_m [N·m].")
      .def_property_readonly("mesh_torque", &PySimulator::meshTorque, "Mesh torque on the load [N·m].")
      .def_property_readonly("gap", &PySimulator::gap, "g = θ_c − ρθ_m [rad].")
      .def_property_readonly("impacts", &PySimulator::impacts, "Impacts so far.");
}

PYBIND11_MODULE(core, m)
{
  m.doc() =
      "backlash_servo.core: the exact backlash servo simulator from Python. Configurations are the YAML keys of the "
      "command-line tools and the node (a dict, or the path of a YAML file), in SI units; see docs/python.md.";
  // pybind11's numpy bindings keep C++ function-local statics (the numpy C API table, the dtypes) whose first use
  // imports numpy: first made by two threads at once, one waits on the static holding the GIL while the other's
  // import waits for the GIL — a deadlock. They are made here, while the import holds the GIL for this thread alone.
  py::module_::import("numpy");
  (void)py::array_t<double>(0);
  (void)py::array_t<std::complex<double>>(0);
  py::register_exception<ConfigError>(m, "ConfigError", PyExc_ValueError);
  py::register_exception<InvalidParameterError>(m, "InvalidParameterError", PyExc_ValueError);
  bindStudies(m);
  bindFrequency(m);
  bindIdentification(m);
  bindSimulator(m);
}
