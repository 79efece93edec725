// backlash_sweep, backlash_design and the chart scripts, checked against single backlash_sim runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>

#include "test_helpers.h"

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <complex>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace
{
using test_helpers::readFile;
using test_helpers::runCapture;

std::vector<std::vector<std::string>> csvRows(const std::string& text)
{
  std::vector<std::vector<std::string>> rows;
  std::stringstream ss(text);
  std::string line;
  std::getline(ss, line);  // header
  while (std::getline(ss, line))
  {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    std::string cell;
    while (std::getline(ls, cell, ','))
    {
      cells.push_back(cell);
    }
    if (!line.empty() && line.back() == ',')
    {
      cells.emplace_back();  // a trailing empty cell
    }
    rows.push_back(cells);
  }
  return rows;
}

double jsonNumber(const std::string& json, const std::string& key)
{
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\":(-?[0-9.eE+-]+)")))
  {
    ADD_FAILURE() << "no " << key << " in " << json.substr(0, 300);
    return NAN;
  }
  return std::stod(m[1]);
}

std::string jsonText(const std::string& json, const std::string& key)
{
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\":\"([a-z_]+)\"")))
  {
    return "";
  }
  return m[1];
}

const std::string SWEEP = BACKLASH_SWEEP_EXE;
const std::string SIM = BACKLASH_SIM_EXE;
const std::string DESIGN = BACKLASH_DESIGN_EXE;
const std::string COMPARE = BACKLASH_COMPARE_EXE;
const std::string DF = BACKLASH_DF_EXE;
const std::string FRF = BACKLASH_FRF_EXE;
const std::string IDENTIFY = BACKLASH_IDENTIFY_EXE;
const std::string GRID = " --zeta 0.3,0.6 --inertia-ratio 1,9 --friction-ratio 0.4 --restitution 0,0.6,1";
}  // namespace

TEST(Sweep, EveryRowEqualsASingleBacklashSimRun)
{
  int code = 0;
  const std::string csv = runCapture(SWEEP + GRID + " --jobs 2 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 12u);
  int cycles = 0;
  for (const auto& r : rows)
  {
    ASSERT_EQ(r.size(), 18u);  // (steady_error: empty unless converged; maxima_per_period; the cycle's shape)
    const std::string json = runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio " + r[1] +
                                        " --friction-ratio " + r[2] + " --restitution " + r[3] + " --backlash " + r[4]);
    EXPECT_EQ(r[5], jsonText(json, "verdict")) << r[0] << " " << r[1] << " " << r[3];
    EXPECT_EQ(std::stod(r[7]), jsonNumber(json, "limit_cycle_error"));
    EXPECT_EQ(std::stoull(r[9]), static_cast<unsigned long long>(jsonNumber(json, "impacts")));
    EXPECT_EQ(std::stoi(r[13]), r[6] == "1" ? static_cast<int>(jsonNumber(json, "maxima_per_period")) : 0);
    if (r[6] == "1")
    {
      EXPECT_EQ(std::stod(r[14]), jsonNumber(json, "peak_to_peak"));
      EXPECT_EQ(std::stod(r[15]), jsonNumber(json, "cycle_centre"));
    }
    else
    {
      EXPECT_EQ(r[14], "");
      EXPECT_EQ(r[15], "");
    }
    EXPECT_EQ(r[16], "");  // (the continuous law reads an ideal sensor: no counts)
    EXPECT_EQ(r[17], "");
    cycles += r[6] == "1";
  }
  EXPECT_GT(cycles, 0);
  EXPECT_LT(cycles, 12);
}

// --tracking adds the tracking figures: each equals backlash_sim's (the same replay) — a number, or empty where the
// JSON has null — and the sharded parts of such a sweep merge into exactly the unsharded CSV.
TEST(Sweep, TrackingColumnsEqualBacklashSimsFigures)
{
  const std::string grid = " --zeta 0.3,0.6 --inertia-ratio 1,9 --friction-ratio 0.4 --restitution 0,1 --tracking";
  int code = 0;
  const std::string csv = runCapture(SWEEP + grid + " --jobs 2 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  EXPECT_NE(
      csv.find("cycle_centre,peak_to_peak_counts,below_resolution,settling_band,settling_time,steady_rms_error\n"),
      std::string::npos);
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 8u);
  int settled = 0;
  for (const auto& r : rows)
  {
    ASSERT_EQ(r.size(), 21u);
    const std::string json = runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio " + r[1] +
                                        " --friction-ratio " + r[2] + " --restitution " + r[3]);
    EXPECT_EQ(std::stod(r[18]), jsonNumber(json, "settling_band"));
    if (json.find("\"settling_time\":null") != std::string::npos)
    {
      EXPECT_EQ(r[19], "");
    }
    else
    {
      EXPECT_EQ(std::stod(r[19]), jsonNumber(json, "settling_time"));
      ++settled;
    }
    EXPECT_EQ(std::stod(r[20]), jsonNumber(json, "steady_rms_error"));
  }
  EXPECT_GT(settled, 0);
  // Shards of the tracking sweep merge into the same bytes.
  char tmpl[] = "/tmp/backlash_tracking_XXXXXX";
  ASSERT_NE(mkdtemp(tmpl), nullptr);
  const std::string dir = tmpl;
  for (int k = 1; k <= 3; ++k)
  {
    ASSERT_EQ(std::system((SWEEP + grid + " --shard " + std::to_string(k) + "/3 --output " + dir + "/p" +
                           std::to_string(k) + ".csv 2>/dev/null")
                              .c_str()),
              0);
  }
  ASSERT_EQ(std::system((SWEEP + " --merge " + dir + "/p2.csv " + dir + "/p1.csv " + dir + "/p3.csv --output " + dir +
                         "/m.csv 2>/dev/null")
                            .c_str()),
            0);
  EXPECT_EQ(readFile(dir + "/m.csv"), csv);
  std::system(("rm -rf " + dir).c_str());
}

// A command profile is a setting every point shares: each row equals backlash_sim with the same profile (a digital
// drive sampling a ramp and a reversal), and differs from the plain step.
TEST(Sweep, AProfileIsSharedByEveryPoint)
{
  const std::string profile = "/tmp/backlash_sweep_profile.yaml";
  std::ofstream(profile) << "- ramp: {time: 0, target: 1, duration: 3}\n- move: {time: 40, distance: -0.4, "
                            "max_velocity: 0.2, max_acceleration: 0.1}\n";
  const std::string shared = " --controller-rate 200 --profile " + profile;
  int code = 0;
  const std::string csv = runCapture(SWEEP + " --zeta 0.3,0.5" + shared + " 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const auto rows = csvRows(csv);
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& r : rows)
  {
    const std::string json =
        runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio 9 --friction-ratio 0.4" + shared);
    EXPECT_EQ(r[5], jsonText(json, "verdict"));
    EXPECT_EQ(std::stod(r[10]), jsonNumber(json, "simulated_time"));
    EXPECT_GE(std::stod(r[10]), 40.0 + 2.0 * 2.0 + 0.0);  // a run until settled lasts past the profile's end
    const std::string step =
        runCapture(SIM + " --json --zeta " + r[0] + " --inertia-ratio 9 --friction-ratio 0.4 --controller-rate 200");
    EXPECT_NE(jsonNumber(step, "simulated_time"), jsonNumber(json, "simulated_time"));
  }
}

// Any numeric parameter is an axis, in either form, with fixed settings (a digital drive) shared by every point:
// each row is exactly the backlash_sim run of the same flags.
TEST(Sweep, AnyParameterIsAnAxisInEitherForm)
{
  struct Grid
  {
    std::string flags;   // the sweep's fixed settings and axes
    std::string header;  // its axis columns
  };
  const Grid grids[] = {
      {" --zeta 0.4 --load-coulomb-friction 0,0.02 --load-static-friction 0.05 --controller-rate 0,200",
       "zeta,inertia_ratio,friction_ratio,restitution,backlash,load_coulomb_friction,controller_rate,"},
      {" --motor-inertia 0.1 --load-inertia 0.9 --motor-friction 0.48 --load-friction 0.32 --backlash 0.05"
       " --restitution 0.5 --gain 0.5:1.5:2 --control-law pid --controller-rate 100 --integral-gain 0,0.2"
       " --derivative-gain 0.1",
       "restitution,backlash,gain,integral_gain,"},
      // The compliant keys in the chart form (the impacts column counts a compliant mesh's contact phases).
      {" --zeta 0.4 --mesh-stiffness 1e3,1e4 --mesh-damping 1,3",
       "zeta,inertia_ratio,friction_ratio,restitution,backlash,mesh_stiffness,mesh_damping,"}};
  for (const Grid& g : grids)
  {
    int code = 0;
    const std::string csv = runCapture(SWEEP + g.flags + " --jobs 2 2>/dev/null", &code);
    ASSERT_EQ(code, 0) << g.flags;
    EXPECT_EQ(csv.substr(0, g.header.size()), g.header);
    const auto rows = csvRows(csv);
    ASSERT_EQ(rows.size(), 4u);
    const int axes = static_cast<int>(std::count(g.header.begin(), g.header.end(), ','));
    std::vector<std::string> keys;
    std::stringstream hs(g.header);
    for (std::string k; std::getline(hs, k, ',');)
    {
      keys.push_back(k);
    }
    for (const auto& r : rows)
    {
      std::string flags = g.flags;
      for (int i = 0; i < axes; ++i)
      {
        std::string flag = "--" + keys[i];
        std::replace(flag.begin(), flag.end(), '_', '-');
        flags += " " + flag + " " + r[i];  // the last occurrence of a flag wins over the grid's list
      }
      // The sweep's own list values stand before: give backlash_sim only the point.
      std::string point;
      std::stringstream fs(flags);
      std::vector<std::string> words;
      for (std::string w; fs >> w;)
      {
        words.push_back(w);
      }
      for (std::size_t i = 0; i + 1 < words.size(); i += 2)
      {
        if (words[i + 1].find(',') == std::string::npos && words[i + 1].find(':') == std::string::npos)
        {
          point += " " + words[i] + " " + words[i + 1];
        }
      }
      const std::string json = runCapture(SIM + " --json" + point);
      EXPECT_EQ(r[axes], jsonText(json, "verdict")) << point;
      EXPECT_EQ(std::stod(r[axes + 2]), jsonNumber(json, "limit_cycle_error")) << point;
      const bool compliant = json.find("\"contact_phases\"") != std::string::npos;  // (only compliant runs have it)
      EXPECT_EQ(std::stod(r[axes + 4]), jsonNumber(json, compliant ? "contact_phases" : "impacts")) << point;
      if (r[axes] == "converged")
      {
        EXPECT_EQ(std::stod(r[axes + 7]), jsonNumber(json, "steady_error")) << point;
      }
    }
  }
  // Mixing the two forms is one clear error.
  int code = 0;
  const std::string err = runCapture(SWEEP + " --gain 1,2 --zeta 0.3,0.4 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("not both"), std::string::npos) << err;
}

TEST(Sweep, ResumeAfterAnInterruptionGivesTheSameCsv)
{
  const std::string full = "/tmp/backlash_sweep_full.csv", part = "/tmp/backlash_sweep_part.csv";
  int code = 0;
  runCapture(SWEEP + GRID + " --output " + full + " 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const std::string expected = readFile(full);
  // A torn file: header, the first three rows and half of the fourth.
  std::stringstream ss(expected);
  std::string line, torn;
  for (int i = 0; i < 4 && std::getline(ss, line); ++i)
  {
    torn += line + "\n";
  }
  std::getline(ss, line);
  torn += line.substr(0, line.size() / 2);
  std::ofstream(part) << torn;
  runCapture(SWEEP + GRID + " --output " + part + " --resume 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(part), expected);
  // A real interruption (SIGINT) leaves a valid prefix; --resume completes it identically.
  std::remove(part.c_str());
  const pid_t pid = fork();
  if (pid == 0)
  {
    const std::string args = SWEEP + GRID + " --jobs 1 --output " + part;
    execl("/bin/sh", "sh", "-c", ("exec " + args + " 2>/dev/null").c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  usleep(20000);
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  const int rc = WEXITSTATUS(status);
  EXPECT_TRUE(rc == 130 || rc == 0) << rc;
  EXPECT_EQ(expected.rfind(readFile(part), 0), 0u) << "interrupted output is not a prefix";
  runCapture(SWEEP + GRID + " --output " + part + " --resume 2>/dev/null", &code);
  EXPECT_EQ(readFile(part), expected);
}

TEST(Sweep, BadAxesAreOneLineErrors)
{
  int code = 0;
  const std::string err = runCapture(SWEEP + " --zeta 1:2 2>&1 >/dev/null", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("--zeta"), std::string::npos) << err;
  runCapture(SWEEP + " --friction-ratio 1.5 2>/dev/null", &code);
  EXPECT_EQ(code, 2);
}

TEST(Design, MaxGainIsConfirmedBySimulatingBelowAndAbove)
{
  const std::string args =
      " --motor-inertia 0.25 --motor-friction 0.64 --load-inertia 1.0 --load-friction 0.64 "
      "--restitution 0.6";
  int code = 0;
  const std::string json = runCapture(DESIGN + args + " --gain 1 --find max-gain --json", &code);
  ASSERT_EQ(code, 0) << json;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(json, m, std::regex("\"max_gain\":\\{[^{]*\"gain\":([0-9.eE+-]+)")));
  const double k = std::stod(m[1]);
  EXPECT_GT(k, 1.0);
  EXPECT_LT(k, 10.0);
  // Independent check with backlash_sim: converges below the answer, limit-cycles clearly above it.
  const std::string below = runCapture(SIM +
                                       " --json --motor-inertia 0.25 --motor-friction 0.64 --load-inertia 1.0 "
                                       "--load-friction 0.64 --restitution 0.6 --gain " +
                                       std::to_string(k * 0.99));
  const std::string above = runCapture(SIM +
                                       " --json --motor-inertia 0.25 --motor-friction 0.64 --load-inertia 1.0 "
                                       "--load-friction 0.64 --restitution 0.6 --gain " +
                                       std::to_string(k * 1.05));
  EXPECT_EQ(jsonText(below, "verdict"), "converged");
  EXPECT_EQ(jsonText(above, "verdict"), "limit_cycle");
  // The chart coordinates printed for the candidate follow from the inputs.
  EXPECT_NEAR(jsonNumber(json, "inertia_ratio"), 4.0, 1e-12);
  EXPECT_NEAR(jsonNumber(json, "friction_ratio"), 0.5, 1e-12);
}

// The design tool searches a gain of any law: the semi-closed-loop PID's integral gain, checked by backlash_sim runs
// of the same digital drive just below and clearly above the answer.
TEST(Design, SearchesTheIntegralGainOfASampledPid)
{
  const std::string joint =
      " --motor-inertia 0.1 --motor-friction 0.48 --load-inertia 0.9 --load-friction 0.32 --restitution 0.5"
      " --backlash 0.05 --gain 1 --control-law pid --controller-rate 100 --feedback motor --derivative-gain 0.3";
  int code = 0;
  const std::string json =
      runCapture(DESIGN + joint + " --tune integral-gain --integral-gain 0.01:100 --find max-gain --json", &code);
  ASSERT_EQ(code, 0) << json;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(json, m, std::regex("\"max_gain\":\\{[^{]*\"gain\":([0-9.eE+-]+)")));
  const double ki = std::stod(m[1]);
  EXPECT_GT(ki, 0.1);
  EXPECT_LT(ki, 10.0);
  const std::string below = runCapture(SIM + " --json" + joint + " --integral-gain " + std::to_string(ki * 0.99));
  const std::string above = runCapture(SIM + " --json" + joint + " --integral-gain " + std::to_string(ki * 1.2));
  EXPECT_EQ(jsonText(below, "verdict"), "converged");
  EXPECT_NE(jsonText(above, "verdict"), "converged");
  // An unknown gain to tune is one clear line.
  const std::string err = runCapture(DESIGN + joint + " --tune backlash --find max-gain 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("--tune"), std::string::npos) << err;
}

/// A 100:1 robot joint under gravity with dry friction, a 1 kHz PID on a 17-bit load encoder and a 0.5 N·m torque
/// limit (gains given by each test).
const std::string ROBOT_JOINT =
    " --motor-inertia 3e-5 --load-inertia 0.12 --motor-friction 5e-5 --load-friction 0.05 --gear-ratio 0.01"
    " --backlash 0.002618 --restitution 0.3 --load-torque -3.5 --motor-coulomb-friction 0.005"
    " --load-coulomb-friction 0.2 --control-law pid --controller-rate 1000 --load-encoder-resolution 131072"
    " --derivative-gain 0.3 --torque-limit 0.5 --command 0.5";

// Whether this robot joint hunts is not monotone in K (a 1 kHz PD on a 17-bit encoder, dry friction, gravity, a
// 0.5 N·m torque limit: free up to ~110 N·m/rad, hunting above): the answer lists the intervals without a cycle and
// agrees with backlash_sim at the values it cites — the chosen design converges, the value just above does not, and
// no interval reaches K = 1000 (a saturated swing there). With integral action every gain hunts (below one encoder
// count): the answer says so, with the smallest cycle met.
TEST(Design, TheIntervalsWithoutACycleAgreeWithTheSimulationsTheyCite)
{
  const std::string joint = ROBOT_JOINT;
  int code = 0;
  const std::string json = runCapture(DESIGN + joint + " --gain 15 --integral-gain 0 --find max-gain --json", &code);
  ASSERT_EQ(code, 0) << json;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(json, m, std::regex("\"max_gain\":\\{[^{]*\"gain\":([0-9.eE+-]+)")));
  const double k = std::stod(m[1]);
  EXPECT_GT(k, 100.0);
  EXPECT_LT(k, 120.0);
  ASSERT_TRUE(std::regex_search(json, m, std::regex("\"intervals\":\\[(.*?)\\]\\]")));
  EXPECT_EQ(std::string(m[1]).find("1000"), std::string::npos) << m[1];
  const std::string chosen = json.substr(json.find("\"chosen\""));
  EXPECT_EQ(jsonText(chosen, "verdict"), "converged");
  const std::string at_chosen =
      runCapture(SIM + " --json" + joint + " --integral-gain 0 --gain " + std::to_string(jsonNumber(chosen, "gain")));
  EXPECT_EQ(jsonText(at_chosen, "verdict"), "converged");
  for (const double above : {k * 1.01, 1000.0})
  {
    const std::string out = runCapture(SIM + " --json" + joint + " --integral-gain 0 --gain " + std::to_string(above));
    EXPECT_NE(jsonText(out, "verdict"), "converged") << above;
  }
  const std::string none = runCapture(DESIGN + joint + " --integral-gain 100 --gain 1:200 --find max-gain", &code);
  ASSERT_EQ(code, 0) << none;
  EXPECT_NE(none.find("max gain: none"), std::string::npos) << none;
  EXPECT_NE(none.find("the smallest cycle met"), std::string::npos) << none;
}

// A hunt of 6e-6 rad on a 17-bit encoder is an eighth of a count: backlash_sim says so in text and JSON, the design
// tool in its description of the cycle, a sweep in its columns.
TEST(Sim, AHuntBelowOneEncoderCountIsSaidSo)
{
  const std::string joint = ROBOT_JOINT + " --gain 15 --integral-gain 100";
  int code = 0;
  const std::string json = runCapture(SIM + joint + " --json", &code);
  ASSERT_EQ(code, 0) << json;
  const double count = 2.0 * M_PI / 131072.0;
  EXPECT_DOUBLE_EQ(jsonNumber(json, "peak_to_peak_counts"), jsonNumber(json, "peak_to_peak") / count);
  EXPECT_LT(jsonNumber(json, "peak_to_peak_counts"), 1.0);
  EXPECT_NE(json.find("\"below_encoder_resolution\":true"), std::string::npos) << json;
  const std::string text = runCapture(SIM + joint, &code);
  EXPECT_NE(text.find("counts of the encoder the loop reads"), std::string::npos) << text;
  EXPECT_NE(text.find("below one count: a hunt the loop cannot see"), std::string::npos) << text;
  const std::string design = runCapture(DESIGN + joint, &code);
  EXPECT_NE(design.find("below one count"), std::string::npos) << design;
  const std::string sweep = runCapture(SWEEP + joint + " --restitution 0.3,0.5", &code);
  ASSERT_EQ(code, 0) << sweep;
  const auto rows = csvRows(sweep);
  ASSERT_EQ(rows.size(), 2u);
  for (const auto& r : rows)
  {
    if (r[2] == "1")  // (limit_cycle) the counts and the flag
    {
      EXPECT_LT(std::stod(r[r.size() - 2]), 1.0);
      EXPECT_EQ(r.back(), "1");
    }
  }
}

// Degrees typed as radians (0.15 for a 0.15° backlash: 8.6°) run, with a warning naming the key, the value in
// degrees and what 0.15° is in rad; a catalogue-sized backlash and the thesis' ρ = 1 joints get none.
TEST(Sim, ABacklashOfDegreesTypedAsRadiansIsWarnedAbout)
{
  const std::string joint =
      " --motor-inertia 3e-5 --load-inertia 0.12 --motor-friction 5e-5 --load-friction 0.05 --gear-ratio 0.01"
      " --restitution 0.3 --gain 15 --command 0.5";
  int code = 0;
  const std::string err = runCapture(SIM + joint + " --backlash 0.15 2>&1 >/dev/null", &code);
  EXPECT_EQ(code, 0) << err;
  EXPECT_NE(err.find("warning: backlash: 0.15 rad is 8.59° at the load (30 % of the step)"), std::string::npos) << err;
  EXPECT_NE(err.find("0.15° would be 0.00261799 rad"), std::string::npos) << err;
  const std::string json = runCapture(SIM + joint + " --backlash 0.15 --json", &code);
  EXPECT_NE(json.find("\"warnings\":[\"backlash: 0.15 rad is 8.59°"), std::string::npos) << json;
  EXPECT_EQ(runCapture(SIM + joint + " --backlash 0.002618 2>&1 >/dev/null", &code), "");
  EXPECT_EQ(runCapture(SIM + " 2>&1 >/dev/null", &code), "");  // (the thesis' D1: ρ = 1, Δ = 0.3 rad)
}

// --config: a YAML file of the joint's keys (a range LO:HI as on the command line) gives the same answer as the
// flags, and flags override it.
TEST(Design, ConfigFileEqualsTheFlags)
{
  const std::string yaml = testing::TempDir() + "backlash_design_joint.yaml";
  std::ofstream(yaml) << "motor_inertia: 0.1\nmotor_friction: 0.48\nload_inertia: 0.9\nload_friction: 0.32\n"
                         "restitution: 0.5\nbacklash: 0.05\ngain: 1\ncontrol_law: pid\ncontroller_rate: 100\n"
                         "feedback: motor\nderivative_gain: 0.3\nintegral_gain: \"0.01:100\"\n";
  const std::string flags =
      " --motor-inertia 0.1 --motor-friction 0.48 --load-inertia 0.9 --load-friction 0.32 --restitution 0.5"
      " --backlash 0.05 --gain 1 --control-law pid --controller-rate 100 --feedback motor --derivative-gain 0.3"
      " --integral-gain 0.01:100";
  int code = 0;
  const std::string search = " --tune integral-gain --find max-gain --json";
  const std::string by_flags = runCapture(DESIGN + flags + search, &code);
  ASSERT_EQ(code, 0) << by_flags;
  const std::string by_file = runCapture(DESIGN + " --config " + yaml + search, &code);
  ASSERT_EQ(code, 0) << by_file;
  EXPECT_EQ(by_file, by_flags);
  const std::string overridden = runCapture(DESIGN + " --config " + yaml + " --json --integral-gain 0.5", &code);
  ASSERT_EQ(code, 0) << overridden;
  EXPECT_EQ(overridden, runCapture(DESIGN + flags + " --json --integral-gain 0.5", &code));
  // An unknown key in the file is one line naming it and the file.
  std::ofstream(yaml, std::ios::app) << "motor_inertai: 1\n";
  const std::string err = runCapture(DESIGN + " --config " + yaml + " 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("motor_inertai"), std::string::npos) << err;
}

// A real single-node Slurm (slurmctld, slurmd, munge started and stopped by the script): scripts/slurm_sweep.sh's
// and scripts/slurm_frf.sh's array jobs and dependent merge jobs write exactly the CSV of an unsharded run.
TEST(Slurm, ArrayJobPlusMergeEqualsTheUnshardedSweep)
{
  int code = 0;
  const std::string log =
      runCapture("timeout 300 bash " + std::string(SOURCE_DIR) + "/test/slurm/local_slurm_sweep.sh 4 2>&1", &code);
  EXPECT_EQ(code, 0) << log;
  EXPECT_NE(log.find("4-part array job + merge job = the unsharded CSV"), std::string::npos) << log;
  EXPECT_NE(log.find("3-part backlash_frf array job + merge job = the unsharded CSV"), std::string::npos) << log;
}

// The workbench's numbers against backlash_sim runs of the same flags: verdict and cycle error, and the RMS
// tracking error and RMS torque recomputed here from backlash_sim's CSV samples at the same instants.
TEST(Compare, MetricsAgreeWithSingleRunsAndCsvSamples)
{
  const std::string joint =
      "backlash: 0.05\nrestitution: 0.5\nload_coulomb_friction: 0.02\nload_static_friction: 0.05\n"
      "controller_rate: 1000\ncommand: 1.0\nduration: 30\nsample_rate: 1000\n";
  const std::string yaml = "/tmp/backlash_compare_test.yaml";
  std::ofstream(yaml) << joint
                      << "strategies:\n"
                         "  - {name: P, control_law: proportional}\n"
                         "  - {name: PID, control_law: pid, integral_gain: 0.5, derivative_gain: 0.3}\n"
                         "  - {name: PID+dither, control_law: pid, integral_gain: 0.5, derivative_gain: 0.3,"
                         " compensation: dither, dither_amplitude: 0.01, dither_frequency: 50}\n"
                         "  - {name: continuous+dither, controller_rate: 0, compensation: dither,"
                         " dither_amplitude: 0.01, dither_frequency: 5}\n";
  int code = 0;
  const std::string json = runCapture(COMPARE + " --config " + yaml + " --json --jobs 2", &code);
  ASSERT_EQ(code, 0) << json;
  const std::vector<std::string> flags = {
      "--controller-rate 1000 --control-law proportional",
      "--controller-rate 1000 --control-law pid --integral-gain 0.5 --derivative-gain 0.3",
      "--controller-rate 1000 --control-law pid --integral-gain 0.5 --derivative-gain 0.3 --compensation dither "
      "--dither-amplitude 0.01 --dither-frequency 50",
      "--compensation dither --dither-amplitude 0.01 --dither-frequency 5"};  // the continuous law, exact
  std::size_t pos = 0;
  for (std::size_t i = 0; i < flags.size(); ++i)
  {
    pos = json.find("{\"name\"", pos + 1);
    ASSERT_NE(pos, std::string::npos);
    const std::string entry = json.substr(pos, json.find('}', pos) - pos + 1);
    const std::string sim = SIM +
                            " --backlash 0.05 --restitution 0.5 --load-coulomb-friction 0.02 --load-static-friction "
                            "0.05 --duration 30 " +
                            flags[i];
    const std::string cli = runCapture(sim + " --json");
    EXPECT_EQ(jsonText(entry, "verdict"), jsonText(cli, "verdict")) << flags[i];
    if (jsonText(cli, "verdict") == "limit_cycle")
    {
      EXPECT_EQ(jsonNumber(entry, "limit_cycle_error"), jsonNumber(cli, "limit_cycle_error")) << flags[i];
    }
    else
    {
      EXPECT_NE(entry.find("\"limit_cycle_error\":null"), std::string::npos) << entry;
    }
    const std::string csv = "/tmp/backlash_compare_test.csv";
    runCapture(sim + " --csv " + csv + " --sample-rate 1000");
    double e2 = 0.0, t2 = 0.0;
    long n = 0;
    std::vector<std::pair<double, double>> errors;  // (t, e)
    for (const auto& r : csvRows(readFile(csv)))
    {
      if (r.size() >= 9 && (r.size() == 9 || r[9].empty()))  // sample rows (t = 0 included), not event rows
      {
        const double e = 1.0 - std::stod(r[1]);
        e2 += e * e;
        t2 += std::stod(r[8]) * std::stod(r[8]);
        ++n;
        errors.emplace_back(std::stod(r[0]), e);
      }
    }
    EXPECT_EQ(n, 30001);
    EXPECT_NEAR(jsonNumber(entry, "rms_error"), std::sqrt(e2 / n), 1e-9) << flags[i];
    EXPECT_NEAR(jsonNumber(entry, "rms_torque"), std::sqrt(t2 / n), 1e-9) << flags[i];
    // Settling into the joint's own band — here the backlash, 0.05 rad (ideal encoders) — and the RMS error after
    // that transient, recomputed from the samples.
    double last_outside = -1.0;
    for (const auto& [t, e] : errors)
    {
      last_outside = std::fabs(e) > 0.05 ? t : last_outside;
    }
    const bool settled = last_outside < errors.back().first;
    const double from = settled ? std::max(last_outside, 0.0) : 15.0;
    double s2 = 0.0;
    long k = 0;
    for (const auto& [t, e] : errors)
    {
      if (t >= from)
      {
        s2 += e * e;
        ++k;
      }
    }
    if (settled)
    {
      EXPECT_NEAR(jsonNumber(entry, "settling_time"), std::max(last_outside, 0.0), 1e-9) << flags[i];
    }
    EXPECT_NEAR(jsonNumber(entry, "steady_rms_error"), std::sqrt(s2 / k), 1e-9) << flags[i];
  }
  // The chart and the CSV table are written.
  const std::string png = "/tmp/backlash_compare_test.png", table = "/tmp/backlash_compare_table.csv";
  std::remove(png.c_str());
  runCapture(COMPARE + " --config " + yaml + " --png " + png + " --csv " + table + " >/dev/null 2>&1", &code);
  ASSERT_EQ(code, 0);
  struct stat st;
  EXPECT_EQ(stat(png.c_str(), &st), 0);
  EXPECT_GT(st.st_size, 10000);
  EXPECT_EQ(csvRows(readFile(table)).size(), 4u);
  // Bad files are one clear line.
  std::ofstream(yaml) << joint << "strategies:\n  - {name: X, control_law: pid, integral_gian: 1}\n";
  const std::string err = runCapture(COMPARE + " --config " + yaml + " 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("integral_gian"), std::string::npos) << err;
}

// On a compliant joint the impact columns count what the mesh does instead: contact phases begun per second (the
// CSV's engagement rows of backlash_sim) and the mesh's losses per second (its energy.mesh_loss).
TEST(Compare, ACompliantStrategyCountsContactPhasesAndMeshLosses)
{
  const std::string yaml = "/tmp/backlash_compare_compliant_test.yaml";
  std::ofstream(yaml) << "backlash: 0.05\nmesh_stiffness: 1000\nmesh_damping: 2\ncontroller_rate: 200\n"
                         "command: 1.0\nduration: 20\nsample_rate: 100\n"
                         "strategies:\n  - {name: PID, control_law: pid, integral_gain: 0.5, derivative_gain: 0.3}\n";
  int code = 0;
  const std::string json = runCapture(COMPARE + " --config " + yaml + " --json", &code);
  ASSERT_EQ(code, 0) << json;
  const std::string sim = SIM +
                          " --backlash 0.05 --mesh-stiffness 1000 --mesh-damping 2 --controller-rate 200 --control-law "
                          "pid --integral-gain 0.5 --derivative-gain 0.3 --duration 20";
  const std::string cli = runCapture(sim + " --json");
  const std::string csv = "/tmp/backlash_compare_compliant_test.csv";
  runCapture(sim + " --csv " + csv);
  long engagements = 0;
  for (const auto& r : csvRows(readFile(csv)))
  {
    engagements += r.size() >= 10 && r[9] == "engagement";
  }
  EXPECT_GT(engagements, 5);
  EXPECT_NEAR(jsonNumber(json, "impacts_per_second"), engagements / 20.0, 1e-12);
  const double mesh_loss = jsonNumber(cli.substr(cli.find("\"energy\"")), "mesh_loss");
  EXPECT_GT(mesh_loss, 0.0);
  EXPECT_NEAR(jsonNumber(json, "impact_energy_per_second"), mesh_loss / 20.0, 1e-12 * mesh_loss);
}

// --vary: every strategy re-run at each value of a plant key (factors of the file's value, or absolute values); each
// row equals backlash_sim with that value and the strategy's own settings (the compensator's estimate stays), and a
// key the strategy overrides is varied around its own value.
TEST(Compare, VaryRerunsEveryStrategyOverTheRange)
{
  const std::string yaml = "/tmp/backlash_compare_vary.yaml";
  std::ofstream(yaml) << "backlash: 0.05\nrestitution: 0.5\nload_coulomb_friction: 0.02\nload_static_friction: "
                         "0.05\ncontroller_rate: 1000\ncommand: 1.0\nduration: 30\n"
                         "strategies:\n"
                         "  - {name: PID, control_law: pid, integral_gain: 0.5, derivative_gain: 0.3}\n"
                         "  - {name: P wide, control_law: proportional, backlash: 0.1}\n";
  int code = 0;
  const std::string json = runCapture(COMPARE + " --config " + yaml + " --vary backlash=0.5:1.5:3 --json", &code);
  ASSERT_EQ(code, 0) << json;
  EXPECT_NE(json.find("\"vary\":{\"key\":\"backlash\",\"absolute\":false}"), std::string::npos) << json;
  const std::vector<std::pair<std::string, double>> strategies = {
      {"--control-law pid --integral-gain 0.5 --derivative-gain 0.3", 0.05}, {"--control-law proportional", 0.1}};
  std::size_t pos = 0;
  int rows = 0;
  for (const auto& st : strategies)
  {
    for (double factor : {0.5, 1.0, 1.5})
    {
      pos = json.find("{\"value\"", pos + 1);
      ASSERT_NE(pos, std::string::npos);
      const std::string entry = json.substr(pos, json.find('}', pos) - pos + 1);
      EXPECT_DOUBLE_EQ(jsonNumber(entry, "value"), factor * st.second) << entry;
      char value[32];
      std::snprintf(value, sizeof value, "%.17g", jsonNumber(entry, "value"));
      const std::string cli =
          runCapture(SIM +
                     " --json --restitution 0.5 --load-coulomb-friction 0.02 --load-static-friction 0.05 "
                     "--controller-rate 1000 --duration 30 --backlash " +
                     value + " " + st.first);
      EXPECT_EQ(jsonText(entry, "verdict"), jsonText(cli, "verdict")) << entry;
      if (jsonText(cli, "verdict") == "limit_cycle")
      {
        EXPECT_EQ(jsonNumber(entry, "limit_cycle_error"), jsonNumber(cli, "limit_cycle_error")) << entry;
      }
      ++rows;
    }
  }
  EXPECT_EQ(rows, 6);
  // Absolute values; the CSV has the key as its second column; bad requests are one line, exit 2.
  const std::string table = "/tmp/backlash_compare_vary.csv";
  runCapture(
      COMPARE + " --config " + yaml + " --vary backlash=0.02:0.04:2 --absolute --csv " + table + " >/dev/null 2>&1",
      &code);
  ASSERT_EQ(code, 0);
  const auto csv = csvRows(readFile(table));
  ASSERT_EQ(csv.size(), 4u);  // 2 strategies × 2 values
  EXPECT_EQ(readFile(table).rfind("name,backlash,verdict,", 0), 0u);
  EXPECT_EQ(std::stod(csv[1][1]), 0.04);
  for (const char* bad : {" --vary backlash=0.5:1.5", " --vary backlsh=1:2:3", " --vary backlash=1:2:1", " --absolute",
                          " --vary load_torque=0.5:2:3"})
  {
    const std::string err = runCapture(COMPARE + " --config " + yaml + std::string(bad) + " 2>&1 >/dev/null", &code);
    EXPECT_EQ(code, 2) << bad;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << bad << ": " << err;
  }
}

// backlash_servo.launch: the YAML's keys win unless the launch arg is given; use_sim_time and ns are independent args.
// /use_sim_time follows each launch file's clock args (roslaunch's arg() gives booleans, not text, in $(eval)).
TEST(Launch, UseSimTimeFollowsTheClockArgsOfEveryLaunchFile)
{
  const auto dump = [](const std::string& args) {
    int code = 0;
    const std::string out =
        runCapture("PATH=/usr/bin:$PATH roslaunch --dump-params backlash_servo " + args + " 2>&1", &code);
    EXPECT_EQ(code, 0) << out;
    const bool on = out.find("/use_sim_time: true") != std::string::npos;
    EXPECT_TRUE(on || out.find("/use_sim_time: false") != std::string::npos) << out;
    return on;
  };
  EXPECT_FALSE(dump("backlash_servo.launch"));
  EXPECT_TRUE(dump("backlash_servo.launch publish_clock:=true"));
  EXPECT_TRUE(dump("backlash_servo.launch publish_clock:=True"));
  EXPECT_FALSE(dump("backlash_servo.launch publish_clock:=false"));
  EXPECT_TRUE(dump("backlash_servo.launch use_sim_time:=true"));  // an external clock
  EXPECT_FALSE(dump("backlash_servo.launch publish_clock:=true use_sim_time:=false"));
  EXPECT_TRUE(dump("thesis_limit_cycle.launch"));
  EXPECT_TRUE(dump("external_controller.launch"));
  EXPECT_TRUE(dump("external_controller.launch controller:=python"));
  EXPECT_TRUE(dump("external_controller.launch controller:=none"));
  // An unknown controller stops the launch with a line naming the choices (--dump-params itself exits 0).
  const std::string bad = runCapture(
      "PATH=/usr/bin:$PATH roslaunch --dump-params backlash_servo external_controller.launch controller:=mine 2>&1");
  EXPECT_EQ(bad.find("/use_sim_time"), std::string::npos) << bad;
  EXPECT_NE(bad.find("controller_must_be_example_python_or_none"), std::string::npos) << bad;
}

// The user documentation cannot go stale: every ```sh block and every "$ " transcript of README.md and docs/*.md is
// run (transcripts must print what they show) and every relative link must name a file (scripts/check_docs.py).
TEST(Docs, EveryCommandInTheDocsRunsAndPrintsWhatItShows)
{
  int code = 0;
  const std::string out = runCapture(
      "PATH=/usr/bin:$PATH /usr/bin/python3 " + std::string(SOURCE_DIR) + "/scripts/check_docs.py 2>&1", &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find(" 0 failures"), std::string::npos) << out;
}

TEST(Launch, YamlKeysWinUnlessArgsAreGiven)
{
  const std::string yaml = "/tmp/backlash_launch_precedence.yaml";
  std::ofstream(yaml) << "real_time_factor: 7.0\npublish_rate: 50.0\nstop_after: 3.0\npublish_clock: true\n";
  const std::string dump =
      "PATH=/usr/bin:$PATH roslaunch --dump-params backlash_servo backlash_servo.launch config:=" + yaml + " 2>&1";
  int code = 0;
  const std::string plain = runCapture(dump, &code);
  ASSERT_EQ(code, 0) << plain;
  EXPECT_NE(plain.find("/backlash_servo/real_time_factor: 7.0"), std::string::npos) << plain;
  EXPECT_NE(plain.find("/backlash_servo/publish_rate: 50.0"), std::string::npos) << plain;
  EXPECT_NE(plain.find("/backlash_servo/stop_after: 3.0"), std::string::npos) << plain;
  const std::string given = runCapture(dump + " real_time_factor:=2 ns:=robot1 use_sim_time:=true", &code);
  ASSERT_EQ(code, 0) << given;
  EXPECT_NE(given.find("/robot1/backlash_servo/real_time_factor: 2"), std::string::npos) << given;
  EXPECT_NE(given.find("/robot1/backlash_servo/publish_rate: 50.0"), std::string::npos) << given;
  EXPECT_NE(given.find("/use_sim_time: true"), std::string::npos) << given;
  // external_controller.launch: the YAML's set-point and lockstep setting are not replaced by unset args (the node
  // would judge against a command the user never gave); given args win; without either, the launch's defaults.
  const std::string ext_yaml = "/tmp/backlash_launch_external.yaml";
  std::ofstream(ext_yaml) << "command: 0.5\nsync: false\n";
  const std::string ext =
      "PATH=/usr/bin:$PATH roslaunch --dump-params backlash_servo external_controller.launch config:=" + ext_yaml;
  const std::string from_file = runCapture(ext + " 2>&1", &code);
  ASSERT_EQ(code, 0) << from_file;
  EXPECT_NE(from_file.find("/backlash_servo/command: 0.5"), std::string::npos) << from_file;
  EXPECT_NE(from_file.find("/backlash_servo/sync: false"), std::string::npos) << from_file;
  EXPECT_NE(from_file.find("/backlash_servo/publish_rate: 100.0"), std::string::npos) << from_file;
  EXPECT_EQ(from_file.find("/controller/command"), std::string::npos) << from_file;  // it reads the servo's
  const std::string ext_given = runCapture(ext + " command:=0.3 sync:=true controller:=python 2>&1", &code);
  ASSERT_EQ(code, 0) << ext_given;
  EXPECT_NE(ext_given.find("/backlash_servo/command: 0.3"), std::string::npos) << ext_given;
  EXPECT_NE(ext_given.find("/controller/command: 0.3"), std::string::npos) << ext_given;
  EXPECT_NE(ext_given.find("/backlash_servo/sync: true"), std::string::npos) << ext_given;
}

TEST(Charts, ScriptsRunHeadlessAndWriteImages)
{
  const std::string out = "/tmp/backlash_charts_test";
  int code = 0;
  const std::string log =
      runCapture("bash " + std::string(SOURCE_DIR) + "/scripts/make_charts.sh --quick " + out + " 2>&1", &code);
  ASSERT_EQ(code, 0) << log;
  for (const char* name : {"existence_maps", "existence_surface", "limit_cycle_error", "error_vs_backlash",
                           "phase_portrait_fig31", "digital_drive", "compliant_joint"})
  {
    for (const char* ext : {".png", ".svg"})
    {
      struct stat st;
      const std::string path = out + "/" + name + ext;
      ASSERT_EQ(stat(path.c_str(), &st), 0) << path;
      EXPECT_GT(st.st_size, 5000) << path;
    }
  }
}

TEST(Bench, HarnessRunsAndTheAccuracyComparisonHolds)
{
  // Only that it runs and that accuracy holds (ours vs an independent tight-tolerance reference, and better than
  // the thesis' fixed-step method); never a timing.
  int code = 0;
  const std::string ref = "/tmp/backlash_bench_reference.txt";
  const std::string out = runCapture(std::string(BENCH_CORE_EXE) + " --quick --reference-out " + ref, &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("accuracy check: ours agrees"), std::string::npos) << out;
  const std::string py = runCapture(
      "/usr/bin/python3 " + std::string(SOURCE_DIR) + "/bench/scipy_baseline.py " + ref + " --max-sim 5", &code);
  EXPECT_EQ(code, 0) << py;
  EXPECT_NE(py.find("thesis_d1"), std::string::npos) << py;
  // The one-solution mode bench/thesis_vs_scipy.sh times solves App. D1: over 10 s it passes the first maximum
  // (3.47 s, thesis Table D1: 3.38 s with fixed 0.01 s steps) and not the second (11.19 s).
  const std::string d1 =
      runCapture("/usr/bin/python3 " + std::string(SOURCE_DIR) + "/bench/scipy_baseline.py --d1 10", &code);
  EXPECT_EQ(code, 0) << d1;
  EXPECT_NE(d1.find("scipy D1: 1 maxima"), std::string::npos) << d1;
}

namespace
{
TEST(SweepOutput, RefusesDevicesAndGridsItDidNotWrite)
{
  int code = 0;
  const std::string err = runCapture(std::string(BACKLASH_SWEEP_EXE) + " --output /dev/null 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("not a regular file"), std::string::npos) << err;
  // --resume with a file from a different grid is refused, and the file is left as it was.
  const std::string part = ::testing::TempDir() + "sweep_other_grid.csv";
  runCapture(std::string(BACKLASH_SWEEP_EXE) + " --zeta 0.3,0.4 --output " + part + " 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  const std::string before = readFile(part);
  const std::string refused =
      runCapture(std::string(BACKLASH_SWEEP_EXE) + " --zeta 0.5,0.6 --output " + part + " --resume 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(refused.find("different grid"), std::string::npos) << refused;
  EXPECT_EQ(readFile(part), before);
  // A grid too large to hold is refused before anything is allocated.
  runCapture(
      std::string(BACKLASH_SWEEP_EXE) + " --zeta 0:1:10000 --inertia-ratio 1:2:10000 --friction-ratio 0:1:10000 2>&1",
      &code);
  EXPECT_EQ(code, 2);
}
}  // namespace

namespace
{
TEST(JointCases, ImplementedReferenceCasesAgreeToOneMicro)
{
  // test/joint_cases/reference_cases.json: cases whose Part-2 features are implemented must agree (maxima to 1e-6 rad
  // and 1e-6 s, verdict, limit-cycle and steady errors); the others are listed as skipped with what they need.
  int code = 0;
  const std::string out = runCapture("/usr/bin/python3 " + std::string(SOURCE_DIR) +
                                         "/test/joint_cases/check_joint_cases.py " + BACKLASH_SIM_EXE + " 2>&1",
                                     &code);
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 0) << out;
  EXPECT_NE(out.find("PASSED  preload_large_D1"), std::string::npos) << out;
}
}  // namespace

namespace
{
TEST(SweepShards, PartsInAnyOrderMergeIntoExactlyTheUnshardedCsv)
{
  const std::string dir = ::testing::TempDir();
  const std::string grid = " --zeta 0.1,0.3,0.5 --inertia-ratio 0.25,9 --friction-ratio 0,0.5 --restitution 0.6,1";
  const std::string sweep = std::string(BACKLASH_SWEEP_EXE) + grid;
  int code = 0;
  runCapture(sweep + " --output " + dir + "shard_whole.csv 2>/dev/null", &code);
  ASSERT_EQ(code, 0);
  for (int k : {4, 2, 1, 3})
  {
    runCapture(sweep + " --shard " + std::to_string(k) + "/4 --output " + dir + "shard_" + std::to_string(k) +
                   ".csv 2>/dev/null",
               &code);
    ASSERT_EQ(code, 0) << k;
  }
  const std::string merge = std::string(BACKLASH_SWEEP_EXE) + " --merge ";
  runCapture(merge + dir + "shard_3.csv " + dir + "shard_1.csv " + dir + "shard_4.csv " + dir +
                 "shard_2.csv --output " + dir + "shard_merged.csv 2>/dev/null",
             &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "shard_merged.csv"), readFile(dir + "shard_whole.csv"));
  // Missing, twice, another grid, incomplete: refused, nothing written.
  const std::string out = " --output " + dir + "shard_bad.csv 2>&1";
  std::remove((dir + "shard_bad.csv").c_str());
  std::string err = runCapture(merge + dir + "shard_1.csv " + dir + "shard_2.csv " + dir + "shard_3.csv" + out, &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(err.find("missing part(s) 4"), std::string::npos) << err;
  err = runCapture(merge + dir + "shard_1.csv " + dir + "shard_1.csv " + dir + "shard_2.csv " + dir + "shard_3.csv " +
                       dir + "shard_4.csv" + out,
                   &code);
  EXPECT_NE(err.find("given twice"), std::string::npos) << err;
  runCapture(std::string(BACKLASH_SWEEP_EXE) + " --zeta 0.2,0.4 --shard 4/4 --output " + dir + "shard_other.csv 2>&1",
             &code);
  err = runCapture(
      merge + dir + "shard_1.csv " + dir + "shard_2.csv " + dir + "shard_3.csv " + dir + "shard_other.csv" + out,
      &code);
  EXPECT_NE(err.find("another sweep"), std::string::npos) << err;
  const std::string part = readFile(dir + "shard_2.csv");
  std::ofstream(dir + "shard_torn.csv") << part.substr(0, part.size() - 20);
  err = runCapture(
      merge + dir + "shard_1.csv " + dir + "shard_torn.csv " + dir + "shard_3.csv " + dir + "shard_4.csv" + out, &code);
  EXPECT_NE(err.find("finish it with --resume"), std::string::npos) << err;
  EXPECT_FALSE(std::ifstream(dir + "shard_bad.csv").good());
  // A torn part is finished by --resume into the same part.
  runCapture(sweep + " --shard 2/4 --resume --output " + dir + "shard_torn.csv 2>/dev/null", &code);
  EXPECT_EQ(code, 0);
  EXPECT_EQ(readFile(dir + "shard_torn.csv"), part);
}
}  // namespace

TEST(Design, SearchRangesOutsideAKeysRangeAreRefusedNeverAborted)
{
  const std::string joint =
      DESIGN +
      " --motor-inertia 1 --load-inertia 1 --motor-friction 0.4 --load-friction 0.4 --backlash 0.3"
      " --restitution 0.5";
  struct Case
  {
    std::string flags, says;
  };
  for (const Case& c : std::vector<Case>{{" --gain 1e-300:1e300 --find max-gain", "gain: must be in"},
                                         {" --gain 1:1e13 --find max-gain", "(got 10000000000000)"},
                                         {" --gear-ratio 1e-9:1e9 --find gear-ratio", "gear_ratio: must be in"}})
  {
    int code = -1;
    const std::string out = runCapture(joint + c.flags + " 2>&1", &code);
    EXPECT_EQ(code, 2) << c.flags << "\n" << out;  // a one-line refusal, not SIGABRT (134)
    EXPECT_NE(out.find(c.says), std::string::npos) << c.flags << "\n" << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  }
  // The default range of a large integral gain (value/1000 … value·1000) is clipped to the key's range.
  int code = -1;
  const std::string out = runCapture(joint +
                                         " --controller-rate 1000 --control-law pid --tune integral-gain"
                                         " --integral-gain 1e12 --find max-gain --json 2>/dev/null",
                                     &code);
  EXPECT_EQ(code, 0) << out;
  EXPECT_EQ(out.find("1e+15"), std::string::npos) << out;
}

// backlash_df's classical prediction is the harmonic balance of the thesis' linear servo x'' + 2ζω_n x' = ω_n²(θ_R −
// θ_c) with the backlash as hysteresis, against its closed form (test_helpers::typeOneLoopCycles). Its simulated cycle
// is backlash_sim's: the frequency is 2π over the run's period, and the amplitude is the fundamental of ρθ_m over the
// last period of backlash_sim's own CSV samples.
TEST(DescribingFunctionTool, PredictsByHarmonicBalanceAndMeasuresTheExactCycle)
{
  const std::string joint = " --zeta 0.1 --inertia-ratio 9 --friction-ratio 0.4 --restitution 1 --backlash 0.3";
  int code = 0;
  const std::string json = runCapture(DF + joint + " --json", &code);
  ASSERT_EQ(code, 0) << json;
  // The closed-form balance (ω_n = 1: G = 1/(s² + 2ζ s)).
  const std::vector<test_helpers::BalanceRoot> roots = test_helpers::typeOneLoopCycles(1.0, 0.2, 1.0, 0.3);
  ASSERT_EQ(roots.size(), 2u);
  const std::regex prediction("\\{\"amplitude\":([0-9.eE+-]+),\"frequency\":([0-9.eE+-]+),\"stable\":(true|false)");
  std::vector<std::smatch> found;
  for (std::sregex_iterator it(json.begin(), json.end(), prediction), end; it != end; ++it)
  {
    found.push_back(*it);
  }
  ASSERT_EQ(found.size(), 2u) << json;
  for (std::size_t i = 0; i < 2; ++i)
  {
    EXPECT_NEAR(std::stod(found[i][1]), roots[i].amplitude, 1e-8);
    EXPECT_NEAR(std::stod(found[i][2]), roots[i].frequency, 1e-6);
    EXPECT_EQ(found[i][3] == "true", roots[i].stable);
  }
  // The simulated cycle against backlash_sim's run of the same joint.
  const std::string csv_path = testing::TempDir() + "backlash_df_cycle.csv";
  const std::string sim = runCapture(SIM + joint + " --json --sample-rate 2000 --csv " + csv_path, &code);
  ASSERT_EQ(code, 0) << sim;
  ASSERT_EQ(jsonText(sim, "verdict"), "limit_cycle");
  const double period = jsonNumber(sim, "period"), end = jsonNumber(sim, "simulated_time");
  EXPECT_EQ(jsonText(json, "verdict"), "limit_cycle");
  EXPECT_NEAR(jsonNumber(json.substr(json.find("\"simulated\"")), "frequency"), 2.0 * 3.14159265358979 / period, 1e-9);
  std::ifstream in(csv_path);
  std::string line;
  std::getline(in, line);
  double b1 = 0.0, a1 = 0.0, count = 0.0;
  while (std::getline(in, line))
  {
    std::vector<std::string> cells;
    std::stringstream row(line);
    for (std::string cell; std::getline(row, cell, ',');)
    {
      cells.push_back(cell);
    }
    if (cells.size() < 9 || (cells.size() > 9 && !cells[9].empty()))
    {
      continue;  // an event row (a sample row ends with an empty event cell)
    }
    const double t = std::stod(cells[0]);
    if (t < end - period || t >= end)
    {
      continue;
    }
    const double theta = 2.0 * 3.14159265358979 * t / period;
    b1 += std::stod(cells[3]) * std::sin(theta);  // ρ = 1: the backlash input is θ_m
    a1 += std::stod(cells[3]) * std::cos(theta);
    ++count;
  }
  ASSERT_GT(count, 1000.0);
  const double amplitude = 2.0 / count * std::hypot(a1, b1);
  EXPECT_NEAR(jsonNumber(json.substr(json.find("\"simulated\"")), "amplitude"), amplitude, 2e-3 * amplitude);
  std::remove(csv_path.c_str());
}

// D1 (ζ = 0.4) limit-cycles, yet the classical DF predicts no cycle: said, not hidden; laws the analysis does not
// take are refused naming the key; a digital P law is analysed.
TEST(DescribingFunctionTool, SaysWhenTheClassicalDfSeesNoCycleAndRefusesOtherLaws)
{
  int code = 0;
  const std::string json =
      runCapture(DF + " --config " + std::string(SOURCE_DIR) + "/config/thesis_limit_cycle.yaml --json", &code);
  ASSERT_EQ(code, 0) << json;
  EXPECT_NE(json.find("\"predictions\":[]"), std::string::npos) << json;
  EXPECT_EQ(jsonText(json, "verdict"), "limit_cycle");
  const std::string counts = runCapture(DF + " --controller-rate 100 --control-law cascade --position-loop-gain 1 "
                                             "--velocity-loop-gain 1 --motor-encoder-resolution 4096 2>&1",
                                        &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(counts.find("motor_encoder_resolution"), std::string::npos) << counts;
  const std::string none = runCapture(DF + " --backlash 0 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(none.find("backlash: must be > 0"), std::string::npos) << none;
  // A digital P law: its line in the report.
  const std::string digital = runCapture(
      DF + " --zeta 0.1 --inertia-ratio 1 --friction-ratio 0.4 --restitution 0 --controller-rate 100", &code);
  EXPECT_EQ(code, 0) << digital;
  EXPECT_NE(digital.find("law: digital P on the load's angle at 100 Hz"), std::string::npos) << digital;
  // A compliant mesh: the classical DF of its dead zone, said so, beside the compliant element's numerical one.
  const std::string compliant = runCapture(
      DF + " --zeta 0.1 --inertia-ratio 1 --friction-ratio 0.4 --mesh-stiffness 3 --mesh-damping 0.3", &code);
  EXPECT_EQ(code, 0) << compliant;
  EXPECT_NE(compliant.find("the dead zone of the compliant mesh"), std::string::npos) << compliant;
  EXPECT_NE(compliant.find("predicted (numerical DF of the real element)"), std::string::npos) << compliant;
  // --png: a PNG (its signature) through the safe-write path; any other name refused before the run.
  const std::string png = testing::TempDir() + "backlash_df_chart.png";
  std::remove(png.c_str());
  runCapture(DF + " --zeta 0.1 --inertia-ratio 1 --friction-ratio 0.4 --restitution 0 --png " + png + " 2>&1", &code);
  ASSERT_EQ(code, 0);
  std::ifstream chart(png, std::ios::binary);
  char signature[8] = {};
  chart.read(signature, 8);
  EXPECT_EQ(std::string(signature + 1, 3), "PNG");
  std::remove(png.c_str());
  const std::string txt = runCapture(DF + " --png chart.txt 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(txt.find("must end in .png"), std::string::npos) << txt;
}

TEST(FrequencyResponseTool, LockedJointGivesTheHeldTransferFunction)
{
  // Backlash 0: the joint is one body on the motor shaft, ω_m/T_m = 1/(F + jωJ) times the hold's
  // (1 − e^{−jωT})/(jωT) (J = 1, F = 0.8 for the chart form's ζ = 0.4, ω_n = 1).
  int code = 0;
  const std::string json =
      runCapture(FRF +
                     " --backlash 0 --channel motor_torque:motor_velocity --injection-rate 200 --amplitude 0.3"
                     " --frequency 0.7,3 --tolerance 1e-12 --linear --json",
                 &code);
  ASSERT_EQ(code, 0) << json;
  EXPECT_EQ(json.find("\"channel\":\"motor_torque:motor_velocity\""), 1u) << json;
  const std::regex point(
      "\\{\"amplitude\":([0-9.eE+-]+),\"frequency\":([0-9.eE+-]+),\"requested_frequency\":([0-9.eE+-]+),"
      "\"gain\":([0-9.eE+-]+),\"phase\":([0-9.eE+-]+)");
  int found = 0;
  for (std::sregex_iterator it(json.begin(), json.end(), point), end; it != end; ++it, ++found)
  {
    const std::smatch& m = *it;
    const double w = std::stod(m[2]), t = 1.0 / 200.0;
    const std::complex<double> hold =
        (1.0 - std::exp(std::complex<double>(0.0, -w * t))) / std::complex<double>(0.0, w * t);
    const std::complex<double> g = 1.0 / std::complex<double>(0.8, w) * hold;
    EXPECT_NEAR(std::stod(m[4]), std::abs(g), 1e-9 * std::abs(g)) << json;
    EXPECT_NEAR(std::stod(m[5]), std::arg(g), 1e-9) << json;
    EXPECT_NEAR(w, 2.0 * 3.14159265358979 * 200.0 / std::round(2.0 * 3.14159265358979 * 200.0 / std::stod(m[3])), 1e-9);
  }
  EXPECT_EQ(found, 2) << json;
  EXPECT_NEAR(jsonNumber(json, "linear_gain"), jsonNumber(json, "gain"), 1e-12) << json;
  EXPECT_NE(json.find("\"crosses_backlash\":false"), std::string::npos) << json;
  // The same mechanics measured with a PID drive's loops closed (the set-point injection): no hold, no controller in
  // the ratio — 1/(F + jωJ) itself; the text report gives the set-point's offset as a speed.
  const std::string closed = runCapture(FRF +
                                            " --backlash 0 --controller-rate 1000 --control-law pid --integral-gain 0.5"
                                            " --derivative-gain 0.5 --channel torque_setpoint:motor_velocity"
                                            " --amplitude 0.1 --frequency 5 --tolerance 1e-12 --json",
                                        &code);
  ASSERT_EQ(code, 0) << closed;
  const double w = jsonNumber(closed, "frequency");
  const std::complex<double> mechanics = 1.0 / std::complex<double>(0.8, w);
  EXPECT_NEAR(jsonNumber(closed, "gain"), std::abs(mechanics), 1e-9 * std::abs(mechanics)) << closed;
  EXPECT_NEAR(jsonNumber(closed, "phase"), std::arg(mechanics), 1e-9) << closed;
  const std::string text =
      runCapture(FRF +
                     " --backlash 0.3 --restitution 0.8 --controller-rate 1000 --channel torque_setpoint:load_velocity"
                     " --offset 0.5 --amplitude 0.02 --frequency 5",
                 &code);
  ASSERT_EQ(code, 0) << text;
  EXPECT_NE(text.find("offset 0.5 rad/s; gain in (rad/s)/(N*m)"), std::string::npos) << text;
  const std::string refused =
      runCapture(FRF + " --channel torque_setpoint:motor_velocity --amplitude 0.1 --frequency 5 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(refused.find("controller_rate"), std::string::npos) << refused;
}

// A sine torque on the load, the continuous P law holding (backlash 0): θ_c/T_ext = 1/(K − Jω² + jωF) (D1, ρ = 1:
// −1.25j at ω_n = 1 rad/s), its unit named; broadband refuses the channel naming it.
TEST(FrequencyResponseTool, ALoadTorqueSineGivesTheDynamicCompliance)
{
  int code = 0;
  const std::string json = runCapture(
      FRF + " --backlash 0 --channel load_torque:load_position --amplitude 0.3 --frequency 1 --tolerance 1e-12 --json",
      &code);
  ASSERT_EQ(code, 0) << json;
  EXPECT_NEAR(jsonNumber(json, "gain"), 1.25, 1e-9) << json;
  EXPECT_NEAR(jsonNumber(json, "phase"), -0.5 * 3.14159265358979323846, 1e-9) << json;
  const std::string text = runCapture(
      FRF + " --backlash 0 --channel load_torque:load_position --amplitude 0.3 --frequency 1 --offset 0.1", &code);
  ASSERT_EQ(code, 0) << text;
  EXPECT_NE(text.find("offset 0.1 N*m; gain in rad/(N*m)"), std::string::npos) << text;
  const std::string broadband = runCapture(FRF +
                                               " --controller-rate 100 --channel load_torque:load_position "
                                               "--excitation prbs --amplitude 0.1 2>&1",
                                           &code);
  EXPECT_NE(code, 0);
  EXPECT_NE(broadband.find("load_torque:load_position"), std::string::npos) << broadband;
}

TEST(FrequencyResponseTool, BacklashPointsCsvChartAndRefusals)
{
  int code = 0;
  // D1 under a 100 Hz P drive: a large sine crosses the backlash twice a period and settles; the CSV has a row per
  // point; the chart is a PNG.
  const std::string csv = testing::TempDir() + "backlash_frf_points.csv";
  const std::string png = testing::TempDir() + "backlash_frf_chart.png";
  std::remove(csv.c_str());
  std::remove(png.c_str());
  const std::string text = runCapture(FRF +
                                          " --controller-rate 100 --restitution 0.8 --amplitude 0.5,1 --frequency "
                                          "0.3,1 --jobs 2 --csv " +
                                          csv + " --png " + png + " 2>&1",
                                      &code);
  ASSERT_EQ(code, 0) << text;
  EXPECT_NE(text.find("the teeth cross the backlash from amplitude 0.5 on"), std::string::npos) << text;
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.rfind("amplitude,requested_frequency,frequency,gain,phase,", 0), 0u) << line;
  int rows = 0;
  while (std::getline(in, line))
  {
    ++rows;
    EXPECT_NE(line.find(",1,1,"), std::string::npos) << line;  // periodic, at the excitation's period
  }
  EXPECT_EQ(rows, 4);
  std::ifstream chart(png, std::ios::binary);
  char signature[8] = {};
  chart.read(signature, 8);
  EXPECT_EQ(std::string(signature + 1, 3), "PNG");
  std::remove(csv.c_str());
  std::remove(png.c_str());
  // Refusals, before any run.
  const std::string fast = runCapture(FRF + " --controller-rate 10 --amplitude 0.1 --frequency 20 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(fast.find("above a quarter of the sample rate"), std::string::npos) << fast;
  const std::string none = runCapture(FRF + " --controller-rate 10 --frequency 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(none.find("--amplitude is required"), std::string::npos) << none;
  const std::string channel = runCapture(FRF + " --channel torque --amplitude 1 --frequency 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(channel.find("'torque' is not a channel"), std::string::npos) << channel;
  const std::string range = runCapture(FRF + " --controller-rate 10 --amplitude 1 --frequency-range 2:1:5 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(range.find("--frequency-range"), std::string::npos) << range;
}

// One point's impact storm (its event budget exceeded) does not abort a multi-point run: that point's row has no
// figures and says why, every other point is the one a run with the default budget measures, the exit status is 0.
TEST(FrequencyResponseTool, OnePointsImpactStormLeavesTheOtherPoints)
{
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "frf_budget.yaml") << "restitution: 0.8\nmax_events: 10000\n";
  const std::string points = " --amplitude 0.05,1 --frequency 0.3,1";
  int code = 0;
  const std::string err =
      runCapture(FRF + " --config " + dir + "frf_budget.yaml" + points + " --csv - 2>&1 >/dev/null", &code);
  EXPECT_EQ(code, 0) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(err.find("stopped, no figures: event budget of 10000 impacts exceeded"), std::string::npos) << err;
  const auto limited =
      csvRows(runCapture(FRF + " --config " + dir + "frf_budget.yaml" + points + " --csv - 2>/dev/null", &code));
  const auto full = csvRows(runCapture(FRF + " --restitution 0.8" + points + " --csv - 2>/dev/null", &code));
  ASSERT_EQ(limited.size(), 4u);
  ASSERT_EQ(full.size(), 4u);
  int stopped = 0;
  for (std::size_t i = 0; i < 4; ++i)
  {
    if (limited[i][3].empty())  // (gain)
    {
      ++stopped;
      EXPECT_EQ(limited[i][8], "0");  // not periodic
    }
    else
    {
      EXPECT_EQ(limited[i], full[i]) << i;
    }
  }
  EXPECT_EQ(stopped, 1);
  const std::string json =
      runCapture(FRF + " --config " + dir + "frf_budget.yaml" + points + " --json 2>/dev/null", &code);
  EXPECT_NE(json.find("\"stopped\":\"event budget of 10000 impacts exceeded"), std::string::npos) << json;
  EXPECT_NE(json.find("\"stopped\":null"), std::string::npos) << json;
}

TEST(FrequencyResponseTool, ShardsMergeIntoTheUnshardedCsv)
{
  // Three parts computed in any order and merged = the CSV of one run; a missing part or a part of another run is
  // refused; --dry-run computes and writes nothing.
  const std::string dir = testing::TempDir() + "backlash_frf_shards/";
  std::string mkdir = "rm -rf " + dir + " && mkdir -p " + dir;
  ASSERT_EQ(std::system(mkdir.c_str()), 0);
  const std::string args = " --controller-rate 100 --restitution 0.8 --amplitude 0.5,1 --frequency 0.3,1,2";
  int code = 0;
  runCapture(FRF + args + " --csv " + dir + "whole.csv 2>&1", &code);
  ASSERT_EQ(code, 0);
  for (const char* k : {"3", "1", "2"})
  {
    runCapture(FRF + args + " --jobs 1 --shard " + k + "/3 --csv " + dir + "p" + k + ".csv 2>&1", &code);
    ASSERT_EQ(code, 0) << k;
  }
  const std::string merged = runCapture(
      FRF + " --merge " + dir + "p2.csv " + dir + "p3.csv " + dir + "p1.csv --csv " + dir + "m.csv 2>&1", &code);
  ASSERT_EQ(code, 0) << merged;
  const auto read = [](const std::string& path) {
    std::ifstream in(path);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
  const std::string whole = read(dir + "whole.csv");
  EXPECT_EQ(read(dir + "m.csv"), whole);
  EXPECT_EQ(std::count(whole.begin(), whole.end(), '\n'), 7);  // the header and six points
  const std::string missing =
      runCapture(FRF + " --merge " + dir + "p1.csv " + dir + "p2.csv --csv " + dir + "x.csv 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(missing.find("part 3/3 is missing"), std::string::npos) << missing;
  runCapture(FRF + " --controller-rate 100 --amplitude 1 --frequency 1 --shard 1/3 --csv " + dir + "q1.csv 2>&1",
             &code);
  const std::string other = runCapture(
      FRF + " --merge " + dir + "q1.csv " + dir + "p2.csv " + dir + "p3.csv --csv " + dir + "y.csv 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(other.find("another run"), std::string::npos) << other;
  runCapture(FRF + args + " --dry-run --csv " + dir + "dry.csv 2>&1", &code);
  EXPECT_EQ(code, 0);
  EXPECT_FALSE(std::ifstream(dir + "dry.csv").good());
  const std::string bad = runCapture(FRF + args + " --shard 4/3 --csv " + dir + "z.csv 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(bad.find("--shard"), std::string::npos) << bad;
}

TEST(FrequencyResponseTool, BroadbandPrbsGivesTheSampledTransferFunctionAndRefusesStrayFlags)
{
  // Backlash 0, torque → motor speed at the hold's instants: H(z) = b/(z − e), e = e^{−(F/J)T}, b = (1 − e)/F
  // (J = 1, F = 0.8); coherence 1 — the torque itself, and injected into a 50 Hz P drive's set-point (its loop closed,
  // one sample late), recorded after the automatic number of settling periods.
  for (const std::string input :
       {"--channel motor_torque:motor_velocity --injection-rate 50",
        "--channel torque_setpoint:motor_velocity --controller-rate 50 --controller-delay 1 --offset 0.5"})
  {
    int code = 0;
    const std::string json = runCapture(
        FRF + " --backlash 0 " + input + " --excitation prbs --prbs-order 7 --periods 2 --amplitude 0.5 --json", &code);
    ASSERT_EQ(code, 0) << json;
    EXPECT_EQ(jsonText(json, "excitation"), "prbs");
    EXPECT_GE(jsonNumber(json, "settle_periods"), 2.0) << json;
    const std::regex line(
        "\\{\"frequency\":([0-9.eE+-]+),\"gain\":([0-9.eE+-]+),\"phase\":([0-9.eE+-]+),"
        "\"coherence\":([0-9.eE+-]+)");
    int found = 0;
    const double ts = 1.0 / 50.0, e = std::exp(-0.8 * ts), b = (1.0 - e) / 0.8;
    for (std::sregex_iterator it(json.begin(), json.end(), line), end; it != end; ++it, ++found)
    {
      const std::smatch& m = *it;
      const std::complex<double> z = std::exp(std::complex<double>(0.0, std::stod(m[1]) * ts));
      const std::complex<double> h = b / (z - e);
      EXPECT_NEAR(std::stod(m[2]), std::abs(h), 1e-8 * std::abs(h)) << input << " " << m[1];
      EXPECT_NEAR(std::stod(m[3]), std::arg(h), 1e-8) << input << " " << m[1];
      EXPECT_NEAR(std::stod(m[4]), 1.0, 1e-8) << input << " " << m[1];
    }
    EXPECT_EQ(found, 63) << input;  // the lines 1 … 63 of a 127-sample period
  }
  int code = 0;
  const std::string stray = runCapture(FRF + " --excitation chirp --prbs-order 8 --amplitude 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(stray.find("--prbs-order does not apply to --excitation chirp"), std::string::npos) << stray;
  const std::string sine_flag =
      runCapture(FRF + " --controller-rate 20 --excitation prbs --frequency 1 --amplitude 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(sine_flag.find("sets its own frequencies"), std::string::npos) << sine_flag;
}

TEST(FrequencyResponseTool, ExactSinesOnACompliantMeshAndOnRigidTeeth)
{
  // --continuous: the sine torque itself on a compliant mesh pressed by a torque offset gives the two-mass transfer
  // function with no hold: ω_m/T_m = 1/(M + ρ²K L/(sL + K)) (M = J_m s + f_m, L = J_L s + f_L, K = c + ds).
  int code = 0;
  const std::string json = runCapture(FRF +
                                          " --backlash 0.1 --gear-ratio 0.5 --mesh-stiffness 100 --mesh-damping 1"
                                          " --channel motor_torque:motor_velocity --continuous --offset 1"
                                          " --amplitude 0.02 --frequency 19 --tolerance 1e-12 --json",
                                      &code);
  ASSERT_EQ(code, 0) << json;
  const std::complex<double> s(0.0, 19.0), m = 0.1 * s + 0.48, l = 0.9 * s + 0.32, k = 100.0 + 1.0 * s;
  const std::complex<double> g = 1.0 / (m + 0.25 * k * l / (s * l + k));
  EXPECT_NEAR(jsonNumber(json, "gain"), std::abs(g), 1e-9 * std::abs(g)) << json;
  EXPECT_NEAR(jsonNumber(json, "phase"), std::arg(g), 1e-9) << json;
  EXPECT_EQ(jsonNumber(json, "frequency"), 19.0);
  // The command under the continuous law takes the sine itself, on a compliant joint and on rigid teeth: D1 without
  // backlash gives its transfer function ρK/(ρK − Jω² + jωF_T) to 1e-9; with dry friction rigid teeth refuse it.
  const std::string law = runCapture(FRF + " --config " + std::string(SOURCE_DIR) +
                                         "/config/compliant_d1.yaml --amplitude 1 --frequency 1 "
                                         "--json",
                                     &code);
  ASSERT_EQ(code, 0) << law;
  EXPECT_EQ(jsonNumber(law, "frequency"), 1.0);
  EXPECT_NE(law.find("\"periodic\":true"), std::string::npos) << law;
  const backlash_servo::ServoParams d1;
  const double w = 0.7;
  const std::complex<double> t =
      d1.gear_ratio * d1.gain /
      (d1.gear_ratio * d1.gain - d1.totalInertia() * w * w + std::complex<double>(0.0, w * d1.totalFriction()));
  const std::string rigid = runCapture(FRF + " --backlash 0 --amplitude 0.5 --frequency 0.7 --json", &code);
  ASSERT_EQ(code, 0) << rigid;
  EXPECT_EQ(jsonNumber(rigid, "frequency"), w);
  EXPECT_NEAR(jsonNumber(rigid, "gain"), std::abs(t), 1e-9 * std::abs(t)) << rigid;
  EXPECT_NEAR(jsonNumber(rigid, "phase"), std::arg(t), 1e-9) << rigid;
  // A load torque holds the teeth on a flank: the release amplitude T_ext/|(−J_Lω² + jωf_L)T(jω)|, solved from the
  // joint without backlash.
  const std::string held =
      runCapture(FRF + " --restitution 0.8 --load-torque 0.2 --amplitude 0.1 --frequency 2 --linear --json", &code);
  ASSERT_EQ(code, 0) << held;
  const std::complex<double> t2 =
      1.0 / (1.0 - d1.totalInertia() * 4.0 + std::complex<double>(0.0, 2.0 * d1.totalFriction()));
  const double release = 0.2 / std::abs(std::complex<double>(-d1.load_inertia * 4.0, 2.0 * d1.load_friction) * t2);
  EXPECT_NEAR(jsonNumber(held, "release_amplitude"), release, 1e-9 * release) << held;
  const std::string dry = runCapture(FRF +
                                         " --motor-coulomb-friction 0.01 --motor-static-friction 0.01"
                                         " --channel motor_torque:motor_velocity --continuous --amplitude 1 "
                                         "--frequency 1 2>&1",
                                     &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(dry.find("motor_static_friction"), std::string::npos) << dry;
  EXPECT_NE(dry.find("without dry friction"), std::string::npos) << dry;
}

TEST(IdentifyTool, EstimatesAJointFromItsRecordingAndWritesAModelEveryToolReads)
{
  // A recording made here with the simulator in effort mode (a torque held over 1 kHz samples, CRLF line ends as
  // spreadsheets write them), identified by the tool: the estimates against the parameters it was made with.
  backlash_servo::ServoParams p;
  p.gear_ratio = 0.5;
  p.restitution = 0.5;
  p.motor_coulomb_friction = p.motor_static_friction = 0.05;
  p.load_coulomb_friction = p.load_static_friction = 0.1;
  backlash_servo::Simulator sim(p, backlash_servo::State(), 0.0);
  const std::string dir = testing::TempDir() + "backlash_identify/";
  ASSERT_EQ(std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str()), 0);
  {
    std::ofstream csv(dir + "recording.csv");
    csv.precision(17);
    csv << "time,motor_torque,motor_position,load_position,command\r\n";
    for (int k = 0; k <= 40000; ++k)
    {
      const double t = k * 1e-3, u = 0.6 * (1.5 * std::sin(1.3 * t) + 0.8 * std::sin(4.1 * t + 0.5));
      sim.advanceTo(t);
      sim.setMotorTorque(u);
      csv << t << "," << u << "," << sim.state().motor_position << "," << sim.state().load_position << ",0\r\n";
    }
  }
  int code = 0;
  const std::string json = runCapture(
      IDENTIFY + " --data " + dir + "recording.csv --gear-ratio 0.5 --json --output " + dir + "model.yaml", &code);
  ASSERT_EQ(code, 0) << json;
  const auto estimate = [&](const std::string& key) {
    return jsonNumber(json.substr(json.find("\"" + key + "\":{")), "value");
  };
  EXPECT_NEAR(estimate("backlash"), p.backlash, 1e-9);
  EXPECT_NEAR(estimate("motor_inertia"), p.motor_inertia, 1e-3 * p.motor_inertia);
  EXPECT_NEAR(estimate("load_inertia"), p.load_inertia, 1e-3 * p.load_inertia);
  EXPECT_NEAR(estimate("load_friction"), p.load_friction, 1e-3 * p.load_friction);
  EXPECT_NEAR(estimate("load_coulomb_friction"), p.load_coulomb_friction, 1e-3 * p.load_coulomb_friction);
  EXPECT_NEAR(estimate("restitution"), p.restitution, 1e-3);
  // The model: the same joint for backlash_sim (its echo of the parameters), static friction at the Coulomb level.
  const std::string sim_json = runCapture(SIM + " --config " + dir + "model.yaml --json", &code);
  ASSERT_EQ(code, 0) << sim_json;
  EXPECT_NEAR(jsonNumber(sim_json, "load_inertia"), p.load_inertia, 1e-3 * p.load_inertia);
  EXPECT_NEAR(jsonNumber(sim_json, "gear_ratio"), 0.5, 0.0);
  // The joint fit's report: every fitted estimate informed, with its largest correlation; the correlation matrix
  // symmetric with a unit diagonal; the static levels from the rests (held in the fit).
  EXPECT_NE(json.find("\"joint_fit\":{"), std::string::npos) << json;
  EXPECT_NE(json.find("\"most_correlated_with\""), std::string::npos) << json;
  EXPECT_EQ(json.find("\"informed\":false"), std::string::npos) << json;
  EXPECT_NEAR(estimate("motor_static_friction"), p.motor_static_friction, 1e-2 * p.motor_static_friction);
  EXPECT_LT(jsonNumber(json.substr(json.find("\"joint_fit\":{")), "rms_residual"), 1e-6);
  // --fit: only the listed keys are estimated; the others keep the prior's values, in the fit and in the model (the
  // prior here knows them: the restitution, the friction levels).
  {
    std::ofstream prior(dir + "known.yaml");
    prior << "gear_ratio: 0.5\nrestitution: 0.5\nmotor_coulomb_friction: 0.05\nmotor_static_friction: 0.05\n"
             "load_coulomb_friction: 0.1\nload_static_friction: 0.1\n";
  }
  const std::string listed = runCapture(IDENTIFY + " --data " + dir + "recording.csv --config " + dir +
                                            "known.yaml --fit backlash,load_inertia --output " + dir + "some.yaml 2>&1",
                                        &code);
  ASSERT_EQ(code, 0) << listed;
  std::ifstream some(dir + "some.yaml");
  const std::string written((std::istreambuf_iterator<char>(some)), std::istreambuf_iterator<char>());
  const auto value = [&](const std::string& key) {
    const std::size_t at = written.find(key + ": ");
    return at == std::string::npos ? NAN : std::stod(written.substr(at + key.size() + 2));
  };
  EXPECT_NEAR(value("load_inertia"), 0.9, 1e-5) << written;
  EXPECT_NEAR(value("backlash"), 0.3, 1e-9) << written;
  EXPECT_EQ(written.find("motor_inertia"), std::string::npos) << written;
  EXPECT_NEAR(value("restitution"), 0.5, 0.0) << written;  // (the prior's, unchanged)
  // The chart of the fit; --joint-fit off: the initial estimates alone (and no chart to draw).
  runCapture(IDENTIFY + " --data " + dir + "recording.csv --gear-ratio 0.5 --png " + dir + "fit.png 2>&1", &code);
  ASSERT_EQ(code, 0);
  std::ifstream png(dir + "fit.png", std::ios::binary);
  char magic[4] = {};
  png.read(magic, 4);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  const std::string off =
      runCapture(IDENTIFY + " --data " + dir + "recording.csv --gear-ratio 0.5 --joint-fit off --json", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(off.find("joint_fit"), std::string::npos) << off;
  const std::string both = runCapture(
      IDENTIFY + " --data " + dir + "recording.csv --gear-ratio 0.5 --joint-fit off --png " + dir + "x.png 2>&1",
      &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(both.find("--joint-fit off"), std::string::npos) << both;
  const std::string unknown =
      runCapture(IDENTIFY + " --data " + dir + "recording.csv --gear-ratio 1 --fit mass 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(unknown.find("--fit: 'mass'"), std::string::npos) << unknown;
  // Refusals, naming what is missing.
  const std::string no_ratio = runCapture(IDENTIFY + " --data " + dir + "recording.csv 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(no_ratio.find("gear ratio must be known"), std::string::npos) << no_ratio;
  {
    std::ofstream bad(dir + "bad.csv");
    bad << "time,motor_torque,motor_position\n0,0,0\n";
  }
  const std::string missing = runCapture(IDENTIFY + " --data " + dir + "bad.csv --gear-ratio 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(missing.find("no column 'load_position'"), std::string::npos) << missing;
  {
    std::ofstream bad(dir + "nan.csv");
    bad << "time,motor_torque,motor_position,load_position\n0,0,0,0\n0.001,x,0,0\n";
  }
  const std::string nan = runCapture(IDENTIFY + " --data " + dir + "nan.csv --gear-ratio 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(nan.find("row 3, column motor_torque: 'x'"), std::string::npos) << nan;
  // A CSV as spreadsheets and scripts write it: a byte order mark is read past; a column given twice, a NUL byte
  // inside a number and a huge field are refused in one short line.
  const auto refusal = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + name) << text;
    const std::string out = runCapture(IDENTIFY + " --data " + dir + name + " --gear-ratio 1 2>&1", &code);
    EXPECT_EQ(code, 2) << name;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
    EXPECT_LT(out.size(), 400u) << name;
    return out;
  };
  const std::string header = "time,motor_torque,motor_position,load_position";
  EXPECT_NE(refusal("bom.csv", "\xEF\xBB\xBF" + header + "\n0,0,0,0\n").find("at least 50 samples"),
            std::string::npos);  // (the header was read: only the data is short)
  EXPECT_NE(refusal("dup.csv", header + ",time\n0,0,0,0,1\n").find("the column 'time' twice (columns 1 and 5)"),
            std::string::npos);
  EXPECT_NE(refusal("nul.csv", header + "\n0," + std::string("0.5\0abc", 7) + ",0,0\n").find("'0.5?abc'"),
            std::string::npos);
  EXPECT_NE(refusal("huge.csv", header + "\n0," + std::string(5000000, '9') + "x,0,0\n").find("(5000001 characters)"),
            std::string::npos);
  {
    std::ofstream prior(dir + "chart.yaml");
    prior << "zeta: 0.4\ngear_ratio: 1\n";
  }
  const std::string chart =
      runCapture(IDENTIFY + " --data " + dir + "recording.csv --config " + dir + "chart.yaml 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(chart.find("physical form"), std::string::npos) << chart;
}

namespace
{
/// The workflow from the command line: backlash_sim records the joint `truth` under a 1 kHz P drive following a slow
/// sine command (its --csv is a recording: event rows are skipped); backlash_identify, given `prior`, writes the
/// model; backlash_sim replays the same experiment on the model. Returns the largest difference of the load angle
/// between the replay and the recording [rad]; the tool's output in *report, the model's YAML in *model.
double identifyAndReplay(const std::string& name, const std::string& truth, const std::string& prior,
                         std::string* report, std::string* model)
{
  const std::string dir = testing::TempDir() + name + "/";
  EXPECT_EQ(std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str()), 0);
  std::ofstream(dir + "truth.yaml") << truth;
  std::ofstream(dir + "prior.yaml") << prior;
  int code = 0;
  runCapture(SIM + " --config " + dir + "truth.yaml --duration 40 --sample-rate 1000 --csv " + dir + "rec.csv", &code);
  EXPECT_EQ(code, 0);
  *report = runCapture(
      IDENTIFY + " --data " + dir + "rec.csv --config " + dir + "prior.yaml --output " + dir + "model.yaml 2>&1",
      &code);
  EXPECT_EQ(code, 0) << *report;
  runCapture(SIM + " --config " + dir + "model.yaml --duration 40 --sample-rate 1000 --csv " + dir + "rep.csv", &code);
  EXPECT_EQ(code, 0);
  std::ifstream in(dir + "model.yaml");
  *model = std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  const auto samples = [](const std::string& path) {
    std::vector<double> load;
    std::ifstream in(path);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line))
    {
      if (line.back() == ',')  // a sample row (its event cell is empty)
      {
        std::stringstream row(line);
        std::string cell;
        std::getline(row, cell, ',');
        std::getline(row, cell, ',');
        load.push_back(std::stod(cell));
      }
    }
    return load;
  };
  const std::vector<double> rec = samples(dir + "rec.csv"), rep = samples(dir + "rep.csv");
  EXPECT_EQ(rec.size(), 40001u);
  EXPECT_EQ(rep.size(), rec.size());
  double worst = rec.size() == rep.size() ? 0.0 : INFINITY;
  for (std::size_t k = 0; k < rec.size() && k < rep.size(); ++k)
  {
    worst = std::max(worst, std::fabs(rec[k] - rep[k]));
  }
  return worst;
}

const std::string IDENTIFY_EXPERIMENT =
    "controller_rate: 1000.0\ngain: 5.0\ngear_ratio: 1.0\n"
    "profile:\n  - sine: {time: 0.0, amplitude: 1.0, frequency: 0.1, duration: 40.0}\n";
const std::string IDENTIFY_FRICTION = "motor_coulomb_friction: 0.05\nload_coulomb_friction: 0.1\nload_torque: 0.2\n";
const std::string IDENTIFY_WRONG_GUESSES =
    "motor_inertia: 0.5\nload_inertia: 3.0\nmotor_friction: 0.1\nload_friction: 1.0\n";

/// The value of `key` in a YAML model (NaN: absent).
double modelValue(const std::string& model, const std::string& key)
{
  const std::size_t at = model.find("\n" + key + ": ");
  return at == std::string::npos ? NAN : std::stod(model.substr(at + key.size() + 3));
}
}  // namespace

TEST(IdentifyTool, AnIdentifiedModelReproducesItsRecordingThroughBacklashSim)
{
  // Rigid teeth (the restitution, 0.5 in the truth, estimated too), a prior whose estimated keys are wrong on
  // purpose: the load of the replay on the model follows the recording to within 2e-3 rad over 40 s (the drive and
  // the profile come from the prior).
  std::string report, model;
  const std::string experiment = IDENTIFY_EXPERIMENT + "restitution: 0.5\n";
  const double worst = identifyAndReplay("backlash_identify_replay", experiment + IDENTIFY_FRICTION,
                                         experiment + IDENTIFY_WRONG_GUESSES, &report, &model);
  EXPECT_LT(worst, 2e-3) << report;
}

TEST(IdentifyTool, ACompliantMeshIdentifiedWhenThePriorSaysSo)
{
  // The same workflow with a compliant mesh (c = 1000 N·m/rad, d = 2 N·m·s/rad): the prior says the mesh is compliant
  // (its stiffness a guess 5× off), the model gets the mesh's stiffness and damping within 1e-3 and no restitution,
  // and its replay follows the recording to within 2e-3 rad over 40 s.
  std::string report, model;
  const double worst =
      identifyAndReplay("backlash_identify_compliant",
                        IDENTIFY_EXPERIMENT + "mesh_stiffness: 1000.0\nmesh_damping: 2.0\n" + IDENTIFY_FRICTION,
                        IDENTIFY_EXPERIMENT + "mesh_stiffness: 5000.0\n" + IDENTIFY_WRONG_GUESSES, &report, &model);
  std::printf("%s\nreplay on the model: largest load-angle difference %.3g rad\n", report.c_str(), worst);
  EXPECT_LT(worst, 2e-3);
  EXPECT_NEAR(modelValue(model, "mesh_stiffness"), 1000.0, 1.0) << model;
  EXPECT_NEAR(modelValue(model, "mesh_damping"), 2.0, 2e-3) << model;
  EXPECT_NEAR(modelValue(model, "load_inertia"), 0.9, 1e-3) << model;
  EXPECT_TRUE(std::isnan(modelValue(model, "restitution"))) << model;
  // A restitution asked of a compliant mesh: refused, naming it.
  int code = 0;
  const std::string refused =
      runCapture(IDENTIFY + " --data " + testing::TempDir() + "backlash_identify_compliant/rec.csv --config " +
                     testing::TempDir() + "backlash_identify_compliant/prior.yaml --fit restitution 2>&1",
                 &code);
  EXPECT_EQ(code, 2) << refused;
  EXPECT_NE(refused.find("restitution"), std::string::npos) << refused;
}

TEST(IdentifyTool, ExperimentInformsTheEstimates)
{
  // --experiment writes a command profile from the prior; backlash_sim runs it on the true joint; the recording
  // identifies that joint within 1 %. A travel that cannot cross the backlash three times over is refused.
  const std::string dir = testing::TempDir() + "backlash_identify_experiment/";
  ASSERT_EQ(std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str()), 0);
  const std::string known = "controller_rate: 1000.0\ngain: 5.0\ngear_ratio: 1.0\nrestitution: 0.5\n";
  {
    std::ofstream prior(dir + "prior.yaml");
    prior << known << "backlash: 0.3\n";
    std::ofstream truth(dir + "truth.yaml");
    truth << known << "motor_coulomb_friction: 0.05\nload_coulomb_friction: 0.1\nload_torque: 0.2\nprofile: " << dir
          << "experiment.yaml\n";
  }
  int code = 0;
  const std::string made = runCapture(
      IDENTIFY + " --experiment --config " + dir + "prior.yaml --output " + dir + "experiment.yaml 2>&1", &code);
  ASSERT_EQ(code, 0) << made;
  runCapture(SIM + " --config " + dir + "truth.yaml --duration 60 --sample-rate 1000 --csv " + dir + "rec.csv", &code);
  ASSERT_EQ(code, 0);
  const std::string json =
      runCapture(IDENTIFY + " --data " + dir + "rec.csv --config " + dir + "prior.yaml --json", &code);
  ASSERT_EQ(code, 0) << json;
  const auto estimate = [&](const std::string& key) {
    return jsonNumber(json.substr(json.find("\"" + key + "\":{")), "value");
  };
  EXPECT_NEAR(estimate("motor_inertia"), 0.1, 1e-3);
  EXPECT_NEAR(estimate("load_inertia"), 0.9, 9e-3);
  EXPECT_NEAR(estimate("load_friction"), 0.32, 3.2e-3);
  EXPECT_NEAR(estimate("motor_coulomb_friction"), 0.05, 5e-4);
  EXPECT_NEAR(estimate("load_coulomb_friction"), 0.1, 1e-3);
  EXPECT_NEAR(estimate("load_torque"), 0.2, 2e-3);
  const std::string narrow = runCapture(
      IDENTIFY + " --experiment --config " + dir + "prior.yaml --travel 0.5 --output " + dir + "narrow.yaml 2>&1",
      &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(narrow.find("travel"), std::string::npos) << narrow;
  // A travel beyond the set-point's range, and a prior with rigid teeth (nothing to design the travel from), are
  // refused naming the key.
  const std::string far = runCapture(
      IDENTIFY + " --experiment --config " + dir + "prior.yaml --travel 1e12 --output " + dir + "far.yaml 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(far.find("command"), std::string::npos) << far;
  std::ofstream(dir + "rigid.yaml") << known << "backlash: 0\n";
  const std::string rigid = runCapture(
      IDENTIFY + " --experiment --config " + dir + "rigid.yaml --output " + dir + "rigid_exp.yaml 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(rigid.find("backlash: the prior's backlash is 0"), std::string::npos) << rigid;
  // Time steps far below a nanosecond (times not in seconds) are refused, naming the column.
  {
    std::ofstream tiny(dir + "tiny.csv");
    tiny << "time,motor_torque,motor_position,load_position\n";
    for (int k = 0; k < 100; ++k)
    {
      tiny << k << "e-303,0.1,0,0\n";
    }
  }
  const std::string tiny = runCapture(IDENTIFY + " --data " + dir + "tiny.csv --gear-ratio 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(tiny.find("time: the samples are"), std::string::npos) << tiny;
}

TEST(IdentifyTool, ADitheredExperimentOnAStickyJoint)
{
  // --dither puts a fast sine on every segment of the experiment (written into the profile, replayed by backlash_sim):
  // on a joint whose static friction is six times its Coulomb level the recording still identifies the Coulomb and
  // viscous levels within 1e-4. A dither needs a digital drive.
  const std::string dir = testing::TempDir() + "backlash_identify_dither/";
  ASSERT_EQ(std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str()), 0);
  const std::string known = "controller_rate: 1000.0\ngain: 5.0\ngear_ratio: 1.0\nrestitution: 0.5\n";
  std::ofstream(dir + "prior.yaml") << known;
  std::ofstream(dir + "truth.yaml") << known
                                    << "motor_coulomb_friction: 0.05\nmotor_static_friction: 0.3\n"
                                       "load_coulomb_friction: 0.1\nload_static_friction: 0.5\nload_torque: 0.2\n"
                                       "profile: "
                                    << dir << "experiment.yaml\n";
  int code = 0;
  const std::string made = runCapture(
      IDENTIFY + " --experiment --config " + dir + "prior.yaml --dither 0.2 --output " + dir + "experiment.yaml 2>&1",
      &code);
  ASSERT_EQ(code, 0) << made;
  std::ifstream in(dir + "experiment.yaml");
  const std::string profile((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(profile.find("dither_amplitude: 0.2, dither_frequency: 7.11"), std::string::npos) << profile;
  runCapture(SIM + " --config " + dir + "truth.yaml --duration 60 --sample-rate 1000 --csv " + dir + "rec.csv", &code);
  ASSERT_EQ(code, 0);
  const std::string json =
      runCapture(IDENTIFY + " --data " + dir + "rec.csv --config " + dir + "prior.yaml --json", &code);
  ASSERT_EQ(code, 0) << json;
  const auto estimate = [&](const std::string& key) {
    return jsonNumber(json.substr(json.find("\"" + key + "\":{")), "value");
  };
  EXPECT_NEAR(estimate("motor_coulomb_friction"), 0.05, 5e-6);
  EXPECT_NEAR(estimate("load_coulomb_friction"), 0.1, 1e-5);
  EXPECT_NEAR(estimate("motor_friction"), 0.48, 4.8e-5);
  EXPECT_NEAR(estimate("load_friction"), 0.32, 3.2e-5);
  std::ofstream(dir + "continuous.yaml") << "gain: 5.0\ngear_ratio: 1.0\n";
  const std::string refused = runCapture(
      IDENTIFY + " --experiment --config " + dir + "continuous.yaml --dither 0.2 --output " + dir + "no.yaml 2>&1",
      &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(refused.find("digital"), std::string::npos) << refused;
}

TEST(IdentifyTool, EncoderCountsFromThePriorSetTheContactBand)
{
  // Angles on the count grid of the prior's encoders (2^16 counts a turn on both) are measured ones: the contact band
  // follows from their counts and the fit is that of measured angles (the backlash within two counts); exact angles
  // with the same prior keep the exact default.
  const std::string dir = testing::TempDir() + "backlash_identify_counts/";
  ASSERT_EQ(std::system(("rm -rf " + dir + " && mkdir -p " + dir).c_str()), 0);
  const std::string known = "controller_rate: 1000.0\ngain: 5.0\ngear_ratio: 1.0\nrestitution: 0.5\n";
  std::ofstream(dir + "truth.yaml")
      << known << "load_coulomb_friction: 0.1\nload_torque: 0.2\n"
      << "profile:\n  - sine: {time: 0.0, amplitude: 1.0, frequency: 0.1, duration: 40.0}\n";
  std::ofstream(dir + "prior.yaml") << known << "motor_encoder_resolution: 65536\nload_encoder_resolution: 65536\n";
  int code = 0;
  runCapture(SIM + " --config " + dir + "truth.yaml --duration 40 --sample-rate 1000 --csv " + dir + "exact.csv",
             &code);
  ASSERT_EQ(code, 0);
  // The recording read through the encoders: every angle floored to its count.
  const double count = 2.0 * M_PI / 65536.0;
  {
    std::ifstream in(dir + "exact.csv");
    std::ofstream out(dir + "counts.csv");
    std::string line;
    std::getline(in, line);
    std::vector<std::string> header;
    std::stringstream names(line);
    for (std::string cell; std::getline(names, cell, ',');)
    {
      header.push_back(cell);
    }
    const auto column = [&header](const std::string& name) {
      return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
    };
    out << "time,motor_torque,motor_position,load_position\n";
    out.precision(17);
    while (std::getline(in, line))
    {
      if (line.back() != ',')
      {
        continue;  // an event row
      }
      std::vector<std::string> cells;
      std::stringstream row(line);
      for (std::string cell; std::getline(row, cell, ',');)
      {
        cells.push_back(cell);
      }
      out << cells[column("time")] << "," << cells[column("motor_torque")] << ","
          << count * std::floor(std::stod(cells[column("motor_position")]) / count) << ","
          << count * std::floor(std::stod(cells[column("load_position")]) / count) << "\n";
    }
  }
  const std::string measured = runCapture(
      IDENTIFY + " --data " + dir + "counts.csv --config " + dir + "prior.yaml --smoothing 20 --json 2>&1", &code);
  ASSERT_EQ(code, 0) << measured;
  // Recognised: both angles on the 2^16-count grid, the contact band from their counts (not the exact default).
  const std::string json = measured.substr(measured.find('{'));
  const std::string seen = json.substr(json.find("\"measurement\":{"));
  EXPECT_EQ(jsonNumber(seen, "motor_encoder_resolution"), 65536.0) << json;
  EXPECT_EQ(jsonNumber(seen, "load_encoder_resolution"), 65536.0) << json;
  EXPECT_EQ(jsonNumber(seen, "smoothing"), 20.0) << json;
  // Two counts of the gap (ρ = 1: a count of each angle, twice): a creeping body's count steps stay inside.
  EXPECT_NEAR(jsonNumber(seen, "contact_band"), 4.0 * count, 1e-12) << json;
  EXPECT_NEAR(jsonNumber(json.substr(json.find("\"backlash\":{")), "value"), 0.3, 2.0 * count) << json;
  const std::string exact =
      runCapture(IDENTIFY + " --data " + dir + "exact.csv --config " + dir + "prior.yaml --json 2>&1", &code);
  ASSERT_EQ(code, 0) << exact;
  const std::string exact_seen = exact.substr(exact.find("\"measurement\":{"));
  EXPECT_EQ(jsonNumber(exact_seen, "motor_noise"), 0.0) << exact;
  EXPECT_EQ(jsonNumber(exact_seen, "contact_band"), 0.0) << exact;
}

TEST(IdentifyTool, ABagIsConvertedByTheBagReport)
{
  // --data FILE.bag runs the bag report's converter (its identification is checked against the CSV route in
  // bag_report.test); the bag's options need a bag, and a bag that cannot be read is refused naming it.
  int code = 0;
  const std::string csv = testing::TempDir() + "backlash_identify_not_a_bag.csv";
  std::ofstream(csv) << "time,motor_torque,motor_position,load_position\n";
  const std::string flags = runCapture(IDENTIFY + " --data " + csv + " --gear-ratio 1 --joint-states /js 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(flags.find("give --data FILE.bag"), std::string::npos) << flags;
  const std::string missing = testing::TempDir() + "backlash_identify_missing.bag";
  const std::string none = runCapture(IDENTIFY + " --data " + missing + " --gear-ratio 1 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(none.find("could not convert " + missing), std::string::npos) << none;
}
