// backlash_identify: the joint's parameters from a recording of its own motion (initial estimates by linear least
// squares on the contact and apart phases, then the joint fit with the simulator as the model). See
// docs/identification.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>
#include <variant>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/files/json_writer.h"
#include "backlash_servo/files/run_program.h"
#include "backlash_servo/files/safe_output.h"
#include "backlash_servo/identification/experiment_design.h"
#include "backlash_servo/identification/identification.h"
#include "backlash_servo/identification/identify_joint.h"
#include "backlash_servo/identification/replay_windows.h"
#include "backlash_servo/model/param_table.h"
#include "progress.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_identify --data FILE.csv --gear-ratio RHO | --config PRIOR.yaml [--fit KEY,...]
                         [--contact-band RAD] [--smoothing R] [--still-speed W] [--windows N] [--window S]
                         [--max-evaluations N] [--joint-fit on|off|auto] [--json] [--output MODEL.yaml]
                         [--png FILE.png]
       backlash_identify --experiment --config PRIOR.yaml [--duration S] [--travel RAD] [--dither RAD[,HZ]]
                         --output PROFILE.yaml
Estimates the joint's backlash, inertias, viscous, Coulomb and static friction, load torque and restitution from a
recording of its own motion. The angles' count grids and noise are recognised from the data. First from the data
alone: the backlash from the gap theta_c - rho*theta_m, the rest by linear least squares on the phases where the teeth
are in contact and where they are apart (on measured angles the equations integrated over each stretch), the
restitution by replaying windows around impacts, the static friction from the rests. A prior with mesh_stiffness > 0 says the
mesh is compliant: its stiffness and damping are estimated instead of the restitution (the bodies from the torque
balance of the whole joint, the mesh from the torque it passes to the load). Then together (the joint fit): the exact
simulator replays windows of the recording, each restarted from the measured state, and a least-squares search
(Levenberg-Marquardt) matches both angles; each estimate gets a standard error and its largest correlation with
another. FILE.csv has the header time,motor_torque,motor_position,load_position (SI: s, N*m, rad on each body's
own shaft; other columns are ignored; rows with an `event` are skipped, so backlash_sim's --csv is a recording),
uniform time steps; the motor torque is the one applied from each sample to the next. FILE.bag is converted by
backlash_bag_report --recording. The prior is what is known: the gear ratio is required (a flag or the prior YAML),
anything else optional (the encoders' resolutions need no drive); a parameter the recording does not inform is
reported not identifiable, with the reason.
--output writes the prior with the estimates in place: a YAML every tool and the node accept.
--experiment writes instead a command profile that informs the estimates (sines at three speeds, each reversal
across the backlash), designed from the prior's gain, inertias and backlash and checked on the prior's joint (its
drive, load torque and friction simulated and read back), for the node or backlash_sim to run.
)";

struct Options
{
  std::string data_path, config_path, output_path, png_path;
  bool experiment = false;
  std::set<std::string> fit;  // the estimates written into the model
  double duration = 60.0, travel = 0.0;
  double dither_amplitude = 0.0, dither_frequency = 0.0;  // [rad], [Hz]
  double motor_counts = 0.0, load_counts = 0.0;  // the prior's encoder resolutions [counts/rev] (no --contact-band)
  std::string joint_states_topic, motor_joint, load_joint;  // a bag's JointState topic and joint names
  RunConfig prior_config;
  KeyValues prior;
  IdentificationPrior known;  // the prior as identification reads it
  double gear_ratio = 0.0, contact_band = 0.0, still_speed = 0.0;
  int smoothing = 0;
  bool json = false;
  std::string joint_fit = "auto";  // on | off | auto
  JointFitSettings joint;
};

/// The prior's keys: the joint's, the drive's, the initial state's and the run's, but `duration`, which is the
/// experiment's length here (--experiment --duration) and no part of a model.
std::vector<std::string> identifyKeys()
{
  std::vector<std::string> keys =
      keysOfSections({ParamSection::Servo, ParamSection::Drive, ParamSection::Initial, ParamSection::Run});
  keys.erase(std::remove(keys.begin(), keys.end(), "duration"), keys.end());
  return keys;
}

/// The flags: the prior's keys and the tool's options, with their help.
FlagParser identifyFlags()
{
  return FlagParser(
      "backlash_identify", HEADER, identifyKeys(),
      {{"config", "PRIOR.yaml", "what is known of the joint (the gear ratio at least); flags override it"},
       {"data", "FILE.csv|FILE.bag",
        "the recording: a CSV time,motor_torque,motor_position,load_position, or a bag (the node's, or any with a "
        "sensor_msgs/JointState topic: see --joint-states)"},
       {"joint_states", "TOPIC",
        "a bag's sensor_msgs/JointState topic carrying both joints and the motor's effort "
        "(default: the node's joint_states)"},
       {"motor_joint", "NAME", "the motor's name in a bag's joint states (default motor_joint)"},
       {"load_joint", "NAME", "the load's name in a bag's joint states (default load_joint)"},
       {"contact_band", "RAD",
        "a sample is in contact when its gap is this close to a flank [rad] (default: from the angles' count grids "
        "and noise, recognised in the data; 1e-8 of the backlash for exact angles)"},
       {"smoothing", "R",
        "measured angles the older way: every term filtered by the centred mean over 2R+1 samples, twice, and "
        "differentiated (default: the equations integrated, no smoothing of them; the phases read through a filter "
        "chosen from the data)"},
       {"still_speed", "W",
        "samples where the motor turns slower than this [rad/s] are left out (default 1e-6 of its fastest)"},
       {"json", "", "one JSON object on stdout"},
       {"output", "MODEL.yaml", "the prior with the estimated keys replaced (with --experiment: the profile)"},
       {"fit", "KEY[,KEY...]",
        "what is estimated (default all: backlash, motor_inertia, load_inertia, motor_friction, load_friction, "
        "motor_coulomb_friction, load_coulomb_friction, motor_static_friction, load_static_friction, load_torque, "
        "and restitution for rigid teeth or mesh_stiffness, mesh_damping for a compliant mesh); the others keep the "
        "prior's values, in the fit and in the model"},
       {"windows", "N", "the joint fit: how many windows of the recording it replays (default 40)"},
       {"window", "S", "the joint fit: each window's length [s] (default 0.2)"},
       {"max_evaluations", "N", "the joint fit: at most this many replays of all windows (default 600)"},
       {"joint_fit", "on|off|auto",
        "the joint fit after the initial estimates: on = every estimate in --fit; auto (default) = every one on exact "
        "angles; on measured ones (--contact-band given) only backlash and restitution, or the mesh's stiffness and "
        "damping; off = none"},
       {"png", "FILE.png",
        "the recording against the fitted model replayed over the windows: load angle, gap, "
        "residuals"},
       {"experiment", "", "write an excitation (a command profile) to --output instead of identifying"},
       {"duration", "S", "--experiment: its length [s] (default 60)"},
       {"travel", "RAD",
        "--experiment: the command's largest excursion [rad], at least 3 times the backlash (default: 3, 6, 12, 24, "
        "48 times it tried on the prior's joint, the first that informs every estimate kept)"},
       {"dither", "RAD[,HZ]",
        "--experiment: a small fast sine on the command, amplitude RAD (a torque gain*RAD) at HZ (default: 20 times "
        "the "
        "loop's natural frequency, at most an eighth of the controller rate), so that no body sticks at the slow "
        "reversals"}});
}

/// --experiment: the prior, the excitation's length and travel, and a dither.
void readExperiment(const FlagParser& parser, Options* options)
{
  Options& o = *options;
  o.prior_config = runConfigFrom(parser.keys());
  o.duration = parser.optionNumber("duration", 60.0);
  o.travel = parser.given("travel") ? parser.optionNumber("travel", 0.0) : 0.0;  // (0: grown until it informs)
  // The profile's positions are commands: within the command's range, as every tool reads them.
  const ParamRange& positions = param("command").range;
  if (parser.given("travel") && !positions.contains(o.travel))
  {
    throw ConfigError("--travel: " + formatNumber(o.travel) + " rad must be " + positions.describe() +
                      " rad (the command's range)");
  }
  if (parser.given("dither"))
  {
    const std::string text = parser.option("dither");
    const std::size_t comma = text.find(',');
    const double rate = o.prior_config.drive.controller_rate;
    if (!(rate > 0.0))
    {
      throw ConfigError(
          "--dither: the drive must be digital (controller_rate > 0 Hz in the prior): a dither is "
          "sampled");
    }
    const auto number = [&text](const std::string& item) {
      char* end = nullptr;
      const double v = std::strtod(item.c_str(), &end);
      if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(v))
      {
        throw ConfigError("--dither: '" + item + "' is not a number (in '" + text + "'; RAD or RAD,HZ)");
      }
      return v;
    };
    o.dither_amplitude = number(text.substr(0, comma));
    o.dither_frequency =
        comma == std::string::npos
            ? std::min(20.0 * o.prior_config.params.naturalFrequency() / (2.0 * 3.14159265358979323846), rate / 8.0)
            : number(text.substr(comma + 1));
    if (!(o.dither_amplitude > 0.0) || !(o.dither_frequency > 0.0) || o.dither_frequency > rate / 4.0)
    {
      throw ConfigError(
          "--dither: the amplitude must be > 0 rad and the frequency > 0 Hz, at most a quarter of the "
          "controller rate (got '" +
          text + "')");
    }
    if (!positions.contains(o.dither_amplitude))
    {
      throw ConfigError("--dither: " + formatNumber(o.dither_amplitude) + " rad must be " + positions.describe() +
                        " rad (the command's range)");
    }
  }
}

/// The keys to fit and the joint fit's settings (--fit, --joint-fit, --windows, --window, --max-evaluations).
void readFit(const FlagParser& parser, Options* options)
{
  Options& o = *options;
  const std::vector<std::string>& fittable = identifiedKeys();
  if (parser.given("fit"))
  {
    std::stringstream list(parser.option("fit"));
    for (std::string key; std::getline(list, key, ',');)
    {
      if (std::find(fittable.begin(), fittable.end(), key) == fittable.end())
      {
        std::string keys;
        for (const std::string& k : fittable)
        {
          keys += (keys.empty() ? "" : ", ") + k;
        }
        throw ConfigError("--fit: '" + key + "' is not estimated here (" + keys + ")");
      }
      o.fit.insert(key);
    }
  }
  // (none given: every key that describes the prior's joint — identifiedKeysFor)
  if (parser.given("duration") || parser.given("travel") || parser.given("dither"))
  {
    throw ConfigError("--duration, --travel and --dither are for --experiment");
  }
  o.joint_fit = parser.given("joint_fit") ? parser.option("joint_fit") : "auto";
  if (o.joint_fit != "on" && o.joint_fit != "off" && o.joint_fit != "auto")
  {
    throw ConfigError("--joint-fit must be on, off or auto (got '" + o.joint_fit + "')");
  }
  o.joint.keys.assign(o.fit.begin(), o.fit.end());
  const double windows = parser.optionNumber("windows", 40.0),
               evaluations = parser.optionNumber("max_evaluations", 600.0);
  o.joint.window = parser.optionNumber("window", 0.2);
  if (!(windows >= 1.0 && windows <= 100000.0) || windows != std::floor(windows))
  {
    throw ConfigError("--windows must be a whole number in [1, 100000]");
  }
  if (!(evaluations >= 1.0 && evaluations <= 1e7) || evaluations != std::floor(evaluations))
  {
    throw ConfigError("--max-evaluations must be a whole number in [1, 10000000]");
  }
  if (!(o.joint.window > 0.0 && std::isfinite(o.joint.window)))
  {
    throw ConfigError("--window must be > 0 s");
  }
  o.joint.windows = static_cast<int>(windows);
  o.joint.max_evaluations = static_cast<int>(evaluations);
  if (o.joint_fit == "off" && (parser.given("windows") || parser.given("window") || parser.given("max_evaluations")))
  {
    throw ConfigError("--windows, --window and --max-evaluations set the joint fit, which --joint-fit off skips");
  }
}

Options parse(int argc, char** argv)
{
  FlagParser parser = identifyFlags();
  parser.parse(argc, argv);
  Options o;
  o.config_path = parser.option("config");
  o.data_path = parser.option("data");
  o.joint_states_topic = parser.option("joint_states");
  o.motor_joint = parser.option("motor_joint");
  o.load_joint = parser.option("load_joint");
  const bool bag = o.data_path.size() > 4 && o.data_path.compare(o.data_path.size() - 4, 4, ".bag") == 0;
  if (!bag && (parser.given("joint_states") || parser.given("motor_joint") || parser.given("load_joint")))
  {
    throw ConfigError("--joint-states, --motor-joint and --load-joint read a bag: give --data FILE.bag");
  }
  o.output_path = parser.option("output");
  o.json = parser.given("json");
  o.experiment = parser.given("experiment");
  if (o.experiment)
  {
    if (!o.data_path.empty() || o.output_path.empty() || o.json)
    {
      throw ConfigError("--experiment writes a profile: give --output PROFILE.yaml (and no --data or --json)");
    }
    readExperiment(parser, &o);
    return o;
  }
  readFit(parser, &o);
  o.png_path = parser.option("png");
  if (parser.given("png") && !isPngPath(o.png_path))
  {
    throw ConfigError("--png: '" + o.png_path + "' must end in .png");
  }
  if (parser.given("png") && o.joint_fit == "off")
  {
    throw ConfigError("--png shows the joint fit, which --joint-fit off skips");
  }
  if (o.data_path.empty())
  {
    throw ConfigError("--data FILE.csv is required: the recording to identify the joint from");
  }
  o.prior = parser.keys();
  // What is known: each key in its range; the rest unknown (no defaults, no envelope: the model is checked).
  const IdentificationPrior checked = identificationPriorFrom(o.prior);
  o.known = checked;
  o.gear_ratio = checked.params.gear_ratio;
  o.contact_band = parser.optionNumber("contact_band", 0.0);
  if (parser.given("contact_band") && !(o.contact_band > 0.0))
  {
    throw ConfigError("--contact-band must be > 0 rad");
  }
  if (!parser.given("contact_band"))
  {
    o.motor_counts = checked.motor_encoder_resolution;
    o.load_counts = checked.load_encoder_resolution;
  }
  const double smoothing = parser.optionNumber("smoothing", 0.0);
  if (!(smoothing >= 0.0 && smoothing <= 100000.0) || smoothing != std::floor(smoothing))
  {
    throw ConfigError("--smoothing must be a whole number of samples in [0, 100000]");
  }
  o.smoothing = static_cast<int>(smoothing);
  o.still_speed = parser.optionNumber("still_speed", 0.0);
  if (parser.given("still_speed") && !(o.still_speed > 0.0))
  {
    throw ConfigError("--still-speed must be > 0 rad/s");
  }
  return o;
}

/// A cell as an error message shows it: at most 40 characters, control characters (a NUL byte) as '?'.
std::string shown(const std::string& cell)
{
  std::string out = cell.substr(0, 40);
  for (char& ch : out)
  {
    ch = static_cast<unsigned char>(ch) < 0x20 ? '?' : ch;
  }
  return cell.size() > 40 ? out + "… (" + std::to_string(cell.size()) + " characters)" : out;
}

/// The CSV's four columns (by header name; others ignored). Errors name the row and the column.
Recording readRecording(const std::string& path)
{
  const std::string text = readRegularFile("--data", path, std::size_t{1} << 30);
  std::istringstream in(text);
  std::string line;
  const auto next = [&in, &line]() {
    if (!std::getline(in, line))
    {
      return false;
    }
    if (!line.empty() && line.back() == '\r')
    {
      line.pop_back();  // (CRLF line ends)
    }
    return true;
  };
  if (!next())
  {
    throw ConfigError("--data: '" + path + "' is empty");
  }
  if (line.compare(0, 3, "\xEF\xBB\xBF") == 0)
  {
    line.erase(0, 3);  // (a UTF-8 byte order mark, as spreadsheet programs write it)
  }
  const std::vector<std::string> header = splitCsvCells(line);
  std::map<std::string, std::size_t> column;
  for (std::size_t i = 0; i < header.size(); ++i)
  {
    if (!column.emplace(header[i], i).second)
    {
      throw ConfigError("--data: '" + path + "' has the column '" + shown(header[i]) + "' twice (columns " +
                        std::to_string(column[header[i]] + 1) + " and " + std::to_string(i + 1) +
                        "): which one is meant?");
    }
  }
  const std::vector<std::string> need = {"time", "motor_torque", "motor_position", "load_position"};
  for (const std::string& name : need)
  {
    if (column.count(name) == 0)
    {
      throw ConfigError("--data: '" + path + "' has no column '" + name +
                        "' (the header needs time,motor_torque,motor_position,load_position)");
    }
  }
  // backlash_sim's CSV has the same columns and an `event` column: its event rows (not samples) are skipped.
  const bool events = column.count("event") != 0;
  const std::size_t event_column = events ? column["event"] : 0;
  Recording r;
  std::vector<double>* into[4] = {&r.time, &r.motor_torque, &r.motor_position, &r.load_position};
  std::size_t row = 1;
  while (next())
  {
    ++row;
    if (line.empty())
    {
      continue;
    }
    const std::vector<std::string> cells = splitCsvCells(line);
    if (events && event_column < cells.size() && !cells[event_column].empty())
    {
      continue;
    }
    for (std::size_t c = 0; c < need.size(); ++c)
    {
      const std::size_t i = column[need[c]];
      char* end = nullptr;
      const double v = i < cells.size() ? std::strtod(cells[i].c_str(), &end) : NAN;
      // (the whole cell must be the number: "0.5\0abc" is not 0.5)
      if (i >= cells.size() || end == cells[i].c_str() || end != cells[i].c_str() + cells[i].size() ||
          !std::isfinite(v))
      {
        throw ConfigError("--data: row " + std::to_string(row) + ", column " + need[c] + ": '" +
                          shown(i < cells.size() ? cells[i] : std::string()) + "' is not a finite number");
      }
      into[c]->push_back(v);
    }
  }
  return r;
}

std::string number(double v, int digits = 9)
{
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

std::string unitOf(const std::string& key)
{
  const ParamSpec* spec = findParam(key);
  return spec ? spec->unit : "";
}

/// The recording and the fitted model replayed over the fit's windows, to a private directory, drawn there by
/// identify_chart.py (run without a shell), then moved into place through the safe-write path.
void drawChart(const Recording& data, double rho, const ReplayWindows& windows, const JointFit& fit,
               const std::string& script, SafeOutput& png)
{
  std::vector<double> motor, load;
  windows.simulate(fit.params, &motor, &load, &fit.anchor_corrections);
  TemporaryDirectory dir("backlash_identify");
  {
    std::ofstream csv(dir.file("replay.csv"));
    csv.precision(12);
    csv << "time,motor,load,gap,motor_fit,load_fit,gap_fit\n";
    for (std::size_t k = 0; k < data.time.size(); ++k)
    {
      csv << data.time[k] << "," << rho * data.motor_position[k] << "," << data.load_position[k] << ","
          << data.load_position[k] - rho * data.motor_position[k] << ",";
      if (std::isfinite(load[k]))
      {
        csv << rho * motor[k] << "," << load[k] << "," << load[k] - rho * motor[k];
      }
      else
      {
        csv << ",,";
      }
      csv << "\n";
    }
    if (!csv.flush())
    {
      throw std::runtime_error("--png: writing the chart data to '" + dir.path() + "' failed (disk full?)");
    }
  }
  const std::string tmp = dir.file("chart.png");
  runChartScript(script, dir.path(), tmp);
  copyFileInto(tmp, png);
  std::cerr << "backlash_identify: wrote " << png.path() << "\n";
}

}  // namespace

/// --experiment: the excitation as a command profile (YAML segments) in `out`.
void writeExperiment(const Options& o, std::ostream& out)
{
  ExperimentRequest request;
  request.duration = o.duration;
  request.travel = o.travel;
  request.dither_amplitude = o.dither_amplitude;
  request.dither_frequency = o.dither_frequency;
  std::cerr << "backlash_identify: checking the experiment on the prior's joint (its guesses, drive and load torque)\n";
  const CheckedExperiment design = designExperiment(
      o.prior_config, request, [](const std::string& line) { std::cerr << "backlash_identify:   " << line << "\n"; });
  const std::vector<ProfileSegment>& segments = design.segments;
  out.precision(10);
  out << "# backlash_identify --experiment: " << o.duration << " s of command about its start, for a joint with "
      << "backlash " << o.prior_config.params.backlash << " rad and loop natural frequency "
      << o.prior_config.params.naturalFrequency() << " rad/s.\n"
      << "# The slow sine: contact motion both ways (friction, load torque); the faster ones: accelerations (the "
         "inertias);\n# every reversal crosses the backlash (the motor alone while the teeth are apart). SI "
         "units: s, rad, Hz.\n";
  out << "# Checked on the prior's joint (simulated, read back by the initial estimates): travel " << design.travel
      << " rad, " << design.impacts << " impacts; ";
  if (design.uninformed.empty())
  {
    out << "every body parameter given back within " << 100.0 * request.tolerance << " %.\n";
  }
  else
  {
    out << "not given back within " << 100.0 * request.tolerance << " %:\n";
    for (const auto& [key, why] : design.uninformed)
    {
      out << "#   " << key << ": " << why << "\n";
      std::cerr << "backlash_identify: warning: the experiment does not inform " << key << " on the prior's joint ("
                << why << ")" << (o.travel > 0.0 ? "; a larger --travel may" : "") << "\n";
    }
  }
  if (o.dither_amplitude > 0.0)
  {
    out << "# A dither on every sine: " << o.dither_amplitude << " rad at " << o.dither_frequency << " Hz (a torque of "
        << o.prior_config.params.gain * o.dither_amplitude
        << " N*m under the gain), so that no body sticks at the slow reversals.\n";
  }
  for (const ProfileSegment& seg : segments)
  {
    out << "- sine: {time: " << seg.time << ", amplitude: " << seg.amplitude << ", frequency: " << seg.frequency
        << ", duration: " << seg.duration;
    if (seg.dither_amplitude > 0.0)
    {
      out << ", dither_amplitude: " << seg.dither_amplitude << ", dither_frequency: " << seg.dither_frequency;
    }
    out << "}\n";
  }
}

/// The recording of --data: a CSV as it is, a bag's joint_states converted by backlash_bag_report --recording (run
/// without a shell) into a private directory, then read as a CSV.
Recording readData(const Options& o)
{
  if (o.data_path.size() <= 4 || o.data_path.compare(o.data_path.size() - 4, 4, ".bag") != 0)
  {
    return readRecording(o.data_path);
  }
  TemporaryDirectory dir("backlash_identify_bag");
  const std::string csv = dir.file("recording.csv");
  std::vector<std::string> argv = {"/usr/bin/python3", helperBesideExecutable("backlash_bag_report.py"), o.data_path,
                                   "--recording", csv};
  for (const auto& [flag, value] : {std::make_pair(std::string("--joint-states"), o.joint_states_topic),
                                    std::make_pair(std::string("--motor-joint"), o.motor_joint),
                                    std::make_pair(std::string("--load-joint"), o.load_joint)})
  {
    if (!value.empty())
    {
      argv.insert(argv.end(), {flag, value});
    }
  }
  if (o.joint_states_topic.empty())
  {
    argv.push_back("--json");  // (its report goes to stderr as one line: only the recording is wanted)
  }
  const int status = runProgram(argv);
  if (status != 0)
  {
    throw ConfigError("--data: backlash_bag_report could not convert " + o.data_path + " (exit status " +
                      std::to_string(status) + "; its message is above)");
  }
  return readRecording(csv);
}

/// How the recording is read, from the options and the prior.
IdentificationSettings settingsFrom(const Options& o)
{
  IdentificationSettings s;
  s.gear_ratio = o.gear_ratio;
  s.contact_band = o.contact_band;
  s.smoothing = o.smoothing;
  // Contact one way only (a limit cycle pushed from one side): the prior's load torque (default 0) splits it.
  s.load_torque_fallback = o.prior.has("load_torque") ? o.prior.number("load_torque") : 0.0;
  s.still_speed = o.still_speed;
  s.motor_encoder_resolution = o.motor_counts;
  s.load_encoder_resolution = o.load_counts;
  return s;
}

/// The model file: the prior's keys with the identified ones replaced by the model's values; the keys not identified
/// named in comments.
void writeModel(const Options& o, const JointIdentification& result, std::ostream& out)
{
  const std::vector<IdentifiedParameter>& rows = result.parameters;
  // The prior's keys, the estimated ones replaced by the model's values (and a static level the estimates
  // raised to its Coulomb level).
  KeyValues model = o.prior;
  const auto valueOf = [&result](const std::string& key) {
    return result.model.*std::get<double ServoParams::*>(findParam(key)->field);
  };
  for (const IdentifiedParameter& r : rows)
  {
    if (r.identifiable)
    {
      model.setNumber(r.key, valueOf(r.key));
    }
  }
  for (const char* stat : {"motor_static_friction", "load_static_friction"})
  {
    const bool unknown = std::any_of(rows.begin(), rows.end(),
                                     [stat](const IdentifiedParameter& r) { return r.key == stat && !r.identifiable; });
    // (absent: the table's default, 0; a level not identified is left to the tools' default, the Coulomb level)
    if (!unknown && valueOf(stat) != model.number(stat, 0.0))
    {
      model.setNumber(stat, valueOf(stat));
    }
  }
  // The prior's drive keys stay when they make a drive; else they describe the recording only (encoders
  // without a controller rate) and are kept as comments, so that every tool reads the model.
  bool drive_ok = true;
  try
  {
    DriveParams drive;
    readDriveKeys(model, false, &drive);
    drive.validate(ControlMode::Position);
  }
  catch (const std::exception&)
  {
    drive_ok = false;
  }
  out << "# backlash_identify: the joint estimated from " << o.data_path << " (SI units)\n";
  for (const auto& [key, value] : model.keys())
  {
    const bool recording_only = !drive_ok && param(key).section == ParamSection::Drive;
    out << (recording_only ? "# " : "") << key << ": " << value
        << (recording_only ? "  (the recording's encoder; not a drive without controller_rate)" : "") << "\n";
  }
  for (const IdentifiedParameter& r : rows)
  {
    if (!r.identifiable)
    {
      out << "# " << r.key << ": not identified (" << r.reason << ")"
          << (o.known.stated.count(r.key) ? ": the prior's value is kept" : ": give it before simulating") << "\n";
    }
  }
}

/// --json: the estimates, what the recording's angles are, the warnings and the joint fit as one JSON object.
void printJson(const Options& o, const JointIdentification& result)
{
  const InitialEstimates& e = result.initial;
  const std::vector<IdentifiedParameter>& rows = result.parameters;
  const JointFit& fit = result.fit;
  const bool joint = result.joint_fit;
  std::ostringstream out;
  JsonWriter w(out);
  w.beginObject();
  w.beginObject("estimates");
  for (const IdentifiedParameter& r : rows)
  {
    w.beginObject(r.key.c_str());
    w.field("value", r.value.value);
    w.field("standard_error", r.value.standard_error);
    w.field("initial", r.initial.value);
    w.field("initial_standard_error", r.initial.standard_error);
    w.field("identifiable", r.identifiable);
    if (!r.identifiable)
    {
      w.field("reason", r.reason);
    }
    if (r.in_joint_fit)
    {
      w.field("informed", r.informed);
      w.field("largest_correlation", r.largest_correlation);
      w.field("most_correlated_with", r.most_correlated_with);
    }
    w.endObject();
  }
  w.endObject();
  const MeasuredAngles& m = result.measurement;
  w.beginObject("measurement");
  w.field("motor_encoder_resolution", m.motor.resolution);
  w.field("motor_noise", m.motor.noise);
  w.field("load_encoder_resolution", m.load.resolution);
  w.field("load_noise", m.load.noise);
  w.field("smoothing", static_cast<long long>(m.smoothing));
  w.field("contact_band", m.contact_band);
  w.field("from_data", m.from_data);
  w.field("phases_from_load_edges", e.phases_from_edges);
  w.endObject();
  w.beginArray("warnings");
  for (const std::string& warning : result.warnings)
  {
    w.field(nullptr, warning);
  }
  w.endArray();
  w.field("zero_offset", e.zero_offset);
  w.field("load_torque_given", e.load_torque_given);
  w.field("contact_samples", static_cast<long long>(e.contact_samples));
  w.field("apart_samples", static_cast<long long>(e.apart_samples));
  w.field("contact_rms_residual", e.contact_rms_residual);
  w.field("apart_rms_residual", e.apart_rms_residual);
  if (joint)
  {
    w.beginObject("joint_fit");
    w.field("windows", static_cast<long long>(fit.windows));
    w.field("window", o.joint.window);
    w.field("evaluations", static_cast<long long>(fit.evaluations));
    w.field("budget_exhausted", fit.budget_exhausted);
    w.field("start_rms_residual", fit.start_rms);
    w.field("rms_residual", fit.rms);
    w.field("condition", fit.condition);
    w.beginArray("correlation");
    for (Eigen::Index i = 0; i < fit.correlation.rows(); ++i)
    {
      w.beginArray();
      for (Eigen::Index j = 0; j < fit.correlation.cols(); ++j)
      {
        w.field(nullptr, fit.correlation(i, j));
      }
      w.endArray();
    }
    w.endArray();
    w.endObject();
  }
  w.endObject();
  std::cout << out.str() << "\n";
}

/// The text report: what the angles are, the samples each phase gave, the joint fit, a row a parameter.
void printText(const Options& o, const Recording& data, const JointIdentification& result)
{
  const InitialEstimates& e = result.initial;
  const std::vector<IdentifiedParameter>& rows = result.parameters;
  const JointFit& fit = result.fit;
  const bool joint = result.joint_fit;
  std::printf("%s\n", result.measurement.summary().c_str());
  if (e.phases_from_edges)
  {
    std::printf(
        "the gap does not resolve the free play: its flanks read at the load's count edges (the motor's angle "
        "there); flights not resolved\n");
  }
  if (result.model.compliant())
  {
    std::printf(
        "%zu samples: the bodies' torque balance (rms residual %.3g N*m); the mesh pressed at %zu, free at %zu "
        "(rms residual %.3g N*m)\n",
        data.time.size(), e.apart_rms_residual, e.contact_samples, e.apart_samples, e.contact_rms_residual);
  }
  else
  {
    std::printf(
        "%zu samples: %zu in contact, %zu apart used by the initial estimates (rms residual %.3g / %.3g "
        "N*m)\n",
        data.time.size(), e.contact_samples, e.apart_samples, e.contact_rms_residual, e.apart_rms_residual);
  }
  if (joint)
  {
    std::printf("joint fit: %zu windows of %g s, %d replays%s; rms residual %.3g -> %.3g rad; condition %.3g\n",
                fit.windows, o.joint.window, fit.evaluations,
                fit.budget_exhausted ? " (the budget: raise --max-evaluations)" : "", fit.start_rms, fit.rms,
                fit.condition);
  }
  std::printf("%-24s %14s %14s +- %-10s %-10s %s\n", "parameter", "initial", joint ? "fitted" : "estimate", "std error",
              "unit", joint ? "identifiability" : "");
  for (const IdentifiedParameter& r : rows)
  {
    std::string how;
    if (!r.identifiable)
    {
      how = "not identifiable: " + r.reason;
    }
    else if (r.key.find("static") != std::string::npos)
    {
      how = std::isfinite(r.value.standard_error) ? "from the rests (held in the joint fit)"
                                                  : "from the rests: at least this (never seen breaking away)";
    }
    else if (joint && !r.in_joint_fit)
    {
      how = "initial estimate (held in the joint fit)";
    }
    else if (joint && !r.informed)
    {
      how = "not informed by this recording (the start kept)";
    }
    else if (joint && !r.most_correlated_with.empty())
    {
      how = "|corr| " + number(std::round(r.largest_correlation * 100.0) / 100.0) + " with " + r.most_correlated_with;
    }
    std::printf("%-24s %14s %14s +- %-10s %-10s %s\n", r.key.c_str(), number(r.initial.value).c_str(),
                number(r.value.value).c_str(), number(r.value.standard_error, 3).c_str(), unitOf(r.key).c_str(),
                how.c_str());
  }
  std::printf("%-24s %14s %14s    %-10s %-10s %s\n", "zero_offset", "", number(e.zero_offset, 6).c_str(), "", "rad",
              "(the gap the encoders read on the forward flank)");
  std::string kept;
  for (const std::string& key : jointFitKeysFor(result.model))
  {
    if (std::none_of(rows.begin(), rows.end(), [&key](const IdentifiedParameter& r) { return r.key == key; }))
    {
      kept += (kept.empty() ? "" : ", ") + key;
    }
  }
  if (!result.model.compliant())
  {
    kept += std::string(kept.empty() ? "" : ", ") + "a compliant mesh";
  }
  if (!kept.empty())
  {
    std::printf("not estimated (the prior's values are kept): %s\n", kept.c_str());
  }
}

int main(int argc, char** argv)
{
  Options o;
  std::unique_ptr<SafeOutput> output, png;
  std::string chart_script;
  Recording data;
  try
  {
    o = parse(argc, argv);
    removeTemporariesOnSignals();  // (outputs' temporaries and the work directories go with the process)
    if (!o.output_path.empty())
    {
      output =
          std::make_unique<SafeOutput>("--output", o.output_path, std::vector<std::string>{o.config_path, o.data_path});
    }
    if (!o.png_path.empty() && !o.output_path.empty() &&
        (o.png_path == o.output_path || sameFile(o.png_path, o.output_path)))
    {
      throw ConfigError("--png: '" + o.png_path + "' is also the --output file (the model)");
    }
    if (!o.png_path.empty())
    {
      png = std::make_unique<SafeOutput>("--png", o.png_path,
                                         std::vector<std::string>{o.config_path, o.data_path, o.output_path});
      chart_script = helperBesideExecutable("identify_chart.py");
    }
    if (o.experiment)
    {
      writeExperiment(o, output->stream());
      output->commit();
      std::cerr << "backlash_identify: wrote " << o.output_path << "\n";
      return 0;
    }
    data = readData(o);
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_identify: error: " << e.what() << "\n";
    return 2;
  }
  try
  {
    const IdentificationSettings s = settingsFrom(o);
    IdentifyOptions options;
    options.keys = o.fit;
    options.joint = o.joint_fit == "on"    ? JointFitMode::On
                    : o.joint_fit == "off" ? JointFitMode::Off
                                           : JointFitMode::Auto;
    options.fit = o.joint;
    Progress progress(isatty(2) != 0, 1.0);
    options.fit.progress = [&progress](int done, int budget) {
      progress.update(static_cast<std::size_t>(done), static_cast<std::size_t>(budget));
    };
    options.stated = o.known.stated;
    const JointIdentification result = identifyJoint(data, s, o.known.params, options);
    progress.finish();
    for (const std::string& warning : result.warnings)
    {
      std::cerr << "backlash_identify: warning: " << warning << "\n";
    }
    if (png && result.joint_fit)
    {
      const ReplayWindows shown(data, result.settings, result.initial.zero_offset, result.fit.window_starts,
                                result.fit.window_length);
      drawChart(data, s.gear_ratio, shown, result.fit, chart_script, *png);
    }
    if (png && !result.joint_fit)
    {
      std::cerr << "backlash_identify: --png not drawn: it shows the joint fit, which did not run\n";
    }
    if (output)
    {
      writeModel(o, result, output->stream());
      output->commit();
      std::cerr << "backlash_identify: wrote " << o.output_path << "\n";
    }
    if (o.json)
    {
      printJson(o, result);
    }
    else
    {
      printText(o, data, result);
    }
    flushStdout();
  }
  catch (const InvalidParameterError& e)
  {
    std::cerr << "backlash_identify: error: " << e.what() << "\n";
    return 2;
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_identify: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
