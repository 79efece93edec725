// The initial estimates recover a joint from its own simulated recording (the exact motion is the truth): a torque
// excitation held over 1 kHz samples in effort mode, the angles recorded at the samples.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <utility>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/drive/drive.h"
#include "backlash_servo/identification/identification.h"
#include "backlash_servo/identification/identify_joint.h"
#include "backlash_servo/identification/replay_windows.h"
#include "backlash_servo/simulation/simulator.h"
#include "recorded_joint.h"

using namespace backlash_servo;

namespace
{
constexpr double PI = 3.14159265358979323846;
}

namespace
{
Recording record(const ServoParams& p, double seconds, double rate, double a)
{
  return recordJoint(p, seconds, rate, a);
}

void expectClose(const Estimate& e, double truth, double rel, double abs, const char* what)
{
  EXPECT_NEAR(e.value, truth, std::max(rel * std::fabs(truth), abs)) << what << " ± " << e.standard_error;
}
}  // namespace

TEST(Identification, InitialEstimatesRecoverARigidJointFromItsRecording)
{
  for (const double rho : {1.0, 0.5})
  {
    SCOPED_TRACE(rho);
    ServoParams p;
    p.gear_ratio = rho;
    p.restitution = 0.5;
    p.motor_coulomb_friction = p.motor_static_friction = 0.05;
    p.load_coulomb_friction = p.load_static_friction = 0.1;
    p.load_torque = 0.2;
    const Recording r = record(p, 60.0, 1000.0, rho < 1.0 ? 0.6 : 1.0);
    IdentificationSettings s;
    s.gear_ratio = rho;
    const InitialEstimates e = estimateInitial(r, s);
    EXPECT_NEAR(e.backlash.value, p.backlash, 1e-9);
    EXPECT_NEAR(e.zero_offset, 0.0, 1e-9);
    // Exact data: the O(h) error of regressing the second difference on the mean held torque stays far below 1e-3.
    expectClose(e.motor_inertia, p.motor_inertia, 1e-3, 0.0, "J_m");
    expectClose(e.load_inertia, p.load_inertia, 1e-3, 0.0, "J_L");
    expectClose(e.motor_friction, p.motor_friction, 1e-3, 0.0, "f_m");
    expectClose(e.load_friction, p.load_friction, 1e-3, 0.0, "f_L");
    expectClose(e.motor_coulomb_friction, p.motor_coulomb_friction, 1e-3, 1e-5, "T_cm");
    expectClose(e.load_coulomb_friction, p.load_coulomb_friction, 1e-3, 1e-5, "T_cL");
    expectClose(e.load_torque, p.load_torque, 1e-3, 1e-5, "T_ext");
    EXPECT_GT(e.contact_samples, 10000u);
    EXPECT_GT(e.apart_samples, 10000u);
    // The standard errors are honest: the truth within a few of them (model error included).
    EXPECT_LT(std::fabs(e.load_inertia.value - p.load_inertia),
              1e-3 * p.load_inertia + 10.0 * e.load_inertia.standard_error);
  }
}

TEST(Identification, RefusesARecordingThatDoesNotCrossTheBacklash)
{
  ServoParams p;
  p.load_torque = -0.5;  // the teeth stay pressed on the forward flank under a small excitation
  const Recording r = record(p, 20.0, 1000.0, 0.05);
  IdentificationSettings s;
  try
  {
    estimateInitial(r, s);
    FAIL() << "accepted a recording without reversals across the backlash";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("reversals"), std::string::npos) << e.what();
  }
  Recording bad = r;
  bad.time[10] += 1e-4;
  EXPECT_THROW(estimateInitial(bad, s), InvalidParameterError);
  // Read through 2^16-count encoders: the gap stays within its measurement band, and the refusal names both causes
  // it cannot tell apart (a free play below the band, or teeth that never left one flank) and what shows each.
  Recording counted = r;
  const double q = 2.0 * M_PI / 65536.0;  // [rad] a count
  for (std::vector<double>* angle : {&counted.motor_position, &counted.load_position})
  {
    for (double& x : *angle)
    {
      x = q * std::round(x / q);
    }
  }
  ServoParams prior;
  IdentifyOptions options;
  options.stated = std::set<std::string>{"gear_ratio"};
  try
  {
    identifyJoint(counted, s, prior, options);
    FAIL() << "accepted a counted recording without reversals across the backlash";
  }
  catch (const InvalidParameterError& e)
  {
    for (const char* says : {"under four times the gap's measurement band", "the load moved over",
                             "finer or less noisy encoders", "never left one flank", "--experiment"})
    {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << says << ": " << e.what();
    }
  }
}

// Time stamps as recorders write them: a clock's nanosecond jitter and Unix-epoch times (rounded to 2.4e-7 s at
// 1.7e9 s) are uniform samples; a lost sample is refused at its own row, with both steps readable.
TEST(Identification, JitteredAndEpochStampsAreUniformALostSampleIsNamed)
{
  Recording r;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> jitter(-1e-9, 1e-9);
  for (int k = 0; k < 30000; ++k)
  {
    r.time.push_back(1700000000.5 + 1e-3 * k + jitter(rng));
    r.motor_torque.push_back(0.0);
    r.motor_position.push_back(0.0);
    r.load_position.push_back(0.0);
  }
  IdentificationSettings s;
  EXPECT_NEAR(samplePeriod(r, s), 1e-3, 1e-9);
  Recording holed = r;
  for (std::size_t k = 20000; k < holed.time.size(); ++k)
  {
    holed.time[k] += 1e-3;  // the sample between rows 20 000 and 20 001 lost
  }
  try
  {
    samplePeriod(holed, s);
    FAIL() << "accepted a lost sample";
  }
  catch (const InvalidParameterError& e)
  {
    const std::string what = e.what();
    EXPECT_NE(what.find("row 20001 "), std::string::npos) << what;
    EXPECT_NE(what.find("0.002 s after the one before, the typical step is 0.001 s"), std::string::npos) << what;
  }
}

TEST(Identification, QuantisedAndNoisyEncodersWithSmoothing)
{
  // The same kind of recording read through 4096-count encoders with Gaussian noise (σ = 1e-4 rad, a fixed seed):
  // every term filtered by the same triangle (r = 80 samples) — the estimates within a few per cent (measured: 0.1–1 %
  // for the inertias, viscous friction and load torque, ~5 % for the motor's Coulomb level), the backlash within two
  // counts.
  ServoParams p;
  p.restitution = 0.5;
  p.motor_coulomb_friction = p.motor_static_friction = 0.05;
  p.load_coulomb_friction = p.load_static_friction = 0.1;
  p.load_torque = 0.2;
  Recording r = record(p, 60.0, 1000.0, 1.0);
  const double count = 2.0 * M_PI / 4096.0;
  std::mt19937 gen(7);
  std::normal_distribution<double> noise(0.0, 1e-4);
  for (std::size_t k = 0; k < r.time.size(); ++k)
  {
    r.motor_position[k] = count * std::floor(r.motor_position[k] / count) + noise(gen);
    r.load_position[k] = count * std::floor(r.load_position[k] / count) + noise(gen);
  }
  IdentificationSettings s;
  s.contact_band = 2.0 * count + 6e-4;
  s.smoothing = 80;
  s.still_speed = 0.02;
  const InitialEstimates e = estimateInitial(r, s);
  EXPECT_NEAR(e.backlash.value, p.backlash, 2.0 * count);
  expectClose(e.motor_inertia, p.motor_inertia, 0.02, 0.0, "J_m");
  expectClose(e.load_inertia, p.load_inertia, 0.02, 0.0, "J_L");
  expectClose(e.motor_friction, p.motor_friction, 0.03, 0.0, "f_m");
  expectClose(e.load_friction, p.load_friction, 0.03, 0.0, "f_L");
  expectClose(e.motor_coulomb_friction, p.motor_coulomb_friction, 0.1, 0.0, "T_cm");
  expectClose(e.load_coulomb_friction, p.load_coulomb_friction, 0.05, 0.0, "T_cL");
  expectClose(e.load_torque, p.load_torque, 0.02, 0.0, "T_ext");
  // The whole identification (auto: the joint fit of the backlash and the restitution on measured angles, windows
  // started from the angles as recorded): e within 2 % (measured 1 %; 6e-4 on a recording with rests), Δ within a
  // count.
  ServoParams prior;
  const JointIdentification id = identifyJoint(r, s, prior, IdentifyOptions());
  for (const IdentifiedParameter& q : id.parameters)
  {
    if (q.key == "restitution")
    {
      std::printf("restitution %.6g → %.6g (joint fit)\n", q.initial.value, q.value.value);
      EXPECT_NEAR(q.value.value, p.restitution, 2e-2 * p.restitution);
    }
    if (q.key == "backlash")
    {
      EXPECT_NEAR(q.value.value, p.backlash, count);
    }
  }
  // Without the smoothing the differences of the counts swamp the fit.
  s.smoothing = 0;
  const InitialEstimates raw = estimateInitial(r, s);
  EXPECT_GT(std::fabs(raw.load_inertia.value - p.load_inertia), 0.1 * p.load_inertia);
}

TEST(Identification, RestitutionFittedByReplayingWindowsOfTheRecording)
{
  // The simulator as the model over windows re-anchored on the recorded state: e recovered for plastic, lossy and
  // nearly elastic teeth (the truth within 0.01 and within a few standard errors).
  for (const double e : {0.0, 0.5, 0.8})
  {
    SCOPED_TRACE(e);
    ServoParams p;
    p.restitution = e;
    p.motor_coulomb_friction = p.motor_static_friction = 0.05;
    p.load_coulomb_friction = p.load_static_friction = 0.1;
    p.load_torque = 0.2;
    const Recording r = record(p, 40.0, 1000.0, 1.0);
    IdentificationSettings s;
    const InitialEstimates initial = estimateInitial(r, s);
    const Estimate fitted = fitRestitution(r, s, initial);
    EXPECT_NEAR(fitted.value, e, 0.01);
    if (std::isfinite(fitted.standard_error))
    {
      EXPECT_LT(std::fabs(fitted.value - e), 0.01 + 10.0 * fitted.standard_error);
    }
    std::printf("e %.2f: fitted %.5f ± %.2g\n", e, fitted.value, fitted.standard_error);
  }
}

TEST(Identification, TheExperimentsDitherKeepsTheBodiesFromSticking)
{
  // A joint whose static friction is well above its Coulomb level sticks at every slow reversal of the experiment (the
  // Coulomb level then shows only in stick-slip). The dither — a fast sine of the command on every segment (20 ω_n),
  // a torque K a_d above the pair's static level — keeps the bodies breaking away: the share of samples of the slow
  // sine where the motor stands still falls tenfold, the load's threefold.
  ServoParams p;
  p.gain = 5.0;
  p.restitution = 0.5;
  p.motor_coulomb_friction = 0.05;
  p.motor_static_friction = 0.3;
  p.load_coulomb_friction = 0.1;
  p.load_static_friction = 0.5;
  DriveParams d;
  d.controller_rate = 1000.0;
  const double duration = 30.0, travel = 0.9, f_d = 20.0 * p.naturalFrequency() / (2.0 * PI);
  const auto stuckShare = [&](double dither) {
    const std::vector<ProfileSegment> experiment = identificationExperiment(p, duration, travel, dither, f_d);
    for (const ProfileSegment& s : experiment)
    {
      EXPECT_EQ(s.dither_amplitude, dither);
      EXPECT_EQ(s.dither_frequency, dither > 0.0 ? f_d : 0.0);
    }
    Simulator sim(p, State(), 0.0);
    sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, 0.0, 0.0));
    sim.setProfile(std::make_shared<CommandProfile>(0.0, experiment));
    int samples = 0;
    std::pair<double, double> stuck{0.0, 0.0};
    for (double t = 0.001; t < duration / 3.0; t += 0.001, ++samples)
    {
      sim.advanceTo(t);
      stuck.first += sim.state().motor_velocity == 0.0 ? 1.0 : 0.0;
      stuck.second += sim.state().load_velocity == 0.0 ? 1.0 : 0.0;
    }
    return std::make_pair(stuck.first / samples, stuck.second / samples);
  };
  const auto plain = stuckShare(0.0), dithered = stuckShare(0.2);
  std::printf(
      "at rest over the slow sine's samples: motor %.1f %%, load %.1f %% without a dither; %.1f %%, %.1f %% with "
      "K·a_d = 1 N·m at %.3g Hz\n",
      100.0 * plain.first, 100.0 * plain.second, 100.0 * dithered.first, 100.0 * dithered.second, f_d);
  EXPECT_GT(plain.first, 0.1);
  EXPECT_GT(plain.second, 0.1);
  EXPECT_LT(dithered.first, 0.1 * plain.first);
  EXPECT_LT(dithered.second, 0.3 * plain.second);
  // The profile carries it: θ_R = v₀ + A sin 2πft + a_d sin 2πf_d t, checked at one instant by hand.
  const std::vector<ProfileSegment> e = identificationExperiment(p, duration, travel, 0.1, f_d);
  const CommandProfile profile(0.0, e);
  const double t = 1.234;
  EXPECT_NEAR(profile.at(t), travel * std::sin(2.0 * PI * e[0].frequency * t) + 0.1 * std::sin(2.0 * PI * f_d * t),
              1e-14);
  // The continuous law takes a dithered sine exactly (two sines) unless the joint's modes carry only one (a torsional
  // shaft) or rigid teeth have dry friction; a dither needs a frequency.
  EXPECT_NO_THROW(profile.requireTakenBy(false, false, true));
  EXPECT_THROW(profile.requireTakenBy(false, false, true, 1), InvalidParameterError);
  EXPECT_THROW(profile.requireTakenBy(false, true, false), InvalidParameterError);
  EXPECT_THROW(identificationExperiment(p, duration, travel, 0.1, 0.0), InvalidParameterError);
}
