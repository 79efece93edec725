// Golden outputs for refactors: recorded before a change of structure and reproduced to the last printed digit
// afterwards. Physics is checked against independent truth elsewhere; this file only pins that
// a refactor changes nothing. Record (only before a deliberate change of results):
//   BACKLASH_GOLDEN_RECORD=1 build/devel/lib/backlash_servo/backlash_servo_golden_test
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "backlash_servo/simulation/simulator.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;
using test_helpers::readFile;
using test_helpers::runCapture;

const std::string GOLDEN_DIR = std::string(SOURCE_DIR) + "/test/golden/";

bool recording()
{
  const char* r = std::getenv("BACKLASH_GOLDEN_RECORD");
  return r != nullptr && std::string(r) == "1";
}

std::vector<std::string> lines(const std::string& text)
{
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string line;
  while (std::getline(ss, line))
  {
    out.push_back(line);
  }
  return out;
}

/// Records (record mode) or compares the whole text with the stored golden file.
void checkGolden(const std::string& name, const std::string& actual)
{
  const std::string path = GOLDEN_DIR + name;
  if (recording())
  {
    std::ofstream(path) << actual;
    return;
  }
  const std::vector<std::string> want = lines(readFile(path));
  const std::vector<std::string> got = lines(actual);
  ASSERT_FALSE(want.empty()) << "missing golden file " << path;
  ASSERT_EQ(want.size(), got.size()) << name;
  for (std::size_t i = 0; i < want.size(); ++i)
  {
    EXPECT_EQ(want[i], got[i]) << name << " line " << i + 1;
  }
}

/// backlash_sim --json without the wall time (the only field that may differ between two identical runs).
std::string simJson(const std::string& args)
{
  int code = 0;
  std::string out = runCapture(std::string(BACKLASH_SIM_EXE) + " " + args + " --json 2>&1", &code);
  out = std::regex_replace(out, std::regex(",\"wall_time\":[^,}]*"), "");
  return "exit " + std::to_string(code) + " " + out;
}

TEST(Golden, BacklashSimJsonOnThesisEdgeAndRandomCases)
{
  const std::vector<std::string> cases = lines(readFile(GOLDEN_DIR + "sim_cases.txt"));
  ASSERT_GE(cases.size(), 60u);
  std::string all;
  for (const std::string& args : cases)
  {
    all += args + "\n" + simJson(args);
  }
  checkGolden("sim_golden.txt", all);
}

TEST(Golden, BacklashSimCsvTrajectory)
{
  const std::string path = ::testing::TempDir() + "golden_traj.csv";
  std::remove(path.c_str());
  int code = 0;
  runCapture(std::string(BACKLASH_SIM_EXE) + " --duration 25 --sample-rate 20 --csv " + path, &code);
  ASSERT_EQ(code, 0);
  checkGolden("sim_trajectory.csv", readFile(path));
}

TEST(Golden, SweepCsv)
{
  int code = 0;
  const std::string csv = runCapture(std::string(BACKLASH_SWEEP_EXE) +
                                         " --zeta 0.1,0.4 --inertia-ratio 0.25,9 --friction-ratio 0,0.4,1"
                                         " --restitution 0,1 --jobs 2 2>/dev/null",
                                     &code);
  ASSERT_EQ(code, 0);
  checkGolden("sweep.csv", csv);
}

/// Every event and the final ledger of the core in effort mode (torque steps) and position mode (command steps).
struct Trace : EventSink
{
  std::string text;
  long impacts = 0;
  void onEvent(const Event& e) override
  {
    // Elastic chatter brings thousands of impacts: the first ones and every 97th are written (the count is final).
    if (e.type == EventType::Impact && ++impacts > 40 && impacts % 97 != 0)
    {
      return;
    }
    char buf[512];
    std::snprintf(buf, sizeof buf, "%s t=%.17g x=%.17g v=%.17g xm=%.17g vm=%.17g c=%s", toString(e.type), e.state.time,
                  e.state.load_position, e.state.load_velocity, e.state.motor_position, e.state.motor_velocity,
                  toString(e.state.contact));
    text += buf;
    if (e.type == EventType::Impact)
    {
      std::snprintf(buf, sizeof buf, " speed=%.17g loss=%.17g stuck=%d", e.impact.approach_speed, e.impact.energy_loss,
                    e.impact.stuck ? 1 : 0);
      text += buf;
    }
    text += "\n";
  }
  void final(const Simulator& sim)
  {
    char buf[512];
    const EnergyLedger& e = sim.energy();
    std::snprintf(buf, sizeof buf, "end impacts=%llu in=%.17g fm=%.17g fl=%.17g imp=%.17g kin=%.17g\n",
                  static_cast<unsigned long long>(sim.impactCount()), e.input, e.motor_friction, e.load_friction,
                  e.impact_loss, sim.kineticEnergy());
    text += buf;
  }
};

TEST(Golden, CoreEffortAndCommandSteps)
{
  Trace trace;
  const double zetas[] = {0.4, 0.1};
  const double restitutions[] = {1.0, 0.6};
  for (double zeta : zetas)
  {
    for (double e : restitutions)
    {
      Simulator sim(test_helpers::chart(zeta, 9.0, 0.4, e), State(), 1.0);
      sim.advanceTo(4.0, &trace);
      sim.setMotorTorque(-0.3, &trace);  // effort mode
      sim.advanceTo(9.0, &trace);
      sim.setMotorTorque(0.25, &trace);
      sim.advanceTo(15.0, &trace);
      sim.setCommand(-1.0, &trace);  // back to the P law with a new set-point
      sim.advanceTo(40.0, &trace);
      trace.final(sim);
    }
  }
  checkGolden("core_trace.txt", trace.text);
}

}  // namespace
