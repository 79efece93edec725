// Live changes of a digital drive's settings (Simulator::retuneDrive, what the node does on dynamic_reconfigure):
// checked sample by sample against the control laws written out here (docs/model.md Part 2, "Digital drive").
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "backlash_servo/simulation/simulator.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

/// One controller sample as the observer saw it: instant t_k [s], reading y_k [rad], reference θ_R,k [rad] and
/// held torque u_k [N·m] (no delay: the output of this sample).
struct Sample
{
  double t, y, reference, u;
};

struct Recorder
{
  std::vector<Sample> samples;
  void attach(Simulator* sim)
  {
    sim->setSampleObserver([this](const State& s, const Drive& d) {
      const auto& drive = dynamic_cast<const SampledDrive&>(d);
      samples.push_back({s.time, drive.loadReading(), drive.reference(), drive.law().offset});
    });
  }
};

ServoParams joint()
{
  ServoParams p;
  p.backlash = 0.05;
  p.restitution = 0.5;
  return p;
}

DriveParams pid()
{
  DriveParams d;
  d.control_law = "pid";
  d.controller_rate = 100.0;
  d.integral_gain = 0.3;
  d.derivative_gain = 0.3;
  return d;
}

/// The joint under drive `d` with the set-point 1 rad from t = 0.
Simulator driven(const ServoParams& p, const DriveParams& d)
{
  Simulator sim(p, State(), 1.0);
  sim.setDrive(std::make_unique<SampledDrive>(d, p.gain, p.gear_ratio, 1.0, 0.0));
  return sim;
}

TEST(LiveRetune, AnIntegralGainChangeKeepsTheIntegratorAndFollowsThePidLaw)
{
  const ServoParams p = joint();
  DriveParams d = pid();
  Simulator sim = driven(p, d);
  Recorder rec;
  rec.attach(&sim);
  sim.advanceTo(5.005);
  const std::size_t before = rec.samples.size();
  const double ki_old = d.integral_gain;
  d.integral_gain = 1.5;
  ASSERT_TRUE(sim.retuneDrive(d));
  sim.advanceTo(10.0);
  ASSERT_GT(rec.samples.size(), before + 400);
  // The PID written out: I_k = u_k − K e_k + K_d (y_k − y_{k−1})/T is the integrator after sample k; its increment
  // is K_i T e_k with the K_i in force at t_k. The first sample after the change adds K_i,new T e_k to the integrator
  // the old gain built up: no bump, no reset.
  const double T = 1.0 / d.controller_rate;
  const double K = p.gain, Kd = d.derivative_gain;
  auto integrator = [&](std::size_t k) {
    const Sample& s = rec.samples[k];
    return s.u - K * (s.reference - s.y) + Kd * (s.y - rec.samples[k - 1].y) / T;
  };
  for (std::size_t k = 2; k < rec.samples.size(); ++k)
  {
    const Sample& s = rec.samples[k];
    const double ki = k < before ? ki_old : d.integral_gain;
    const double increment = integrator(k) - integrator(k - 1);
    EXPECT_NEAR(increment, ki * T * (s.reference - s.y), 1e-12 * (1.0 + std::fabs(integrator(k))))
        << "sample " << k << " at t = " << s.t;
  }
  EXPECT_NEAR(rec.samples[before].t, 5.01, 1e-12);  // the sample due after the change is on the old schedule
}

TEST(LiveRetune, TheSameSettingsChangeNothing)
{
  const ServoParams p = joint();
  const DriveParams d = pid();
  Simulator plain = driven(p, d), retuned = driven(p, d);
  plain.advanceTo(3.0037);
  retuned.advanceTo(3.0037);
  ASSERT_TRUE(retuned.retuneDrive(d));
  plain.advanceTo(20.0);
  retuned.advanceTo(20.0);
  EXPECT_EQ(plain.state().load_position, retuned.state().load_position);
  EXPECT_EQ(plain.state().motor_velocity, retuned.state().motor_velocity);
  EXPECT_EQ(plain.impactCount(), retuned.impactCount());
}

TEST(LiveRetune, ARateChangeKeepsTheDueSampleAndSpacesTheNextOnesByTheNewPeriod)
{
  const ServoParams p = joint();
  DriveParams d = pid();
  Simulator sim = driven(p, d);
  Recorder rec;
  rec.attach(&sim);
  sim.advanceTo(1.003);
  const std::size_t before = rec.samples.size();
  d.controller_rate = 250.0;
  ASSERT_TRUE(sim.retuneDrive(d));
  sim.advanceTo(1.2);
  ASSERT_GT(rec.samples.size(), before + 40);
  EXPECT_NEAR(rec.samples[before].t, 1.01, 1e-12);
  for (std::size_t k = before + 1; k < rec.samples.size(); ++k)
  {
    EXPECT_NEAR(rec.samples[k].t - rec.samples[k - 1].t, 0.004, 1e-12) << k;
  }
}

TEST(LiveRetune, DelayZeroToOneHoldsThePresentOutputOneMoreSample)
{
  const ServoParams p = joint();
  DriveParams d;
  d.controller_rate = 100.0;  // the P law: u_k = K e_k
  Simulator sim = driven(p, d);
  Recorder rec;
  rec.attach(&sim);
  sim.advanceTo(0.505);
  const std::size_t before = rec.samples.size();
  const double held = sim.motorTorque();
  d.controller_delay = 1.0;
  ASSERT_TRUE(sim.retuneDrive(d));
  sim.advanceTo(0.6);
  ASSERT_GT(rec.samples.size(), before + 5);
  EXPECT_EQ(rec.samples[before].u, held);  // [t_k, t_k+1): still the output computed before the change
  for (std::size_t k = before + 1; k < rec.samples.size(); ++k)
  {
    const Sample& prev = rec.samples[k - 1];
    EXPECT_DOUBLE_EQ(rec.samples[k].u, p.gain * (prev.reference - prev.y)) << k;  // one sample late
  }
}

TEST(LiveRetune, ANewLawOrAContinuousRateNeedsAFreshDriveAndBadValuesAreRefused)
{
  const ServoParams p = joint();
  const DriveParams d = pid();
  Simulator sim = driven(p, d);
  sim.advanceTo(1.003);
  const State at = sim.state();
  DriveParams other = d;
  other.control_law = "cascade";
  EXPECT_FALSE(sim.retuneDrive(other));
  other = d;
  other.feedback = "motor";
  EXPECT_FALSE(sim.retuneDrive(other));
  other = d;
  other.compensation = "dither";
  other.dither_amplitude = 0.01;
  other.dither_frequency = 5.0;
  EXPECT_FALSE(sim.retuneDrive(other));
  other = d;
  other.control_law = "proportional";
  other.controller_rate = 0.0;
  EXPECT_FALSE(sim.retuneDrive(other));
  other = d;
  other.controller_delay = 0.5;
  try
  {
    sim.retuneDrive(other);
    ADD_FAILURE() << "a delay of 0.5 samples was accepted";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_NE(std::string(e.what()).find("controller_delay"), std::string::npos) << e.what();
  }
  EXPECT_EQ(sim.state().load_position, at.load_position);
  EXPECT_EQ(dynamic_cast<const SampledDrive&>(sim.drive()).nextEventTime(0.0), 1.01);  // the drive is untouched
  // The continuous law has no settings to retune in place.
  Simulator continuous(p, State(), 1.0);
  EXPECT_FALSE(continuous.retuneDrive(DriveParams()));
}

}  // namespace
