// backlash_frf: stepped sines and broadband estimates against closed forms and single runs.
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
