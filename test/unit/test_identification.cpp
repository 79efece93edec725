// The initial estimates recover a joint from its own simulated recording (the exact motion is the truth): a torque
// excitation held over 1 kHz samples in effort mode, the angles recorded at the samples.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "backlash_servo/identification.h"
#include "backlash_servo/simulator.h"
#include "recorded_joint.h"

using namespace backlash_servo;

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
