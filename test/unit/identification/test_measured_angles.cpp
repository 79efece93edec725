// Measured angles: each angle's count grid and noise recognised from the data, and the bodies identified from the
// equations integrated over stretches of one phase (the recordings are the simulator's exact motion, read through
// encoders here; the joint's own parameters are the truth).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <sstream>
#include <string>

#include "backlash_servo/identification/identify_joint.h"
#include "backlash_servo/identification/measured_angles.h"
#include "backlash_servo/model/param_table.h"
#include "identification/phase_regression.h"
#include "recorded_joint.h"

using namespace backlash_servo;

namespace
{
constexpr double TWO_PI = 6.283185307179586;

/// A smooth angle: two sines [rad] at 1 kHz for `n` samples.
std::vector<double> smoothAngle(std::size_t n)
{
  std::vector<double> x(n);
  for (std::size_t k = 0; k < n; ++k)
  {
    const double t = 1e-3 * static_cast<double>(k);
    x[k] = 0.7 * std::sin(1.3 * t) + 0.2 * std::sin(5.0 * t + 0.3);
  }
  return x;
}

/// The recording read through N-count encoders on both shafts, with Gaussian noise of σ counts (a fixed seed).
Recording readThroughEncoders(Recording r, double counts, double sigma_counts, unsigned seed = 11)
{
  const double q = TWO_PI / counts;
  std::mt19937 gen(seed);
  std::normal_distribution<double> noise(0.0, sigma_counts * q);
  for (std::vector<double>* angle : {&r.motor_position, &r.load_position})
  {
    for (double& x : *angle)
    {
      x = q * std::round(x / q) + (sigma_counts > 0.0 ? noise(gen) : 0.0);
    }
  }
  return r;
}

/// The dry-friction joint (rigid teeth, a load torque) with restitution 0.5.
ServoParams bouncyJoint()
{
  ServoParams p = dryFrictionJoint();
  p.restitution = 0.5;
  return p;
}

/// bouncyJoint()'s exact 60 s recording at 1 kHz (recordJoint, amplitude 1), simulated once for the tests that read it.
const Recording& bouncyRecording()
{
  static const Recording r = recordJoint(bouncyJoint(), 60.0, 1000.0, 1.0);
  return r;
}

const IdentifiedParameter& parameter(const JointIdentification& id, const std::string& key)
{
  for (const IdentifiedParameter& p : id.parameters)
  {
    if (p.key == key)
    {
      return p;
    }
  }
  throw std::runtime_error("no " + key);
}

}  // namespace

TEST(MeasuredAngles, ExactQuantisedAndNoisyAnglesAreToldApart)
{
  const std::vector<double> exact = smoothAngle(20000);
  const AngleMeasurement a = recogniseAngle(exact, 0.0);
  EXPECT_FALSE(a.measured());
  // On a 4096-count grid: the resolution found from the samples alone, and stated; the noise a count's spread.
  std::vector<double> counted = exact;
  const double q = TWO_PI / 4096.0;
  for (double& x : counted)
  {
    x = q * std::round(x / q);
  }
  for (const double stated : {0.0, 4096.0})
  {
    const AngleMeasurement b = recogniseAngle(counted, stated);
    EXPECT_EQ(b.resolution, 4096.0);
    EXPECT_NEAR(b.noise, q / std::sqrt(12.0), 0.25 * q / std::sqrt(12.0));
  }
  // White noise of σ = 1e-5 rad: no grid, its level within 10 %.
  std::vector<double> noisy = exact;
  std::mt19937 gen(3);
  std::normal_distribution<double> noise(0.0, 1e-5);
  for (double& x : noisy)
  {
    x += noise(gen);
  }
  const AngleMeasurement c = recogniseAngle(noisy, 0.0);
  EXPECT_EQ(c.resolution, 0.0);
  EXPECT_NEAR(c.noise, 1e-5, 1e-6);
}

TEST(MeasuredAngles, TheNoiseInTheAngleNoLongerShrinksTheInertia)
{
  // The motor alone (rigid teeth far apart: a backlash of 100 rad) driven by the recorded torque, its angle read with
  // white noise. Integrated twice over pieces of 60 ms (as short as a flight across the play), the noise in the
  // regressor θ biases J_m low (errors in variables) unless its share of XᵀX is subtracted: with it, J_m and f_m
  // within 2 %.
  ServoParams p;
  p.backlash = 100.0;
  p.motor_inertia = 0.1;
  p.motor_friction = 0.5;
  p.motor_coulomb_friction = p.motor_static_friction = 0.0;
  State start;
  start.contact = Contact::Apart;
  start.load_position = 50.0;
  Simulator sim(p, start, 0.0);
  Recording r;
  std::mt19937 gen(5);
  const double sigma = 3e-4;
  std::normal_distribution<double> noise(0.0, sigma);
  for (int k = 0; k <= 20000; ++k)
  {
    const double t = 1e-3 * k;
    sim.advanceTo(t);
    const double u = 0.3 * std::sin(7.0 * t) + 0.2 * std::sin(19.0 * t);
    sim.setMotorTorque(u);
    r.time.push_back(t);
    r.motor_torque.push_back(u);
    r.motor_position.push_back(sim.state().motor_position + noise(gen));
    r.load_position.push_back(sim.state().load_position);
  }
  std::vector<double> sign(r.time.size());
  for (std::size_t k = 1; k + 1 < sign.size(); ++k)
  {
    const double w = r.motor_position[k + 1] - r.motor_position[k - 1];
    sign[k] = w > 0.0 ? 1.0 : -1.0;  // (no Coulomb level to fit: the sign's errors do not matter here)
  }
  const PhaseRows apart = integratedRows(r, sign, {{100, r.time.size() - 100}}, 60, 0);
  const PhaseRows none;
  const BodiesFit corrected = fitBodies(apart, none, 1.0, NAN, {NAN, NAN}, sigma, true);
  const BodiesFit naive = fitBodies(apart, none, 1.0, NAN, {NAN, NAN}, 0.0, true);
  EXPECT_NEAR(corrected.p(0), p.motor_inertia, 0.02 * p.motor_inertia);
  EXPECT_NEAR(corrected.p(1), p.motor_friction, 0.02 * p.motor_friction);
  EXPECT_LT(naive.p(0), 0.9 * p.motor_inertia);  // (what the correction is for)
  // A known inertia moves its column to the right-hand side (its regressor's noise with it): the viscous coefficient
  // follows from the rest, unbiased.
  const BodiesFit held = fitBodies(apart, none, 1.0, NAN, {p.motor_inertia, NAN}, sigma, true);
  EXPECT_EQ(held.p(0), p.motor_inertia);
  EXPECT_NEAR(held.p(1), p.motor_friction, 0.02 * p.motor_friction);
}

TEST(MeasuredAngles, AJointReadThroughNoisyEncodersIsIdentifiedWithoutFlags)
{
  // The dry-friction joint (rigid teeth, e = 0.5, a load torque) read through 2^18-count encoders with 0.5 counts of
  // noise: no smoothing, band or still speed given — all from the data. Every estimate it reports is within its
  // target and has the truth within four standard errors; what it does not report says why (this excitation's
  // flights are too short for the motor alone at this noise: the pair's sums are given instead).
  const ServoParams p = bouncyJoint();
  const Recording r = readThroughEncoders(bouncyRecording(), 262144.0, 0.5);
  IdentificationSettings s;
  s.gear_ratio = p.gear_ratio;
  ServoParams prior;
  prior.gear_ratio = p.gear_ratio;
  IdentifyOptions options;
  options.stated = std::set<std::string>{"gear_ratio"};
  const JointIdentification id = identifyJoint(r, s, prior, options);
  EXPECT_TRUE(id.measurement.from_data);
  EXPECT_EQ(id.measurement.motor.resolution, 0.0);  // (noise: no grid)
  EXPECT_GT(id.measurement.contact_band, 0.0);
  const std::map<std::string, double> target = {{"backlash", 0.05},
                                                {"motor_inertia", 0.05},
                                                {"load_inertia", 0.05},
                                                {"motor_coulomb_friction", 0.1},
                                                {"load_coulomb_friction", 0.1}};
  for (const auto& [key, tolerance] : target)
  {
    const IdentifiedParameter& q = parameter(id, key);
    const double truth = p.*std::get<double ServoParams::*>(findParam(key)->field);
    if (q.identifiable)
    {
      EXPECT_NEAR(q.value.value, truth, tolerance * truth) << key;
      EXPECT_LE(std::fabs(q.value.value - truth), 4.0 * q.value.standard_error) << key;
    }
    else
    {
      EXPECT_FALSE(q.reason.empty()) << key;
      EXPECT_TRUE(std::isnan(q.value.value)) << key;  // (not stated in the prior: none)
    }
  }
  EXPECT_TRUE(parameter(id, "backlash").identifiable);
  // Where the motor alone is not resolved, the reason gives the pair's sums: J_m + ρ²J_L = 1 kg·m² here.
  const IdentifiedParameter& load = parameter(id, "load_inertia");
  const std::size_t at = load.reason.find("J_m + ρ²J_L = ");
  if (!load.identifiable && at != std::string::npos)
  {
    const double sum = std::stod(load.reason.substr(at + std::string("J_m + ρ²J_L = ").size()));
    EXPECT_NEAR(sum, p.motor_inertia + p.gear_ratio * p.gear_ratio * p.load_inertia, 0.01) << load.reason;
  }
}

TEST(MeasuredAngles, AStatedMotorInertiaSplitsThePair)
{
  // The noisy recording above, where the flights are too short for the motor alone: a prior stating J_m (a datasheet's
  // value) and not fitting it gives the load's inertia from the pair's sum, within 5 % and the truth within four
  // standard errors. A stated J_m 30 % off is caught by the stretches apart, which then split no friction.
  const ServoParams p = bouncyJoint();
  const Recording r = readThroughEncoders(bouncyRecording(), 262144.0, 0.5);
  IdentificationSettings s;
  s.gear_ratio = p.gear_ratio;
  IdentifyOptions options;
  options.stated = std::set<std::string>{"gear_ratio", "motor_inertia"};
  options.keys = std::set<std::string>{"backlash",      "load_inertia",           "motor_friction",
                                       "load_friction", "motor_coulomb_friction", "load_coulomb_friction",
                                       "load_torque"};
  ServoParams prior;
  prior.gear_ratio = p.gear_ratio;
  prior.motor_inertia = p.motor_inertia;
  const JointIdentification id = identifyJoint(r, s, prior, options);
  const IdentifiedParameter& load = parameter(id, "load_inertia");
  ASSERT_TRUE(load.identifiable) << load.reason;
  EXPECT_NEAR(load.value.value, p.load_inertia, 0.05 * p.load_inertia);
  EXPECT_LE(std::fabs(load.value.value - p.load_inertia), 4.0 * load.value.standard_error);
  EXPECT_EQ(id.model.motor_inertia, p.motor_inertia);  // (held, not estimated)
  prior.motor_inertia = 1.3 * p.motor_inertia;
  const JointIdentification wrong = identifyJoint(r, s, prior, options);
  const IdentifiedParameter& friction = parameter(wrong, "motor_coulomb_friction");
  EXPECT_FALSE(friction.identifiable);
  EXPECT_NE(friction.reason.find("do not move the motor as its stated inertia"), std::string::npos) << friction.reason;
}

TEST(MeasuredAngles, TheBacklashsErrorIsTheScatterOfItsContactEpisodes)
{
  // One motion read through 4096-count encoders (the backlash 196 counts) with one count of noise, four draws of the
  // noise: each backlash is reported with a standard error from the scatter of the episodes of contact on the two
  // flanks — informative (within 0.35 % of the backlash, where one sample's scatter on each flank claims 0.41 %) and
  // honest (the truth within four of them).
  const ServoParams p = bouncyJoint();
  const Recording& exact = bouncyRecording();
  IdentificationSettings s;
  s.gear_ratio = p.gear_ratio;
  ServoParams prior;
  prior.gear_ratio = p.gear_ratio;
  IdentifyOptions options;
  options.stated = std::set<std::string>{"gear_ratio"};
  options.keys = std::set<std::string>{"backlash"};
  for (unsigned seed : {1u, 2u, 3u, 4u})
  {
    const JointIdentification id = identifyJoint(readThroughEncoders(exact, 4096.0, 1.0, seed), s, prior, options);
    const IdentifiedParameter& backlash = parameter(id, "backlash");
    ASSERT_TRUE(backlash.identifiable) << backlash.reason;
    EXPECT_LE(backlash.value.standard_error, 0.0035 * p.backlash) << seed;
    EXPECT_LE(std::fabs(backlash.value.value - p.backlash), 4.0 * backlash.value.standard_error) << seed;
  }
}

TEST(MeasuredAngles, ABacklashOfTwoLoadCountsIsFoundAtTheLoadsCountEdges)
{
  // The backlash 1.5 counts of a 4096-count load encoder, the motor's 2^20 counts a turn: the gap's band (half a count
  // of each angle) does not resolve the flanks, but at each change of the load's count the gap is known to the motor's
  // resolution — the backlash within 5 % with the truth within four standard errors, and the pair (the teeth in
  // contact between edges on one flank) gives J_m + ρ²J_L = 1 kg·m² within 5 %, the truth within four of its
  // standard errors.
  ServoParams p = dryFrictionJoint();
  p.restitution = 0.3;
  p.backlash = 1.5 * TWO_PI / 4096.0;
  Recording r = recordJoint(p, 60.0, 1000.0, 1.0);
  const double ql = TWO_PI / 4096.0, qm = TWO_PI / 1048576.0;
  for (std::size_t k = 0; k < r.time.size(); ++k)
  {
    r.load_position[k] = ql * std::round(r.load_position[k] / ql);
    r.motor_position[k] = qm * std::round(r.motor_position[k] / qm);
  }
  IdentificationSettings s;
  s.gear_ratio = p.gear_ratio;
  s.load_encoder_resolution = 4096.0;
  s.motor_encoder_resolution = 1048576.0;
  ServoParams prior;
  IdentifyOptions options;
  options.stated = std::set<std::string>{"gear_ratio"};
  const JointIdentification id = identifyJoint(r, s, prior, options);
  EXPECT_TRUE(id.initial.phases_from_edges);
  const IdentifiedParameter& backlash = parameter(id, "backlash");
  ASSERT_TRUE(backlash.identifiable);
  EXPECT_NEAR(backlash.value.value, p.backlash, 0.05 * p.backlash);
  EXPECT_LE(std::fabs(backlash.value.value - p.backlash), 4.0 * backlash.value.standard_error);
  const IdentifiedParameter& load = parameter(id, "load_inertia");
  ASSERT_FALSE(load.identifiable);
  const std::size_t at = load.reason.find("J_m + ρ²J_L = ");
  ASSERT_NE(at, std::string::npos) << load.reason;
  std::istringstream sum(load.reason.substr(at + std::string("J_m + ρ²J_L = ").size()));
  double value = 0.0, error = 0.0;
  std::string plus_minus;
  sum >> value >> plus_minus >> error;
  EXPECT_NEAR(value, 1.0, 0.05) << load.reason;
  EXPECT_LE(std::fabs(value - 1.0), 4.0 * error) << load.reason;
}
