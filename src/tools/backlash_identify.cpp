// backlash_identify: the joint's parameters from a recording of its own motion (initial estimates by linear least
// squares on the contact and apart phases). See docs/identification.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"
#include "backlash_servo/config/safe_input.h"
#include "backlash_servo/identification.h"
#include "json_writer.h"
#include "safe_output.h"

using namespace backlash_servo;

namespace
{
const char* HEADER =
    R"(usage: backlash_identify --data FILE.csv --gear-ratio RHO | --config PRIOR.yaml [--contact-band RAD]
                         [--smoothing R] [--still-speed W] [--json] [--output MODEL.yaml]
       backlash_identify --experiment --config PRIOR.yaml [--duration S] [--travel RAD] --output PROFILE.yaml
Estimates the joint's backlash, inertias, viscous and Coulomb friction and load torque from a recording of its own
motion: the backlash from the range of the gap theta_c - rho*theta_m, the rest by linear least squares on the phases
where the teeth are in contact and where they are apart. FILE.csv has the header time,motor_torque,motor_position,
load_position (SI: s, N*m, rad on each body's own shaft; other columns are ignored; rows with an `event` are
skipped, so backlash_sim's --csv is a recording), uniform time steps; the motor torque is the one applied from each
sample to the next. The gear ratio must be known (a flag or the prior YAML).
--output writes the prior with the estimates in place: a YAML every tool and the node accept.
--experiment writes instead a command profile that informs the estimates (sines at three speeds, each reversal
across the backlash), designed from the prior's gain, inertias and backlash, for the node or backlash_sim to run.
)";

struct Options
{
  std::string data_path, config_path, output_path;
  bool experiment = false;
  std::set<std::string> fit;  // the estimates written into the model
  double duration = 60.0, travel = 0.0;
  RunConfig prior_config;
  KeyValues prior;
  double gear_ratio = 0.0, contact_band = 0.0, still_speed = 0.0;
  int smoothing = 0;
  bool json = false;
};

Options parse(int argc, char** argv)
{
  FlagParser parser(
      "backlash_identify", HEADER,
      keysOfSections({ParamSection::Servo, ParamSection::Drive, ParamSection::Initial, ParamSection::Run}),
      {{"config", "PRIOR.yaml", "what is known of the joint (the gear ratio at least); flags override it"},
       {"data", "FILE.csv", "the recording: time,motor_torque,motor_position,load_position"},
       {"contact_band", "RAD",
        "a sample is in contact when its gap is this close to a flank [rad] (default: 1e-8 of the backlash, for exact "
        "data; give the gap's quantisation for measured data)"},
       {"smoothing", "R",
        "for quantised or noisy angles: every term filtered by the centred mean over 2R+1 samples, twice (default 0: "
        "none)"},
       {"still_speed", "W",
        "samples where the motor turns slower than this [rad/s] are left out (default 1e-6 of its fastest)"},
       {"json", "", "one JSON object on stdout"},
       {"output", "MODEL.yaml", "the prior with the estimated keys replaced (with --experiment: the profile)"},
       {"fit", "KEY[,KEY...]",
        "the estimates written into the model (default all: backlash, motor_inertia, load_inertia, motor_friction, "
        "load_friction, motor_coulomb_friction, load_coulomb_friction, load_torque, restitution); the others keep the "
        "prior's values"},
       {"experiment", "", "write an excitation (a command profile) to --output instead of identifying"},
       {"duration", "S", "--experiment: its length [s] (default 60)"},
       {"travel", "RAD",
        "--experiment: the command's largest excursion [rad] (default and least: 3 times the backlash)"}});
  parser.parse(argc, argv);
  Options o;
  o.config_path = parser.option("config");
  o.data_path = parser.option("data");
  o.output_path = parser.option("output");
  o.json = parser.given("json");
  o.experiment = parser.given("experiment");
  if (o.experiment)
  {
    if (!o.data_path.empty() || o.output_path.empty() || o.json)
    {
      throw ConfigError("--experiment writes a profile: give --output PROFILE.yaml (and no --data or --json)");
    }
    o.prior_config = runConfigFrom(parser.keys());
    o.duration = parser.optionNumber("duration", 60.0);
    o.travel = parser.optionNumber("travel", 3.0 * o.prior_config.params.backlash);
    return o;
  }
  const std::vector<std::string> fittable = {
      "backlash",      "motor_inertia",          "load_inertia",          "motor_friction",
      "load_friction", "motor_coulomb_friction", "load_coulomb_friction", "load_torque",
      "restitution"};
  if (parser.given("fit"))
  {
    std::stringstream list(parser.option("fit"));
    for (std::string key; std::getline(list, key, ',');)
    {
      if (std::find(fittable.begin(), fittable.end(), key) == fittable.end())
      {
        throw ConfigError("--fit: '" + key +
                          "' is not estimated here (backlash, motor_inertia, load_inertia, motor_friction, "
                          "load_friction, motor_coulomb_friction, load_coulomb_friction, load_torque, restitution)");
      }
      o.fit.insert(key);
    }
  }
  else
  {
    o.fit.insert(fittable.begin(), fittable.end());
  }
  if (parser.given("duration") || parser.given("travel"))
  {
    throw ConfigError("--duration and --travel are for --experiment");
  }
  if (o.data_path.empty())
  {
    throw ConfigError("--data FILE.csv is required: the recording to identify the joint from");
  }
  o.prior = parser.keys();
  if (o.prior.has("zeta") || o.prior.has("inertia_ratio") || o.prior.has("friction_ratio"))
  {
    throw ConfigError(
        "the prior must be in physical form (motor_inertia, …), not the chart form: the estimates "
        "replace physical keys");
  }
  if (!o.prior.has("gear_ratio"))
  {
    throw ConfigError("the gear ratio must be known: give --gear-ratio or gear_ratio in the prior YAML");
  }
  // The prior as a whole must be a valid joint (the estimates replace some of its keys).
  const RunConfig checked = runConfigFrom(o.prior);
  o.gear_ratio = checked.params.gear_ratio;
  o.contact_band = parser.optionNumber("contact_band", 0.0);
  if (parser.given("contact_band") && !(o.contact_band > 0.0))
  {
    throw ConfigError("--contact-band must be > 0 rad");
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
  const std::vector<std::string> header = splitCsvCells(line);
  std::map<std::string, std::size_t> column;
  for (std::size_t i = 0; i < header.size(); ++i)
  {
    column[header[i]] = i;
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
      if (i >= cells.size() || end == cells[i].c_str() || *end != '\0' || !std::isfinite(v))
      {
        throw ConfigError("--data: row " + std::to_string(row) + ", column " + need[c] + ": '" +
                          (i < cells.size() ? cells[i] : std::string()) + "' is not a finite number");
      }
      into[c]->push_back(v);
    }
  }
  return r;
}

std::string number(double v)
{
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

struct Row
{
  const char* key;
  const char* unit;
  const Estimate* e;
};

}  // namespace

int main(int argc, char** argv)
{
  Options o;
  std::unique_ptr<SafeOutput> output;
  Recording data;
  try
  {
    o = parse(argc, argv);
    if (!o.output_path.empty())
    {
      output =
          std::make_unique<SafeOutput>("--output", o.output_path, std::vector<std::string>{o.config_path, o.data_path});
    }
    if (o.experiment)
    {
      const std::vector<ProfileSegment> segments =
          identificationExperiment(o.prior_config.params, o.duration, o.travel);
      std::ostream& out = output->stream();
      out.precision(10);
      out << "# backlash_identify --experiment: " << o.duration << " s of command about its start, for a joint with "
          << "backlash " << o.prior_config.params.backlash << " rad and loop natural frequency "
          << o.prior_config.params.naturalFrequency() << " rad/s.\n"
          << "# The slow sine: contact motion both ways (friction, load torque); the faster ones: accelerations (the "
             "inertias);\n# every reversal crosses the backlash (the motor alone while the teeth are apart). SI "
             "units: s, rad, Hz.\n";
      for (const ProfileSegment& seg : segments)
      {
        out << "- sine: {time: " << seg.time << ", amplitude: " << seg.amplitude << ", frequency: " << seg.frequency
            << ", duration: " << seg.duration << "}\n";
      }
      output->commit();
      std::cerr << "backlash_identify: wrote " << o.output_path << "\n";
      return 0;
    }
    data = readRecording(o.data_path);
  }
  catch (const std::exception& e)
  {
    std::cerr << "backlash_identify: error: " << e.what() << "\n";
    return 2;
  }
  try
  {
    IdentificationSettings s;
    s.gear_ratio = o.gear_ratio;
    s.contact_band = o.contact_band;
    s.smoothing = o.smoothing;
    // Contact one way only (a limit cycle pushed from one side): the prior's load torque (default 0) splits it.
    s.load_torque_fallback = o.prior.has("load_torque") ? o.prior.number("load_torque") : 0.0;
    s.still_speed = o.still_speed;
    const InitialEstimates e = estimateInitial(data, s);
    // The restitution: the simulator replayed over windows around impacts (none: not estimated, the prior's kept).
    Estimate restitution;
    std::string restitution_note = o.fit.count("restitution") ? "" : "not in --fit";
    try
    {
      if (restitution_note.empty())
      {
        restitution = fitRestitution(data, s, e);
      }
    }
    catch (const InvalidParameterError& none)
    {
      restitution_note = none.what();
    }
    std::vector<Row> rows = {{"backlash", "rad", &e.backlash},
                             {"motor_inertia", "kg*m^2", &e.motor_inertia},
                             {"load_inertia", "kg*m^2", &e.load_inertia},
                             {"motor_friction", "N*m*s/rad", &e.motor_friction},
                             {"load_friction", "N*m*s/rad", &e.load_friction},
                             {"motor_coulomb_friction", "N*m", &e.motor_coulomb_friction},
                             {"load_coulomb_friction", "N*m", &e.load_coulomb_friction},
                             {"load_torque", "N*m", &e.load_torque}};
    if (restitution_note.empty())
    {
      rows.push_back({"restitution", "-", &restitution});
    }
    if (output)
    {
      // The prior's keys, the estimated ones replaced (static friction at least the Coulomb level).
      KeyValues model = o.prior;
      for (const Row& r : rows)
      {
        if (o.fit.count(r.key) == 0 || (std::string(r.key) == "load_torque" && e.load_torque_given))
        {
          continue;  // the prior's value stays
        }
        // A friction level estimated below zero is zero within its scatter: the model gets 0.
        const bool level = std::string(r.key).find("friction") != std::string::npos;
        model.setNumber(r.key, level ? std::max(0.0, r.e->value) : r.e->value);
      }
      for (const char* body : {"motor", "load"})
      {
        const std::string coulomb = std::string(body) + "_coulomb_friction",
                          stat = std::string(body) + "_static_friction";
        const double level = model.number(coulomb, 0.0);  // (absent: the table's default, 0)
        if (level > 0.0 && (!model.has(stat) || model.number(stat) < level))
        {
          model.setNumber(stat, level);
        }
      }
      runConfigFrom(model);  // what every tool will read: refused here (naming the key) rather than there
      output->stream() << "# backlash_identify: the joint estimated from " << o.data_path << " (SI units)\n";
      for (const auto& [key, value] : model.keys())
      {
        output->stream() << key << ": " << value << "\n";
      }
      output->commit();
      std::cerr << "backlash_identify: wrote " << o.output_path << "\n";
    }
    if (o.json)
    {
      std::ostringstream out;
      JsonWriter w(out);
      w.beginObject();
      w.beginObject("estimates");
      for (const Row& r : rows)
      {
        w.beginObject(r.key);
        w.field("value", r.e->value);
        w.field("standard_error", r.e->standard_error);
        w.endObject();
      }
      w.endObject();
      w.field("zero_offset", e.zero_offset);
      w.field("load_torque_given", e.load_torque_given);
      w.field("contact_samples", static_cast<long long>(e.contact_samples));
      w.field("apart_samples", static_cast<long long>(e.apart_samples));
      w.field("contact_rms_residual", e.contact_rms_residual);
      w.field("apart_rms_residual", e.apart_rms_residual);
      w.endObject();
      std::cout << out.str() << "\n";
    }
    else
    {
      std::printf("%zu samples: %zu in contact, %zu apart used (rms residual %.3g / %.3g N*m)\n", data.time.size(),
                  e.contact_samples, e.apart_samples, e.contact_rms_residual, e.apart_rms_residual);
      for (const Row& r : rows)
      {
        std::printf("%-24s %14s +- %-10s %s\n", r.key, number(r.e->value).c_str(), number(r.e->standard_error).c_str(),
                    r.unit);
      }
      std::printf("%-24s %14s    %-10s %s (the gap the encoders read on the forward flank)\n", "zero_offset",
                  number(e.zero_offset).c_str(), "", "rad");
      if (e.load_torque_given)
      {
        std::printf(
            "load_torque: the prior's (the contact motion went one way only: the load torque and the Coulomb "
            "friction cannot be told apart)\n");
      }
      const char* why = restitution_note.empty()             ? ""
                        : restitution_note == "not in --fit" ? "restitution (not in --fit), "
                                                             : "restitution (no impact in the recording), ";
      std::printf(
          "not estimated (the prior's values are kept): %sstatic friction (at least the Coulomb level), a "
          "compliant mesh\n",
          why);
      if (o.fit.size() < 9)
      {
        std::printf("written into the model (--fit): only the listed keys; the others keep the prior's values\n");
      }
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
