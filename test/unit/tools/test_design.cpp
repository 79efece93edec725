// backlash_design: its answers against the simulations they cite.
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
