// backlash_df: the describing-function prediction beside the exact cycle.
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
