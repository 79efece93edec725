// The digital drive (docs/model.md Part 2): sampling with a zero-order hold, delay, encoders,
// P / PID / cascade, saturation — against closed forms and limits written here. The reference cases of
// test/joint_cases/reference_cases.json run in tools/test_repository.cpp (JointCases).
#include <gtest/gtest.h>

#include <cmath>

#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;
constexpr double TWO_PI = 6.283185307179586476925;

RunSummary run(const DriveParams& d, double duration, ServoParams p = ServoParams())
{
  RunConfig c;
  c.params = p;
  c.drive = d;
  c.duration = duration;
  return runResponse(c);
}

TEST(Drive, SampledPLawTendsToTheContinuousCycleAtFirstOrder)
{
  // As f_s grows the D1 limit cycle tends to the continuous 0.0514732 rad, the error ∝ 1/f_s (measured 5.7e-4 at
  // 100 Hz, 5.8e-5 at 1 kHz).
  const double continuous = run(DriveParams(), 1500.0).status.error;
  DriveParams d;
  d.controller_rate = 100.0;
  const double e100 = run(d, 1500.0).status.error - continuous;
  d.controller_rate = 1000.0;
  const double e1000 = run(d, 1500.0).status.error - continuous;
  EXPECT_NEAR(continuous, 0.0514732, 1e-7);
  EXPECT_GT(e1000, 0.0);
  EXPECT_NEAR(e100 / e1000, 10.0, 0.5);
}

TEST(Drive, ZeroOrderHoldDelayAndEncoderReadings)
{
  ServoParams p;
  DriveParams d;
  d.controller_rate = 100.0;
  d.load_encoder_resolution = 1000.0;
  d.motor_encoder_resolution = 500.0;
  State s;
  s.load_position = 0.0123;
  s.motor_position = 0.0123;
  SampledDrive drive(d, p.gain, p.gear_ratio, 1.0, 0.0);
  drive.sample(s);
  // q(θ) = 2π/N floor(Nθ/2π): 0.0123 rad is 1.957… counts of 2π/1000 → 1 count; of 2π/500 → 0 counts.
  EXPECT_DOUBLE_EQ(drive.loadReading(), TWO_PI / 1000.0);
  EXPECT_DOUBLE_EQ(drive.motorReading(), 0.0);
  EXPECT_DOUBLE_EQ(drive.law().offset, p.gain * (1.0 - TWO_PI / 1000.0));  // u_0 = K e_0, held
  EXPECT_DOUBLE_EQ(drive.nextEventTime(0.0), 0.01);
  // With one sample of delay the torque is 0 on [0, T) and u_0 on [T, 2T).
  d.controller_delay = 1.0;
  SampledDrive late(d, p.gain, p.gear_ratio, 1.0, 0.0);
  late.sample(s);
  EXPECT_EQ(late.law().offset, 0.0);
  late.sample(s);
  EXPECT_DOUBLE_EQ(late.law().offset, p.gain * (1.0 - TWO_PI / 1000.0));
  // Through the simulator: the held torque is constant between samples.
  Simulator sim(p, State(), 1.0);
  d.controller_delay = 0.0;
  d.load_encoder_resolution = 0.0;
  d.motor_encoder_resolution = 0.0;
  sim.setDrive(std::make_unique<SampledDrive>(d, p.gain, p.gear_ratio, 1.0, 0.0));
  sim.advanceTo(0.004);
  EXPECT_DOUBLE_EQ(sim.motorTorque(), 1.0);
  sim.advanceTo(0.0099);
  EXPECT_DOUBLE_EQ(sim.motorTorque(), 1.0);
  sim.advanceTo(0.0101);
  EXPECT_LT(sim.motorTorque(), 1.0);
}

TEST(Drive, PidOnTheMotorEncoderCannotSeeTheBacklash)
{
  // Semi-closed loop: the integral drives the motor reading to the command; the load stops wherever the backlash
  // leaves it, within Δ of the command.
  ServoParams p;
  p.backlash = 0.05;
  p.restitution = 0.5;
  DriveParams d;
  d.controller_rate = 1000.0;
  d.control_law = "pid";
  d.feedback = "motor";
  d.integral_gain = 0.3;
  d.derivative_gain = 0.3;
  const RunSummary r = run(d, 600.0, p);
  EXPECT_NEAR(r.final_state.motor_position * p.gear_ratio, 1.0, 1e-6);
  EXPECT_LE(std::fabs(r.final_state.load_position - 1.0), p.backlash + 1e-9);
}

TEST(Drive, TorqueLimitNeverReachedChangesNothingAndAReachedOneHolds)
{
  DriveParams d;
  d.controller_rate = 1000.0;
  d.control_law = "pid";
  d.integral_gain = 0.2;
  const RunSummary free = run(d, 100.0);
  d.torque_limit = 10.0;  // |u| stays near 1 N·m
  const RunSummary loose = run(d, 100.0);
  ASSERT_EQ(free.maxima.size(), loose.maxima.size());
  for (std::size_t i = 0; i < free.maxima.size(); ++i)
  {
    EXPECT_EQ(free.maxima[i].position, loose.maxima[i].position);
  }
  // A limit that is reached: the motor torque never exceeds it, and anti-windup keeps the integrator bounded
  // (the run converges instead of winding up).
  d.torque_limit = 0.3;
  ServoParams p;
  Simulator sim(p, State(), 1.0);
  sim.setDrive(std::make_unique<SampledDrive>(d, p.gain, p.gear_ratio, 1.0, 0.0));
  double worst = 0.0;
  for (int i = 1; i <= 20000; ++i)
  {
    sim.advanceTo(i * 0.01);
    worst = std::max(worst, std::fabs(sim.motorTorque()));
  }
  EXPECT_LE(worst, 0.3);
  EXPECT_NEAR(worst, 0.3, 1e-12);
}

TEST(Drive, CombinationsTheModelDoesNotDefineAreRefused)
{
  DriveParams pid;
  pid.control_law = "pid";
  EXPECT_THROW(pid.validate(), InvalidParameterError);  // pid without a rate
  DriveParams delay;
  delay.controller_rate = 100.0;
  delay.controller_delay = 2.0;
  EXPECT_THROW(delay.validate(), InvalidParameterError);
  DriveParams motor;
  motor.feedback = "motor";
  EXPECT_THROW(motor.validate(), InvalidParameterError);  // continuous law on the motor
  DriveParams law;
  law.control_law = "bang_bang";
  EXPECT_THROW(law.validate(), InvalidParameterError);
}

}  // namespace

namespace
{
TEST(Drive, ContinuousTorqueLimitSwitchesExactlyAtTheBandEdges)
{
  // Δ = 0: J θ'' + F θ' = ρ sat(K(θ_R − θ)), against RK4 in long double with fine steps (the kinks at the switches
  // cost it accuracy, hence 1e-8); and the switches happen exactly where K|θ_R − θ| = T_max.
  ServoParams p;
  p.backlash = 0.0;
  DriveParams d;
  d.torque_limit = 0.3;
  RunConfig c;
  c.params = p;
  c.drive = d;
  const double j = p.totalInertia(), f = p.totalFriction(), rho = p.gear_ratio, k = p.gain, tmax = 0.3;
  using L = long double;
  L x = 0, v = 0;
  auto acc = [&](L xx, L vv) {
    L u = k * (1.0L - xx);
    u = u > tmax ? tmax : (u < -tmax ? -tmax : u);
    return (rho * u - f * vv) / j;
  };
  const L h = 1e-5L;
  Simulator sim(p, State(), 1.0);
  sim.setDrive(std::make_unique<ProportionalDrive>(p.gain, 1.0, tmax));
  struct Switches : EventSink
  {
    void onEvent(const Event&) override {}
  } none;
  long steps = 0;
  for (double target : {1.0, 3.0, 6.0, 12.0})
  {
    for (; steps < std::lround(target / 1e-5); ++steps)
    {
      const L k1x = v, k1v = acc(x, v);
      const L k2x = v + h / 2 * k1v, k2v = acc(x + h / 2 * k1x, v + h / 2 * k1v);
      const L k3x = v + h / 2 * k2v, k3v = acc(x + h / 2 * k2x, v + h / 2 * k2v);
      const L k4x = v + h * k3v, k4v = acc(x + h * k3x, v + h * k3v);
      x += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
      v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
    }
    sim.advanceTo(target, &none);
    EXPECT_NEAR(sim.state().load_position, static_cast<double>(x), 1e-8) << target;
    EXPECT_LE(std::fabs(sim.motorTorque()), tmax + 1e-15);
  }
  // Saturated at the start (K·1 > T_max), linear near the command: the torque is exactly the law of its region.
  const double e = 1.0 - sim.state().load_position;
  EXPECT_DOUBLE_EQ(sim.motorTorque(), std::fabs(k * e) <= tmax ? k * e : (e > 0 ? tmax : -tmax));
  const RunSummary r = runResponse(c);
  EXPECT_TRUE(r.settled);
  EXPECT_LE(std::fabs(r.balance_error), 1e-12 * r.energy.input);
}
}  // namespace

// A loop beyond its stability limit is reported "diverged" where the motion leaves the closed forms' bounds (it used
// to be computed on into overflowing numbers, NaN, or a stack overflow in the root isolation). Truth: a rigid,
// frictionless joint (Δ = 0, f = 0) under a sampled P law is the ZOH double integrator
// (z − 1)² + (a/2)(z + 1) = 0, a = K T²/J: roots of modulus r = √(1 + a/2) at angle φ, cos φ = (2 − a/2)/(2r), so the
// swing grows by r^{2π/φ} per oscillation.
TEST(Drive, AnUnstableLoopIsReportedDivergedWithItsGrowthRate)
{
  ServoParams p;
  p.motor_inertia = 1.0;
  p.load_inertia = 1.0;
  p.motor_friction = 0.0;
  p.load_friction = 0.0;
  p.backlash = 0.0;
  p.gain = 10.0;
  DriveParams d;
  d.controller_rate = 10.0;
  const RunSummary r = run(d, 1000.0, p);
  EXPECT_EQ(r.status.verdict, Verdict::Diverged);
  EXPECT_EQ(r.stopped_by, "diverged");
  EXPECT_NE(r.message.find("the motion diverged"), std::string::npos) << r.message;
  EXPECT_LT(r.simulated, 1000.0);
  EXPECT_GT(std::fabs(r.final_state.load_position), 1e8);
  const double a = p.gain * 0.01 / 2.0, radius = std::sqrt(1.0 + a / 2.0);
  const double phi = std::acos((2.0 - a / 2.0) / (2.0 * radius));
  const double growth = std::pow(radius, 2.0 * M_PI / phi);
  ASSERT_GE(r.maxima.size(), 30u);
  const std::size_t n = r.maxima.size();
  const double measured = std::pow((r.maxima[n - 1].position - 1.0) / (r.maxima[n - 21].position - 1.0), 1.0 / 20.0);
  EXPECT_NEAR(measured / growth, 1.0, 0.01) << measured << " vs " << growth;
  EXPECT_STREQ(toString(r.status.verdict), "diverged");
}
