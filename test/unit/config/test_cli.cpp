// backlash_sim as a user runs it: JSON contract, YAML config equivalence, CSV output, clear errors with exit code 2.
#include <gtest/gtest.h>

#include "test_helpers.h"

#include "backlash_servo/config/flag_parser.h"
#include "backlash_servo/config/run_config_loader.h"

#include <sys/stat.h>
#include <sys/wait.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>

namespace
{
struct Result
{
  int code;
  std::string out;
  std::string err;
};

Result run(const std::string& args)
{
  const std::string err_file = "/tmp/backlash_sim_test_err.txt";
  int code = 0;
  const std::string out =
      test_helpers::runCapture(std::string(BACKLASH_SIM_EXE) + " " + args + " 2>" + err_file, &code);
  std::ifstream f(err_file);
  std::stringstream err;
  err << f.rdbuf();
  return {code, out, err.str()};
}

double number(const std::string& json, const std::string& key)
{
  std::smatch m;
  const std::regex re("\"" + key + "\":(-?[0-9.eE+-]+)");
  if (!std::regex_search(json, m, re))
  {
    ADD_FAILURE() << "no key " << key << " in " << json.substr(0, 300);
    return 0.0;
  }
  return std::stod(m[1]);
}

std::string writeFile(const std::string& name, const std::string& text)
{
  const std::string path = "/tmp/" + name;
  std::ofstream(path) << text;
  return path;
}

/// A profile file /tmp/backlash_sim_profile_<name>.yaml holding `yaml`.
std::string profile(const std::string& name, const std::string& yaml)
{
  return writeFile("backlash_sim_profile_" + name + ".yaml", yaml + "\n");
}
}  // namespace

// A tool option named as one of the tool's keys would shadow one of the two (--duration once read the run's
// length where backlash_identify meant its experiment's): refused when the parser is made.
TEST(Cli, AToolOptionCannotShareAKeysName)
{
  EXPECT_THROW(
      backlash_servo::FlagParser("tool", "", {"duration", "gain"}, {{"duration", "S", "the experiment's length"}}),
      std::logic_error);
  EXPECT_NO_THROW(backlash_servo::FlagParser("tool", "", {"gain"}, {{"duration", "S", "the experiment's length"}}));
}

TEST(Cli, ThesisCaseJsonHasTheContractFields)
{
  const Result r = run("--json");
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* key : {"\"params\"", "\"limit_cycle\":true", "\"limit_cycle_error\"", "\"period\"", "\"maxima\"",
                          "\"impacts\"", "\"energy\"", "\"input\"", "\"motor_friction\"", "\"load_friction\"",
                          "\"impact_loss\"", "\"kinetic\"", "\"final_state\"", "\"contact\""})
  {
    EXPECT_NE(r.out.find(key), std::string::npos) << key;
  }
  EXPECT_NEAR(number(r.out, "limit_cycle_error"), 0.0515, 5e-4);
  EXPECT_NEAR(number(r.out, "motor_inertia"), 0.1, 1e-15);
}

TEST(Cli, ChartFormAndYamlConfigGiveTheSameRun)
{
  const Result flags = run("--json --zeta 0.5 --inertia-ratio 1 --friction-ratio 0.4 --restitution 1 --backlash 0.3");
  const std::string yaml = writeFile("backlash_sim_test.yaml",
                                     "# fig. 31\nzeta: 0.5   # damping ratio\ninertia_ratio: 1\nfriction_ratio: 0.4\n"
                                     "restitution: 1\nbacklash: 0.3\npublish_rate: 100  # node-only key, ignored\n");
  const Result file = run("--json --config " + yaml);
  ASSERT_EQ(flags.code, 0) << flags.err;
  ASSERT_EQ(file.code, 0) << file.err;
  EXPECT_DOUBLE_EQ(number(flags.out, "limit_cycle_error"), number(file.out, "limit_cycle_error"));
  EXPECT_NEAR(number(file.out, "limit_cycle_error"), 0.046, 1e-3);
  // Flags override the file.
  const Result over = run("--json --config " + yaml + " --backlash 0.03");
  EXPECT_NEAR(number(over.out, "limit_cycle_error") * 10.0, number(file.out, "limit_cycle_error"), 1e-6);
}

TEST(Cli, CsvHasSamplesAndEventRows)
{
  const std::string csv = "/tmp/backlash_sim_test.csv";
  std::remove(csv.c_str());
  const Result r = run("--duration 20 --csv " + csv + " --sample-rate 50");
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream f(csv);
  std::string header;
  std::getline(f, header);
  EXPECT_EQ(
      header,
      "time,load_position,load_velocity,motor_position,motor_velocity,gap,contact,mesh_torque,motor_torque,event");
  int samples = 0, impacts = 0, maxima = 0;
  std::string line;
  while (std::getline(f, line))
  {
    const std::string event = line.substr(line.rfind(',') + 1);
    samples += event.empty();
    impacts += event == "impact";
    maxima += event == "maximum";
  }
  EXPECT_EQ(samples, 20 * 50 + 1);
  EXPECT_GT(impacts, 0);
  EXPECT_GE(maxima, 2);
}

TEST(Cli, StaticFrictionDefaultsToTheCoulombValueInBothForms)
{
  for (const std::string form : {"", "--zeta 0.4 --inertia-ratio 9 --friction-ratio 0.4 "})
  {
    const Result r = run(form +
                         "--duration 1 --json --load-coulomb-friction 0.02 --motor-coulomb-friction 0.01 "
                         "--motor-static-friction 0.03");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(number(r.out, "load_static_friction"), 0.02) << form;
    EXPECT_EQ(number(r.out, "motor_static_friction"), 0.03) << form;
  }
}

TEST(Cli, BadInputIsOneClearLineAndExitCode2)
{
  struct Case
  {
    std::string args;
    std::string mentions;
  };
  const std::string bad_yaml = writeFile("backlash_sim_bad.yaml", "zeta: [0.5\n  inertia_ratio: : 1\n");
  const std::string unknown_key =
      writeFile("backlash_sim_unknown.yaml", "zeta: 0.5\ninertia_ratio: 1\nfriction_ratio: 0\nbacklsh: 0.3\n");
  const Case cases[] = {
      {"--restitution 1.5", "restitution"},
      {"--motor-inertia -1", "motor_inertia"},
      {"--gain nan", "--gain"},
      {"--backlash abc", "--backlash"},
      {"--frobnicate 3", "--frobnicate"},
      {"--zeta 0.4 --gain 2", "not both"},
      {"--zeta 0.4", "--inertia-ratio"},
      {"--contact sideways", "--contact"},
      {"--contact forward --motor-position 0.2", "motor_position"},
      {"--config /nonexistent.yaml", "cannot read"},
      {"--config " + bad_yaml, "not valid YAML"},
      {"--config " + unknown_key, "backlsh"},
      // A typo names the nearest key or flag (a transposition and a misspelling are one edit each).
      {"--config " + writeFile("backlash_sim_typo.yaml", "derivitive_gain: 0.3\n"),
       "unknown key 'derivitive_gain' (did you mean 'derivative_gain'?)"},
      {"--derivitive-gain 0.3", "unknown option --derivitive-gain (did you mean --derivative-gain?)"},
      {"--gian 2", "(did you mean --gain?)"},
      {"--load-coulomb-friction 0.2 --load-static-friction 0.1", "load_static_friction"},
      {"--motor-coulomb-friction -0.1", "motor_coulomb_friction"},
      {"--motor-static-friction inf", "--motor-static-friction"},
      {"--controller-rate nan", "--controller-rate"},
      {"--controller-rate 1e-300", "controller_rate: must be 0 (the continuous law) or at least 0.001 Hz (got 1e-300)"},
      {"--controller-rate 100 --controller-delay 2", "controller_delay"},
      {"--control-law bangbang", "--control-law"},
      {"--control-law pid", "controller_rate"},
      // Command profiles: every field checked, the file named.
      {"--profile " + profile("steps", "- step: {time: 0, target: 1}") + " --command 1", "not both"},
      {"--profile " + profile("typo", "- ramp: {time: 0, target: 1, rat: 2}") + " --controller-rate 100", "'rat'"},
      {"--profile " + profile("negative", "- ramp: {time: 0, target: 1, duration: -2}") + " --controller-rate 100",
       "duration"},
      {"--profile " + profile("nan", "- step: {time: 0, target: .nan}"), "'target'"},
      {"--profile " + profile("order", "- step: {time: 5, target: 1}\n- step: {time: 2, target: 0}"), "in order"},
      {"--profile " + profile("kind", "- jump: {time: 0, target: 1}"), "'jump'"},
      {"--profile " + profile("nocsv", "- points: {time: 0, csv: /nonexistent.csv}"), "cannot read"},
      {"--profile /nonexistent.csv", "cannot read"},
      {"--profile " + profile("sine", "- sine: {time: 0, amplitude: 0.1, frequency: 1, duration: 2}") +
           " --load-coulomb-friction 0.01",
       "controller_rate"},
      {"--profile " + profile("ramp", "- ramp: {time: 0, target: 1, duration: 2}") + " --load-coulomb-friction 0.01",
       "dry friction"},
      // Profile files are input like parameters: in the envelope, a strict CSV grammar, no silent defaults.
      {"--profile " + profile("huge", "- step: {time: 0, target: 1e12}"), "(got 1000000000000)"},
      {"--profile " + profile("empty", "profile: []"), "non-empty list"},
      {"--profile " + profile("dup", "- step: {time: 0, target: 1, target: 2}"), "'target' is given twice"},
      {"--config " + writeFile("backlash_sim_dup.yaml", "gain: 1\ngain: 2\n"), "'gain' is given twice"},
      {"--profile " + writeFile("backlash_sim_nan_first.csv", "nan,2\n1,3\n"), "row 1"},
      {"--profile " + writeFile("backlash_sim_three.csv", "0,1\n1,2,3\n"), "row 2 has 3 columns"},
      {"--profile " + writeFile("backlash_sim_crlf.csv", "time,value\r\n0,1\r\n"), "carriage return"},
      {"--profile " + writeFile("backlash_sim_nul.csv", std::string("0,1\n1,2\0"
                                                                    "5\n",
                                                                    9)),
       "NUL byte"},
      {"--profile " + writeFile("backlash_sim_bigpoint.csv", "0,1\n1,1e300\n"), "point 2"},
      {"--profile /dev/zero", "not a regular file"},
      {"--profile /nonexistent.yaml", "profile file: cannot read '/nonexistent.yaml'"},
      {"--config /tmp", "a directory"}};
  for (const Case& c : cases)
  {
    const std::string csv = "/tmp/backlash_sim_never.csv";
    std::remove(csv.c_str());
    const Result r = run(c.args + " --csv " + csv);
    EXPECT_EQ(r.code, 2) << c.args;
    EXPECT_TRUE(r.out.empty()) << c.args;
    EXPECT_NE(r.err.find(c.mentions), std::string::npos) << c.args << " -> " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(std::ifstream(csv).good()) << "half-written output for " << c.args;
  }
}

namespace
{
TEST(Cli, OutputNeverLies)
{
  // A failed write (a full disk) is an error, not exit 0 with a result nobody got.
  Result full = run("--duration 5 --json >/dev/full");
  EXPECT_EQ(full.code, 1) << full.err;
  EXPECT_NE(full.err.find("standard output"), std::string::npos) << full.err;
  // A device is never replaced by a regular file (as root, a rename over /dev/null would do exactly that).
  Result dev = run("--duration 1 --csv /dev/null");
  EXPECT_EQ(dev.code, 2);
  EXPECT_NE(dev.err.find("not a regular file"), std::string::npos) << dev.err;
  struct stat st;
  ASSERT_EQ(stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  // The CSV is streamed to FILE.tmp and renamed when complete; no temporary is left behind.
  const std::string csv = "/tmp/backlash_sim_stream.csv";
  std::remove(csv.c_str());
  Result ok = run("--duration 3 --csv " + csv);
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_TRUE(std::ifstream(csv).good());
  EXPECT_FALSE(std::ifstream(csv + ".tmp").good());
}

TEST(Cli, AnImpactStormStopsAtTheEventBudgetWithAClearMessage)
{
  // Elastic teeth under a pressing torque chatter physically for ever; the budget ends the run, unsettled.
  Result r = run("--zeta 0.2 --inertia-ratio 0.04 --friction-ratio 0.8 --restitution 1 --max-events 1000 --json");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"stopped_by\":\"event_budget\""), std::string::npos) << r.out.substr(0, 300);
  EXPECT_NE(r.out.find("\"settled\":false"), std::string::npos);
  EXPECT_NEAR(number(r.out, "impacts"), 1001.0, 0.5);
  EXPECT_NE(r.err.find("event budget of 1000 impacts exceeded"), std::string::npos) << r.err;
  Result bad = run("--max-events 0");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("max_events"), std::string::npos) << bad.err;
}
}  // namespace

// Profiles from a file, inline in the run's YAML and as a CSV of set-points are the same run, judged against the
// final value from the last step on.
TEST(Cli, ProfilesFromAFileInlineOrCsvAreTheSameRun)
{
  const std::string file = profile("same", "- step: {time: 0, target: 1}\n- step: {time: 30.5, target: 0.5}");
  const std::string csv = writeFile("backlash_sim_profile_same.csv", "time,value\n0,1\n30.5,0.5\n");
  const std::string inline_yaml =
      writeFile("backlash_sim_profile_inline.yaml",
                "backlash: 0.3\nprofile:\n  - step: {time: 0, target: 1}\n"
                "  - points: {time: 0, csv: backlash_sim_profile_same.csv}\n");  // point times count from `time`
  const Result a = run("--json --duration 80 --profile " + file);
  const Result b = run("--json --duration 80 --profile " + csv);
  const Result c = run("--json --duration 80 --config " + inline_yaml);
  ASSERT_EQ(a.code, 0) << a.err;
  ASSERT_EQ(b.code, 0) << b.err;
  ASSERT_EQ(c.code, 0) << c.err;
  auto maxima = [](const std::string& json) {
    const std::size_t from = json.find("\"maxima\"");
    return json.substr(from, json.find("\"wall_time\"") - from);
  };
  EXPECT_EQ(maxima(a.out), maxima(b.out));
  EXPECT_EQ(maxima(a.out), maxima(c.out));
  EXPECT_EQ(number(a.out, "command"), 0.5);  // judged against the final value
  // Judged from the profile's end on (the last step at 30.5 s), against its final value.
  const std::string first_time = maxima(a.out).substr(std::string("\"maxima\":[{\"time\":").size(), 10);
  EXPECT_GE(std::stod(first_time), 30.5) << maxima(a.out);
}

namespace
{
TEST(Cli, AProfileCsvsFirstRowIsDataUnlessItIsANameHeader)
{
  // ".5,2" is the first point, not a header to drop: the command reaches 2 at 0.5 s, then 3 at 1 s.
  const std::string dot = writeFile("backlash_sim_dot.csv", ".5,2\n1,3\n");
  const std::string named = writeFile("backlash_sim_named.csv", "time [s],command [rad]\n0.5,2\n1,3\n");
  for (const std::string& path : {dot, named})
  {
    const Result r = run("--profile " + path + " --duration 0.75 --csv /tmp/backlash_sim_dot_out.csv");
    ASSERT_EQ(r.code, 0) << r.err;
    const std::string csv = test_helpers::readFile("/tmp/backlash_sim_dot_out.csv");
    // The reference column at 0.7 s (the 70th sample at 100 Hz) is the first point's value.
    const auto header_end = csv.find('\n');
    const std::string header = csv.substr(0, header_end);
    std::stringstream rows(csv.substr(header_end + 1));
    std::string line, at_07;
    while (std::getline(rows, line))
    {
      if (line.rfind("0.7,", 0) == 0)
      {
        at_07 = line;
      }
    }
    ASSERT_FALSE(at_07.empty()) << csv.substr(0, 400);
    std::vector<std::string> names, cells;
    std::stringstream hs(header), ls(at_07);
    for (std::string c; std::getline(hs, c, ',');)
    {
      names.push_back(c);
    }
    for (std::string c; std::getline(ls, c, ',');)
    {
      cells.push_back(c);
    }
    // The continuous P law with K = 1 N·m/rad (the default): command = motor_torque / K + load_position.
    auto cell = [&](const char* name) {
      const auto col = static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
      return col < cells.size() ? std::stod(cells[col]) : NAN;
    };
    EXPECT_NEAR(cell("motor_torque") + cell("load_position"), 2.0, 1e-12) << path << ": " << at_07;
  }
}
}  // namespace

TEST(Cli, AnIdentificationPriorIsWhatTheUserKnows)
{
  using namespace backlash_servo;
  // Only the gear ratio is required; the encoders' resolutions need no drive; keys not given are unknown — the
  // table's default inertias (whose split with ρ = 0.01 lies outside the validated envelope) are not checked.
  KeyValues robot;
  robot.setNumber("gear_ratio", 0.01);
  robot.setNumber("motor_encoder_resolution", 65536);
  robot.setNumber("load_encoder_resolution", 4096);
  const IdentificationPrior prior = identificationPriorFrom(robot);
  EXPECT_EQ(prior.stated, std::set<std::string>{"gear_ratio"});
  EXPECT_EQ(prior.motor_encoder_resolution, 65536.0);
  EXPECT_EQ(prior.load_encoder_resolution, 4096.0);
  EXPECT_THROW(runConfigFrom(robot), InvalidParameterError);  // (as a joint to simulate it is refused)
  // A Coulomb level given without its static level: the static level at least the Coulomb one.
  KeyValues dry = robot;
  dry.setNumber("motor_coulomb_friction", 0.1);
  EXPECT_EQ(identificationPriorFrom(dry).params.motor_static_friction, 0.1);
  // Refused, naming what is wrong: no gear ratio, the chart form, a key outside its range.
  KeyValues none;
  none.setNumber("motor_encoder_resolution", 4096);
  try
  {
    identificationPriorFrom(none);
    ADD_FAILURE() << "a prior without the gear ratio was accepted";
  }
  catch (const ConfigError& e)
  {
    EXPECT_NE(std::string(e.what()).find("gear ratio"), std::string::npos) << e.what();
  }
  KeyValues chart = robot;
  chart.setNumber("zeta", 0.5);
  EXPECT_THROW(identificationPriorFrom(chart), ConfigError);
  KeyValues negative = robot;
  negative.setNumber("load_inertia", -1.0);
  try
  {
    identificationPriorFrom(negative);
    ADD_FAILURE() << "a negative inertia was accepted";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_EQ(e.field(), "load_inertia");
  }
}
