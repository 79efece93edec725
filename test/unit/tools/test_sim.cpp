// backlash_sim: what it says about a run (encoder counts, units typed wrong).
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
