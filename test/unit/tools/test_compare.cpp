// backlash_compare (the workbench): its metrics against single runs and their CSV samples.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>
#include "tools/tools_test.h"

using namespace tools_test;

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

// A strategy the duration leaves undecided is run on until settled: its verdict and the time it needed equal
// backlash_sim's run until settled (with the same cap), a duration of that time (rounded up) decides it in the table,
// the metrics stay those of the given duration, and a strategy decided within the duration has no run-on. Without
// max_duration the run-on stops at ten times the duration and says so.
TEST(Compare, AnUndecidedStrategySaysHowLongItWouldNeed)
{
  const std::string joint =
      "backlash: 0.05\nrestitution: 0.5\nload_coulomb_friction: 0.02\nload_static_friction: 0.05\n"
      "controller_rate: 1000\ncommand: 1.0\nsample_rate: 1000\nmax_duration: 2000\n"
      "strategies:\n"
      "  - {name: P, control_law: proportional}\n"
      "  - {name: PID, control_law: pid, integral_gain: 0.5, derivative_gain: 0.3}\n";
  const std::string yaml = "/tmp/backlash_compare_run_on.yaml";
  std::ofstream(yaml) << joint << "duration: 2\n";
  int code = 0;
  const std::string json = runCapture(COMPARE + " --config " + yaml + " --json", &code);
  ASSERT_EQ(code, 0) << json;
  const std::vector<std::string> flags = {"--control-law proportional",
                                          "--control-law pid --integral-gain 0.5 --derivative-gain 0.3"};
  const std::string sim = SIM +
                          " --backlash 0.05 --restitution 0.5 --load-coulomb-friction 0.02 --load-static-friction 0.05 "
                          "--controller-rate 1000 --json ";
  std::size_t pos = 0;
  int undecided = 0;
  for (const std::string& f : flags)
  {
    pos = json.find("{\"name\"", pos + 1);
    ASSERT_NE(pos, std::string::npos);
    const std::size_t run_on = json.find("\"run_on\":", pos);
    const std::string entry = json.substr(pos, json.find('}', json.find('}', run_on) + 1) - pos + 1);
    ASSERT_EQ(jsonText(entry, "verdict"), "undecided") << entry;  // 2 s decides neither
    ++undecided;
    const std::string settled = runCapture(sim + "--duration 0 --max-duration 2000 " + f);
    const std::string on = entry.substr(entry.find("\"run_on\":"));
    EXPECT_EQ(jsonText(on, "verdict"), jsonText(settled, "verdict")) << entry;
    EXPECT_EQ(jsonText(on, "stopped_by"), "settled") << entry;
    EXPECT_DOUBLE_EQ(jsonNumber(on, "time"), jsonNumber(settled, "simulated_time")) << entry << settled;
    // The metrics are the 2 s run's: its RMS tracking error equals backlash_sim's over 2 s.
    const std::string two = runCapture(sim + "--duration 2 " + f);
    EXPECT_NEAR(jsonNumber(entry, "rms_error"), jsonNumber(two, "rms_error"), 1e-9) << entry;
    // Given the time it asked for, the table decides it.
    char duration[32];
    std::snprintf(duration, sizeof duration, "%g", std::ceil(jsonNumber(on, "time")));
    std::ofstream(yaml) << joint << "duration: " << duration << "\n";
    const std::string longer = runCapture(COMPARE + " --config " + yaml + " --json", &code);
    ASSERT_EQ(code, 0) << longer;
    const std::size_t at =
        longer.find("{\"name\":\"" + std::string(f.find("pid") != std::string::npos ? "PID" : "P") + "\"");
    ASSERT_NE(at, std::string::npos) << longer;
    EXPECT_EQ(jsonText(longer.substr(at), "verdict"), jsonText(settled, "verdict")) << longer;
    EXPECT_NE(longer.find("\"run_on\":null", at), std::string::npos) << longer;
  }
  EXPECT_EQ(undecided, 2);
  // The text table says it under the table, with the duration that decides it; without max_duration the PID's
  // limit cycle (found at ~1000 s above) is beyond the run-on's cap of 10 × 2 s.
  std::ofstream(yaml) << std::regex_replace(joint, std::regex("max_duration: 2000\n"), "") << "duration: 2\n";
  const std::string table = runCapture(COMPARE + " --config " + yaml, &code);
  EXPECT_NE(table.find("note: 'P' is undecided within duration 2 s; run on until settled, it is converged at "),
            std::string::npos)
      << table;
  EXPECT_NE(table.find("decides it here)"), std::string::npos) << table;
  EXPECT_NE(table.find("note: 'PID' is undecided within duration 2 s; run on until settled, it is still undecided at "
                       "20 s, where the run-on's cap ended it (set max_duration to look further)"),
            std::string::npos)
      << table;
}
