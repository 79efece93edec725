// backlash_identify: parameters from recordings, against the joints that made them.
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

namespace
{
/**
 * A recording made here with the simulator in effort mode (a torque held over 1 kHz samples, CRLF line ends as
 * spreadsheets write them), written once for the tests below into dir() + "recording.csv"; joint() is the joint it
 * was made with.
 */
class IdentifyRecording : public testing::Test
{
 public:
  static backlash_servo::ServoParams joint()
  {
    backlash_servo::ServoParams p;
    p.gear_ratio = 0.5;
    p.restitution = 0.5;
    p.motor_coulomb_friction = p.motor_static_friction = 0.05;
    p.load_coulomb_friction = p.load_static_friction = 0.1;
    return p;
  }
  static std::string dir() { return testing::TempDir() + "backlash_identify/"; }
  static std::string recording() { return dir() + "recording.csv"; }

  static void SetUpTestSuite()
  {
    ASSERT_EQ(std::system(("rm -rf " + dir() + " && mkdir -p " + dir()).c_str()), 0);
    backlash_servo::Simulator sim(joint(), backlash_servo::State(), 0.0);
    std::ofstream csv(recording());
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
};
}  // namespace

TEST_F(IdentifyRecording, EstimatesTheJointAndWritesAModelEveryToolReads)
{
  const backlash_servo::ServoParams p = joint();
  const std::string dir = IdentifyRecording::dir();
  int code = 0;
  const std::string json = runCapture(
      IDENTIFY + " --data " + recording() + " --gear-ratio 0.5 --json --output " + dir + "model.yaml", &code);
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
}

TEST_F(IdentifyRecording, FitEstimatesOnlyTheListedKeys)
{
  const std::string dir = IdentifyRecording::dir();
  int code = 0;
  // --fit: only the listed keys are estimated; the others keep the prior's values, in the fit and in the model (the
  // prior here knows them: the restitution, the friction levels).
  {
    std::ofstream prior(dir + "known.yaml");
    prior << "gear_ratio: 0.5\nrestitution: 0.5\nmotor_coulomb_friction: 0.05\nmotor_static_friction: 0.05\n"
             "load_coulomb_friction: 0.1\nload_static_friction: 0.1\n";
  }
  const std::string listed = runCapture(IDENTIFY + " --data " + recording() + " --config " + dir +
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
}

TEST_F(IdentifyRecording, DrawsTheFitAndSkipsItWhenTold)
{
  const std::string dir = IdentifyRecording::dir();
  int code = 0;
  // The chart of the fit; --joint-fit off: the initial estimates alone (and no chart to draw).
  runCapture(IDENTIFY + " --data " + recording() + " --gear-ratio 0.5 --png " + dir + "fit.png 2>&1", &code);
  ASSERT_EQ(code, 0);
  std::ifstream png(dir + "fit.png", std::ios::binary);
  char magic[4] = {};
  png.read(magic, 4);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  const std::string off =
      runCapture(IDENTIFY + " --data " + recording() + " --gear-ratio 0.5 --joint-fit off --json", &code);
  ASSERT_EQ(code, 0);
  EXPECT_EQ(off.find("joint_fit"), std::string::npos) << off;
  const std::string both = runCapture(
      IDENTIFY + " --data " + recording() + " --gear-ratio 0.5 --joint-fit off --png " + dir + "x.png 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(both.find("--joint-fit off"), std::string::npos) << both;
}

TEST_F(IdentifyRecording, RefusesNamingWhatIsMissing)
{
  const std::string dir = IdentifyRecording::dir();
  int code = 0;
  const std::string unknown =
      runCapture(IDENTIFY + " --data " + recording() + " --gear-ratio 1 --fit mass 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(unknown.find("--fit: 'mass'"), std::string::npos) << unknown;
  const std::string no_ratio = runCapture(IDENTIFY + " --data " + recording() + " 2>&1", &code);
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
  {
    std::ofstream prior(dir + "chart.yaml");
    prior << "zeta: 0.4\ngear_ratio: 1\n";
  }
  const std::string chart =
      runCapture(IDENTIFY + " --data " + recording() + " --config " + dir + "chart.yaml 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(chart.find("physical form"), std::string::npos) << chart;
}

TEST_F(IdentifyRecording, ReadsACsvAsSpreadsheetsWriteItAndRefusesMalformedOnesInOneLine)
{
  const std::string dir = IdentifyRecording::dir();
  int code = 0;
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
  // (checked on the prior's joint before it was written: the progress, and the finding in the profile's header)
  EXPECT_NE(made.find("impacts, every key given back"), std::string::npos) << made;
  EXPECT_NE(readFile(dir + "experiment.yaml").find("every body parameter given back within 2 %"), std::string::npos);
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
  // --duration is the experiment's length (three sines of a third each), and nothing else's.
  runCapture(
      IDENTIFY + " --experiment --config " + dir + "prior.yaml --duration 120 --output " + dir + "long.yaml 2>&1",
      &code);
  ASSERT_EQ(code, 0);
  const std::string long_profile = readFile(dir + "long.yaml");
  EXPECT_NE(long_profile.find("duration: 40}"), std::string::npos) << long_profile;
  // An experiment too long for its check to hold in memory is refused before it is simulated, naming the flag.
  const std::string huge = runCapture(
      IDENTIFY + " --experiment --config " + dir + "prior.yaml --duration 1e6 --output " + dir + "huge.yaml 2>&1",
      &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(huge.find("duration: 1000000 s at 1000 Hz is 1000000000 samples"), std::string::npos) << huge;
  const std::string stray =
      runCapture(IDENTIFY + " --data " + dir + "rec.csv --config " + dir + "prior.yaml --duration 5 2>&1", &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(stray.find("--duration, --travel and --dither are for --experiment"), std::string::npos) << stray;
  // A travel or a dither beyond the command's range: refused at --experiment, naming the flag (every tool would
  // refuse the profile).
  for (const std::string& flag : {std::string(" --travel 1e12"), std::string(" --dither 1e12,1")})
  {
    const std::string far = runCapture(
        IDENTIFY + " --experiment --config " + dir + "prior.yaml" + flag + " --output " + dir + "far.yaml 2>&1", &code);
    EXPECT_EQ(code, 2) << far;
    EXPECT_NE(far.find(flag.substr(1, flag.find(' ', 1) - 1) + ": 1000000000000 rad must be in"), std::string::npos)
        << far;
  }
  // The chart and the model in one file: refused before any work, nothing written.
  const std::string clash = runCapture(IDENTIFY + " --data " + dir + "rec.csv --config " + dir +
                                           "prior.yaml --output " + dir + "same.png --png " + dir + "same.png 2>&1",
                                       &code);
  EXPECT_EQ(code, 2);
  EXPECT_NE(clash.find("is also the --output file"), std::string::npos) << clash;
  EXPECT_FALSE(std::ifstream(dir + "same.png").good());
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
