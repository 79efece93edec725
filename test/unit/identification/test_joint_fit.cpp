// The joint fit (every listed parameter at once, the exact simulator as the model over re-anchored windows) against
// joints simulated with known parameters: the exact motion is the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "backlash_servo/identification/identification.h"
#include "backlash_servo/identification/joint_fit.h"
#include "backlash_servo/identification/replay_windows.h"
#include "backlash_servo/simulation/simulator.h"
#include "recorded_joint.h"

using namespace backlash_servo;

namespace
{
Recording record(const ServoParams& p, double seconds, double rate, double a)
{
  return recordJoint(p, seconds, rate, a, true);
}

ServoParams truth()
{
  ServoParams p = dryFrictionJoint();
  p.restitution = 0.5;
  return p;
}

double ServoParams::*member(const std::string& key)
{
  if (key == "backlash")
    return &ServoParams::backlash;
  if (key == "motor_inertia")
    return &ServoParams::motor_inertia;
  if (key == "load_inertia")
    return &ServoParams::load_inertia;
  if (key == "motor_friction")
    return &ServoParams::motor_friction;
  if (key == "load_friction")
    return &ServoParams::load_friction;
  if (key == "motor_coulomb_friction")
    return &ServoParams::motor_coulomb_friction;
  if (key == "load_coulomb_friction")
    return &ServoParams::load_coulomb_friction;
  if (key == "load_torque")
    return &ServoParams::load_torque;
  return &ServoParams::restitution;
}
}  // namespace

TEST(ReplayWindows, TheTrueJointReplaysItsOwnRecordingToRounding)
{
  // Independent of any fit: the windows re-anchored on the exact recording, replayed with the true parameters, give
  // the recording back (the anchors' velocities are central differences: O(h²) of the motion, so not to rounding —
  // but far below the residual of a wrong parameter).
  const ServoParams p = truth();
  const Recording r = record(p, 20.0, 1000.0, 1.0);
  IdentificationSettings s;
  const std::size_t length = 200;
  const ReplayWindows w(r, s, 0.0, ReplayWindows::spread(r.time.size(), length, 20), length);
  EXPECT_EQ(w.starts().size(), 20u);
  std::vector<double> res;
  w.residuals(p, &res);
  ASSERT_EQ(res.size(), w.size());
  double worst = 0.0;
  for (double v : res)
  {
    worst = std::max(worst, std::fabs(v));
  }
  ServoParams off = p;
  off.load_inertia *= 1.01;
  std::vector<double> res_off;
  w.residuals(off, &res_off);
  double worst_off = 0.0;
  for (double v : res_off)
  {
    worst_off = std::max(worst_off, std::fabs(v));
  }
  std::printf("replay of the truth: largest residual %.3g rad; with J_L 1 %% off: %.3g rad\n", worst, worst_off);
  EXPECT_LT(worst, 1e-5);
  EXPECT_GT(worst_off, 20.0 * worst);
}

TEST(Identification, StaticFrictionBracketedByTheRests)
{
  // The torques that held a body at rest bound its static level from below, those that broke it away from above:
  // on exact 1 kHz data both levels within 1 % (the motor's from its rests with the teeth apart, the load's from the
  // pair's rests on a flank less the motor's share).
  const ServoParams p = truth();
  const Recording r = record(p, 40.0, 1000.0, 1.0);
  const InitialEstimates e = estimateInitial(r, IdentificationSettings());
  std::printf("static friction from the rests: motor %.5f ± %.2g (truth %.2f), load %.5f ± %.2g (truth %.2f)\n",
              e.motor_static_friction.value, e.motor_static_friction.standard_error, p.motor_static_friction,
              e.load_static_friction.value, e.load_static_friction.standard_error, p.load_static_friction);
  EXPECT_NEAR(e.motor_static_friction.value, p.motor_static_friction, 1e-2 * p.motor_static_friction);
  EXPECT_NEAR(e.load_static_friction.value, p.load_static_friction, 1e-2 * p.load_static_friction);
  // Without dry friction no body ever rests: nothing to bracket.
  ServoParams smooth;
  IdentificationSettings given;
  given.load_torque_fallback = 0.0;
  const InitialEstimates none = estimateInitial(record(smooth, 20.0, 1000.0, 1.0), given);
  EXPECT_TRUE(std::isnan(none.motor_static_friction.value));
}

TEST(JointFit, RecoversEveryParameterFromAPerturbedStart)
{
  // Exact 1 kHz data with rests (static friction above the Coulomb level on both bodies, held at the levels the
  // rests give): the fit started 10–30 % off on every other parameter comes back to the truth, to the floor the
  // anchors' central-difference velocities leave (≈ 1e-5 rad of residual).
  const ServoParams p = truth();
  const Recording r = record(p, 40.0, 1000.0, 1.0);
  const InitialEstimates e = estimateInitial(r, IdentificationSettings());
  ServoParams start = p;
  const double factors[] = {1.1, 0.8, 1.2, 0.9, 1.3, 0.85, 1.15, 0.9, 0.7};
  std::size_t i = 0;
  for (const std::string& key : jointFitKeysFor(p))
  {
    start.*member(key) *= factors[i++];
  }
  start.motor_static_friction = e.motor_static_friction.value;
  start.load_static_friction = e.load_static_friction.value;
  IdentificationSettings s;
  JointFitSettings f;
  f.keys = jointFitKeysFor(p);
  f.windows = 30;
  const JointFit fit = fitJoint(r, s, 0.0, start, f);
  std::printf("joint fit: rms %.3g → %.3g rad over %zu windows, %d evaluations, condition %.3g\n", fit.start_rms,
              fit.rms, fit.windows, fit.evaluations, fit.condition);
  ASSERT_EQ(fit.parameters.size(), f.keys.size());
  for (const FittedParameter& q : fit.parameters)
  {
    const double t = p.*member(q.key);
    std::printf("  %-24s start %-10.5g fitted %-12.7g truth %-8.4g ± %.2g (|corr| ≤ %.2f with %s)\n", q.key.c_str(),
                q.start, q.value, t, q.standard_error, q.largest_correlation, q.most_correlated_with.c_str());
    EXPECT_NEAR(q.value, t, 1e-3 * std::fabs(t)) << q.key;  // (measured ≤ 2e-5)
    EXPECT_TRUE(q.informed) << q.key;
  }
  EXPECT_LT(fit.rms, 1e-5);
  EXPECT_LT(fit.rms, 1e-2 * fit.start_rms);
  EXPECT_FALSE(fit.budget_exhausted);
  // Correlations: a symmetric matrix with a unit diagonal.
  for (Eigen::Index a = 0; a < fit.correlation.rows(); ++a)
  {
    EXPECT_NEAR(fit.correlation(a, a), 1.0, 1e-12);
    for (Eigen::Index b = 0; b < fit.correlation.cols(); ++b)
    {
      EXPECT_NEAR(fit.correlation(a, b), fit.correlation(b, a), 1e-12);
      EXPECT_LE(std::fabs(fit.correlation(a, b)), 1.0 + 1e-12);
    }
  }
}

TEST(JointFit, SaysWhatTheRecordingDoesNotInform)
{
  // Teeth pressed on one flank by the load torque throughout: no impact, so the restitution is not informed (NaN
  // standard error, its start kept); the inertias are.
  ServoParams p = truth();
  p.load_torque = -3.0;
  p.load_static_friction = p.load_coulomb_friction;
  const Recording r = record(p, 10.0, 1000.0, 0.3);
  double lowest = 1e9, highest = -1e9;
  for (std::size_t k = 0; k < r.time.size(); ++k)
  {
    const double g = r.load_position[k] - p.gear_ratio * r.motor_position[k];
    lowest = std::min(lowest, g);
    highest = std::max(highest, g);
  }
  ASSERT_LT(highest - lowest, 1e-9) << "the recording must stay on one flank";
  IdentificationSettings s;
  JointFitSettings f;
  f.keys = {"load_inertia", "restitution"};
  f.windows = 10;
  f.max_evaluations = 200;
  const JointFit fit = fitJoint(r, s, 0.0, p, f);
  ASSERT_EQ(fit.parameters.size(), 2u);
  EXPECT_TRUE(fit.parameters[0].informed);
  EXPECT_NEAR(fit.parameters[0].value, p.load_inertia, 1e-4);
  EXPECT_FALSE(fit.parameters[1].informed);
  EXPECT_TRUE(std::isnan(fit.parameters[1].standard_error));
  EXPECT_EQ(fit.parameters[1].value, p.restitution);
}

TEST(JointFit, RefusesWhatItCannotFit)
{
  const ServoParams p = truth();
  const Recording r = record(p, 2.0, 1000.0, 1.0);
  IdentificationSettings s;
  JointFitSettings f;
  f.keys = {"gain"};
  EXPECT_THROW(fitJoint(r, s, 0.0, p, f), InvalidParameterError);
  f.keys = {};
  EXPECT_THROW(fitJoint(r, s, 0.0, p, f), InvalidParameterError);
  // Keys that do not describe the joint: a mesh for rigid teeth, a restitution for a compliant mesh; and a torsional
  // shaft (its gear is not measured).
  f.keys = {"mesh_stiffness"};
  EXPECT_THROW(fitJoint(r, s, 0.0, p, f), InvalidParameterError);
  ServoParams compliant = p;
  compliant.mesh_stiffness = 1e4;
  f.keys = {"restitution"};
  EXPECT_THROW(fitJoint(r, s, 0.0, compliant, f), InvalidParameterError);
  compliant.shaft_stiffness = 1e4;
  compliant.gear_inertia = 0.1;
  f.keys = {"load_inertia"};
  EXPECT_THROW(fitJoint(r, s, 0.0, compliant, f), InvalidParameterError);
  // A window shorter than two samples replays nothing of the dynamics: refused, naming the key and the period.
  f.keys = {"backlash"};
  f.window = 1e-9;
  try
  {
    fitJoint(r, s, 0.0, p, f);
    FAIL() << "accepted a window below one sample";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("window"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("0.001 s"), std::string::npos) << e.what();
  }
}

TEST(JointFit, MeasuredAnglesFromFineEncoders)
{
  // The chain backlash_identify runs on measured angles — initial estimates (smoothing r = 10), the restitution by
  // golden section, the joint fit of the impact parameters — on the recording read through 18-bit encoders (2.4e-5
  // rad counts) with Gaussian noise σ = 1e-6 rad (a fixed seed). Measured: the static levels from the rests within
  // 5 % (motor) and 18 % (load: the pair's rests are few and short); the restitution 0.478 → 0.49987; the backlash
  // from the flanks' medians within 1e-5 rad (no window here reaches the backward flank: not informed by the fit);
  // the residual near the counts. (Fitting every parameter on these angles moves the friction levels by up to 1.6 %:
  // the windows' anchors, not the parameters, then set the fit — the initial estimates are better there.)
  const ServoParams p = truth();
  Recording r = record(p, 60.0, 1000.0, 1.0);
  const double count = 2.0 * M_PI / 262144.0;
  std::mt19937 gen(7);
  std::normal_distribution<double> noise(0.0, 1e-6);
  for (std::size_t k = 0; k < r.time.size(); ++k)
  {
    r.motor_position[k] = count * std::floor(r.motor_position[k] / count) + noise(gen);
    r.load_position[k] = count * std::floor(r.load_position[k] / count) + noise(gen);
  }
  IdentificationSettings s;
  s.contact_band = 2.0 * count + 6e-6;
  s.smoothing = 10;
  s.still_speed = 0.02;
  const InitialEstimates e = estimateInitial(r, s);
  EXPECT_NEAR(e.motor_static_friction.value, p.motor_static_friction, 0.1 * p.motor_static_friction);
  EXPECT_NEAR(e.load_static_friction.value, p.load_static_friction, 0.25 * p.load_static_friction);
  ServoParams start = p;
  start.backlash = e.backlash.value;
  start.motor_inertia = e.motor_inertia.value;
  start.load_inertia = e.load_inertia.value;
  start.motor_friction = e.motor_friction.value;
  start.load_friction = e.load_friction.value;
  start.motor_coulomb_friction = e.motor_coulomb_friction.value;
  start.load_coulomb_friction = e.load_coulomb_friction.value;
  start.load_torque = e.load_torque.value;
  start.motor_static_friction = std::max(e.motor_static_friction.value, start.motor_coulomb_friction);
  start.load_static_friction = std::max(e.load_static_friction.value, start.load_coulomb_friction);
  start.restitution = fitRestitution(r, s, e).value;
  JointFitSettings f;
  f.keys = {"backlash", "restitution"};  // (what backlash_identify fits on measured angles by default)
  f.windows = 25;
  f.max_evaluations = 300;
  const JointFit fit = fitJoint(r, s, e.zero_offset, start, f);
  std::printf("measured angles: rms %.3g → %.3g rad, %d evaluations\n", fit.start_rms, fit.rms, fit.evaluations);
  for (const FittedParameter& q : fit.parameters)
  {
    const double t = p.*member(q.key);
    std::printf("  %-24s initial %-10.6g fitted %-10.6g truth %-6.3g ± %.2g\n", q.key.c_str(), q.start, q.value, t,
                q.standard_error);
    EXPECT_NEAR(q.value, t, 1e-3 * std::fabs(t)) << q.key;  // (measured ≤ 2.6e-4)
  }
  EXPECT_LT(fit.rms, 2.0 * count);
}
