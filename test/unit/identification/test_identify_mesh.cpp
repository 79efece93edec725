// A joint with a compliant mesh identified from its own recording: joints simulated with known parameters (the exact
// motion is the truth).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>

#include <variant>

#include "backlash_servo/identification/identify_joint.h"
#include "backlash_servo/identification/joint_fit.h"
#include "backlash_servo/model/param_table.h"
#include "identification/identify_mesh.h"
#include "recorded_joint.h"

using namespace backlash_servo;

namespace
{
ServoParams compliantTruth()
{
  ServoParams p = dryFrictionJoint();
  p.mesh_stiffness = 1000.0;  // contact frequency √(c/μ) = 105 rad/s, μ = 0.09 kg·m²: resolved at 1 kHz
  p.mesh_damping = 2.0;       // ζ_c ≈ 0.1
  return p;
}
}  // namespace

/// 40 s at 1 kHz with rests (recorded once: the compliant joint under held torques is the slow part).
const Recording& recording()
{
  static const Recording r = recordJoint(compliantTruth(), 40.0, 1000.0, 1.0, true);
  return r;
}

double valueOf(const ServoParams& p, const std::string& key)
{
  return p.*std::get<double ServoParams::*>(findParam(key)->field);
}

TEST(IdentifyMesh, InitialEstimatesOfACompliantJoint)
{
  // Exact data: the bodies from the whole joint's torque balance to 1e-4, the mesh from the torque it transmits to
  // 1 % (the differences average the contact's oscillation over a sample: O((ωh)²) with ω = 105 rad/s, h = 1 ms),
  // the backlash between the fitted flanks to 1e-4, static friction from each body's rests to 3 %.
  const ServoParams p = compliantTruth();
  const InitialEstimates e = estimateCompliantInitial(recording(), IdentificationSettings());
  const std::map<std::string, Estimate> estimates = e.byKey();
  for (const auto& [key, x] : estimates)
  {
    const double truth = valueOf(p, key);
    std::printf("  %-24s %-12.7g ± %-9.2g truth %.6g\n", key.c_str(), x.value, x.standard_error, truth);
    const double tolerance = key.rfind("mesh_", 0) == 0 ? 1e-2 : key.find("static") != std::string::npos ? 3e-2 : 1e-4;
    EXPECT_NEAR(x.value, truth, tolerance * std::fabs(truth)) << key;
  }
  EXPECT_EQ(estimates.size(), 12u);
  EXPECT_NEAR(e.zero_offset, 0.0, 1e-4 * p.backlash);
  std::printf("  zero offset %.3g rad; samples: mesh pressed %zu, free %zu\n", e.zero_offset, e.contact_samples,
              e.apart_samples);
  EXPECT_GT(e.contact_samples, 1000u);
}

TEST(IdentifyMesh, RefusesWhatTheRecordingCannotTell)
{
  // The mesh pressed on one flank only (a load torque keeps the teeth on it): no second flank, no backlash; and the
  // load moving one way only, its friction not told from the load torque unless that is given.
  ServoParams p = compliantTruth();
  p.load_torque = -5.0;
  const Recording r = recordJoint(p, 5.0, 1000.0, 0.5);
  IdentificationSettings s;
  s.load_torque_fallback = p.load_torque;  // (the load moves one way: the load torque given)
  try
  {
    estimateCompliantInitial(r, s);
    ADD_FAILURE() << "a mesh pressed on one flank was accepted";
  }
  catch (const InvalidParameterError& e)
  {
    std::printf("%s\n", e.what());
    EXPECT_NE(std::string(e.what()).find("flank only"), std::string::npos);
  }
  EXPECT_THROW(estimateCompliantInitial(r, IdentificationSettings()), InvalidParameterError);
  // A compliant joint's recording read as rigid teeth: refused, saying the mesh looks compliant.
  try
  {
    estimateInitial(recording(), IdentificationSettings());
    ADD_FAILURE() << "a compliant recording was taken for rigid teeth";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("mesh_stiffness > 0"), std::string::npos) << e.what();
  }
}

TEST(IdentifyMesh, TheJointFitRecoversTheCompliantJoint)
{
  // The joint fit with the compliant joint as the model, started 10–30 % off on every parameter (the static levels
  // held at the rests' estimates): back to the truth within 1e-3 (the static levels' error is what remains).
  const ServoParams p = compliantTruth();
  const InitialEstimates e = estimateCompliantInitial(recording(), IdentificationSettings());
  ServoParams start = p;
  const std::vector<std::string> keys = jointFitKeysFor(p);
  ASSERT_EQ(keys.size(), 10u);
  const double factors[] = {1.1, 0.8, 1.2, 0.9, 1.3, 0.85, 1.15, 0.9, 0.7, 1.25};
  for (std::size_t i = 0; i < keys.size(); ++i)
  {
    start.*std::get<double ServoParams::*>(findParam(keys[i])->field) *= factors[i];
  }
  start.motor_static_friction = e.motor_static_friction.value;
  start.load_static_friction = e.load_static_friction.value;
  JointFitSettings f;
  f.keys = keys;
  f.windows = 30;
  const JointFit fit = fitJoint(recording(), IdentificationSettings(), e.zero_offset, start, f);
  std::printf("joint fit: rms %.3g → %.3g rad, %d evaluations, condition %.3g\n", fit.start_rms, fit.rms,
              fit.evaluations, fit.condition);
  for (const FittedParameter& q : fit.parameters)
  {
    const double t = valueOf(p, q.key);
    std::printf("  %-24s start %-10.5g fitted %-12.7g ± %-9.2g truth %.6g\n", q.key.c_str(), q.start, q.value,
                q.standard_error, t);
    EXPECT_NEAR(q.value, t, 1e-3 * std::fabs(t)) << q.key;
    EXPECT_TRUE(q.informed) << q.key;
  }
  EXPECT_LT(fit.rms, 1e-2 * fit.start_rms);
}

TEST(IdentifyMesh, MeasuredAnglesFromFineEncoders)
{
  // The same recording read through 18-bit encoders with Gaussian noise (σ = 1e-6 rad, a fixed seed), every term
  // filtered (r = 12 samples), identified from a prior that says only that the mesh is compliant: on measured angles
  // the joint fit adjusts the backlash and the mesh (auto), the bodies keep the filtered fits. Measured: the bodies
  // within 1.5 %, Δ within 1e-5, c within 0.3 %, d within 0.7 % (over 20–40 windows alike); the static levels are
  // lower bounds (a filtered breakaway has no sharp instant) — 17 % and 3 % below the truth.
  const ServoParams p = compliantTruth();
  Recording r = recording();
  const double count = 2.0 * M_PI / (1 << 18), sigma = 1e-6;
  std::mt19937 gen(7);
  std::normal_distribution<double> noise(0.0, sigma);
  for (std::size_t k = 0; k < r.time.size(); ++k)
  {
    r.motor_position[k] = count * std::floor(r.motor_position[k] / count) + noise(gen);
    r.load_position[k] = count * std::floor(r.load_position[k] / count) + noise(gen);
  }
  IdentificationSettings s;
  s.contact_band = 2.0 * count + 6.0 * sigma;
  s.smoothing = 12;
  s.still_speed = 0.02;
  ServoParams prior;
  prior.mesh_stiffness = 5000.0;
  IdentifyOptions options;
  options.fit.windows = 30;
  const JointIdentification id = identifyJoint(r, s, prior, options);
  ASSERT_TRUE(id.joint_fit);
  std::printf("joint fit: rms %.3g → %.3g rad, %d evaluations\n", id.fit.start_rms, id.fit.rms, id.fit.evaluations);
  std::map<std::string, double> tolerance = {
      {"backlash", 1e-4},      {"mesh_stiffness", 0.01},         {"mesh_damping", 0.03},
      {"motor_inertia", 0.02}, {"load_inertia", 0.02},           {"motor_friction", 0.02},
      {"load_friction", 0.02}, {"motor_coulomb_friction", 0.03}, {"load_coulomb_friction", 0.02},
      {"load_torque", 0.02}};
  for (const IdentifiedParameter& q : id.parameters)
  {
    const double t = valueOf(p, q.key);
    std::printf("  %-24s initial %-12.6g fitted %-12.6g truth %g%s\n", q.key.c_str(), q.initial.value, q.value.value, t,
                q.in_joint_fit ? " (joint fit)" : "");
    if (q.key.find("static") != std::string::npos)
    {
      EXPECT_LE(q.value.value, 1.02 * t) << q.key;  // a lower bound
      EXPECT_GE(q.value.value, 0.7 * t) << q.key;
      EXPECT_TRUE(std::isnan(q.value.standard_error)) << q.key;
    }
    else
    {
      EXPECT_NEAR(q.value.value, t, tolerance.at(q.key) * t) << q.key;
    }
    EXPECT_EQ(q.in_joint_fit, q.key == "backlash" || q.key.rfind("mesh_", 0) == 0) << q.key;
  }
  EXPECT_EQ(id.parameters.size(), 12u);
}
