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

// A robot file runs every joint of the arm together: one verdict per joint, each joint's load the arm's gravity at
// its pose (worked out here by hand for the example arm), CSV columns per joint, flags that would be ambiguous refused.
TEST(Sim, ARobotFileRunsEveryJointOfTheArm)
{
  const std::string arm = " --config " + std::string(SOURCE_DIR) + "/config/three_joint_arm.yaml";
  int code = 0;
  const std::string json = runCapture(SIM + arm + " --duration 2 --json", &code);
  ASSERT_EQ(code, 0) << json;
  EXPECT_EQ(jsonNumber(json, "simulated"), 2.0);
  std::vector<std::string> names;
  std::vector<double> q, torque;
  const std::regex joint(
      "\"name\":\"([a-z]+)\",\"verdict\":\"[a-z_]+\".*?\"load_position\":(-?[0-9.eE+-]+)"
      ".*?\"load_torque\":(-?[0-9.eE+-]+)");
  for (auto it = std::sregex_iterator(json.begin(), json.end(), joint); it != std::sregex_iterator(); ++it)
  {
    names.push_back((*it)[1]);
    q.push_back(std::stod((*it)[2]));
    torque.push_back(std::stod((*it)[3]));
  }
  ASSERT_EQ(names, (std::vector<std::string>{"shoulder", "elbow", "wrist"})) << json;
  // Held at their commands (0.3, −0.6, 0.4 rad) by the PIDs; gravity on each load by hand at the pose (link masses
  // at their centres, +q turning a link down), held from the last controller sample (within a millisecond's motion).
  EXPECT_NEAR(q[0], 0.3, 1e-3);
  EXPECT_NEAR(q[1], -0.6, 1e-3);
  EXPECT_NEAR(q[2], 0.4, 1e-3);
  const double g = 9.80665, c1 = std::cos(q[0]), c12 = std::cos(q[0] + q[1]), c123 = std::cos(q[0] + q[1] + q[2]);
  const double wrist = g * 0.9 * 0.08 * c123;
  const double elbow = g * (2.1 * 0.175 + 0.9 * 0.35) * c12 + wrist;
  const double shoulder = g * (3.2 * 0.2 + 3.0 * 0.4) * c1 + elbow;
  EXPECT_NEAR(torque[0], shoulder, 1e-4 * shoulder);
  EXPECT_NEAR(torque[1], elbow, 1e-4 * elbow);
  EXPECT_NEAR(torque[2], wrist, 1e-4 * wrist);

  const std::string csv = "/tmp/backlash_sim_robot_" + std::to_string(getpid()) + ".csv";
  const std::string text = runCapture(SIM + arm + " --duration 0.5 --csv " + csv + " --sample-rate 50", &code);
  ASSERT_EQ(code, 0) << text;
  EXPECT_NE(text.find("arm 'three_joint_arm': 3 joints, 0.5 s simulated"), std::string::npos) << text;
  EXPECT_NE(text.find("\nelbow "), std::string::npos) << text;
  const std::string table = readFile(csv);
  EXPECT_EQ(table.rfind("time,shoulder_position,shoulder_velocity,shoulder_motor_position,", 0), 0u) << table;
  const auto rows = csvRows(table);
  ASSERT_EQ(rows.size(), 26u);  // 0, 0.02, …, 0.5 s
  EXPECT_EQ(rows.back()[0], "0.5");
  EXPECT_EQ(rows.front().size(), 1u + 3u * 6u);
  std::remove(csv.c_str());

  const std::string refused = runCapture(SIM + arm + " --backlash 0.01 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(refused.find("--backlash with a robot file: the joints' keys are the file's"), std::string::npos)
      << refused;
  for (const char* bad : {" --duration nan", " --duration -1", " --max-duration inf"})
  {
    const std::string out = runCapture(SIM + arm + bad + " 2>&1", &code);
    EXPECT_EQ(code, 2) << bad << ": " << out;
    EXPECT_NE(out.find("duration"), std::string::npos) << out;
  }
  // A single-joint tool never runs an arm's file as the default joint: refused, naming the tool that runs it.
  const std::string sweep = runCapture(SWEEP + arm + " --backlash 0.1,0.2 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(sweep.find("describes an arm (joints:): backlash_sim --config runs it"), std::string::npos) << sweep;
}
