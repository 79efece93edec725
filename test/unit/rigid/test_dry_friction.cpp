// Dry friction and stiction (docs/model.md Part 2) against closed forms written here, and the energy ledger.
#include <gtest/gtest.h>

#include "test_helpers.h"

#include <cmath>
#include <random>
#include <string>

#include "backlash_servo/drive/drive.h"
#include "backlash_servo/simulation/simulator.h"

using namespace backlash_servo;

namespace
{
constexpr double PI = 3.14159265358979323846;

ServoParams undamped()
{
  ServoParams p;
  p.motor_inertia = 0.1;
  p.load_inertia = 0.9;
  p.motor_friction = 0.0;
  p.load_friction = 0.0;
  p.gain = 1.0;
  p.gear_ratio = 1.0;
  p.backlash = 0.0;
  p.restitution = 0.0;
  return p;
}
}  // namespace

// Rigid mesh, Coulomb friction only, continuous P law: J θ̈ = ρK(θ_R − θ) − C sign θ̇ with C = ρT_cm + ρ²T_cL.
// Each half cycle lasts π/ω exactly and the error |θ − θ_R| falls by 2C/(ρK); the motion stops at the first turning
// point whose spring torque ρK|x| is within the static capacity S = ρT_sm + ρ²T_sL, and stays there for ever.
TEST(DryFriction, CoulombOscillationLosesAFixedDecrementAndSticksInsideTheStaticBand)
{
  ServoParams p = undamped();
  p.motor_coulomb_friction = 0.01;
  p.motor_static_friction = 0.015;
  p.load_coulomb_friction = 0.02;
  p.load_static_friction = 0.03;
  const double rho_k = p.gear_ratio * p.gain;
  const double decrement = 2.0 * (p.motor_coulomb_friction + p.load_coulomb_friction) / rho_k;  // 0.06 rad
  const double band = (p.motor_static_friction + p.load_static_friction) / rho_k;               // 0.045 rad
  const double omega = std::sqrt(rho_k / p.totalInertia());
  Simulator sim(p, State(), 1.0);
  test_helpers::Recorder rec;
  sim.advanceTo(100.0, &rec);
  const std::vector<Event> rests = rec.of(EventType::Rest);
  int expected = 0;
  for (double x = 1.0; x > band; x -= decrement)
  {
    ++expected;
  }
  ASSERT_EQ(static_cast<int>(rests.size()), expected);  // 16 turning points, the last one sticks
  for (int n = 1; n <= expected; ++n)
  {
    const double error = (n % 2 == 1 ? 1.0 : -1.0) * (1.0 - decrement * n);
    EXPECT_NEAR(rests[n - 1].state.time, n * PI / omega, 1e-9) << "rest " << n;
    EXPECT_NEAR(rests[n - 1].state.load_position, 1.0 + error, 1e-9) << "rest " << n;
  }
  const double last = 1.0 - (1.0 - decrement * expected);
  EXPECT_EQ(sim.state().load_velocity, 0.0);
  EXPECT_EQ(sim.state().load_position, rests.back().state.load_position);  // stuck: not a bit moved since
  EXPECT_NEAR(sim.state().load_position, last, 1e-9);
  // Input work = dry-friction losses (no viscous, no impacts, at rest at both ends).
  const EnergyLedger& e = sim.energy();
  EXPECT_NEAR(e.input, e.motor_dry_friction + e.load_dry_friction, 1e-12);
  EXPECT_GT(e.motor_dry_friction, 0.0);
  EXPECT_NEAR(e.motor_dry_friction / e.load_dry_friction, 0.5, 1e-12);  // same path, T_cm / T_cL
}

// A constant motor torque against stiction: the meshed pair stays exactly where it is while ρu ≤ S (even though
// the motor alone would break away), and above it slides with the closed form of
// J θ̈ + F_T θ̇ = ρ(u − T_cm) − ρ²T_cL.
TEST(DryFriction, PairBreaksAwayExactlyAtItsStaticCapacity)
{
  ServoParams p;
  p.gear_ratio = 0.5;
  p.backlash = 0.05;
  p.restitution = 0.5;
  p.motor_coulomb_friction = 0.1;
  p.motor_static_friction = 0.15;
  p.load_coulomb_friction = 0.2;
  p.load_static_friction = 0.3;
  const double rho = p.gear_ratio;
  const double capacity = rho * p.motor_static_friction + rho * rho * p.load_static_friction;  // 0.15 N·m
  State start;
  start.load_position = 0.2;
  start.motor_position = 0.4;  // forward contact, g = 0
  {
    Simulator sim(p, start, 0.0);
    sim.setMotorTorque(0.999 * capacity / rho);  // > T_sm: the motor alone would go
    sim.advanceTo(20.0);
    EXPECT_EQ(sim.state().load_position, start.load_position);
    EXPECT_EQ(sim.state().motor_position, start.motor_position);
    EXPECT_EQ(sim.state().load_velocity, 0.0);
  }
  const double u = 0.4;
  Simulator sim(p, start, 0.0);
  sim.setMotorTorque(u);
  const double a = rho * (u - p.motor_coulomb_friction) - rho * rho * p.load_coulomb_friction;
  const double f = p.totalFriction();
  const double rate = f / p.totalInertia();
  for (double t : {0.1, 1.0, 3.0, 10.0})
  {
    sim.advanceTo(t);
    const double x = start.load_position + a / f * (t - (1.0 - std::exp(-rate * t)) / rate);
    const double v = a / f * (1.0 - std::exp(-rate * t));
    EXPECT_NEAR(sim.state().load_position, x, 1e-12 * std::max(1.0, std::fabs(x))) << t;
    EXPECT_NEAR(sim.state().load_velocity, v, 1e-12) << t;
    EXPECT_EQ(sim.state().contact, Contact::Forward);
  }
  EXPECT_NEAR(sim.energyBalanceError(), 0.0, 1e-12 * sim.energy().input);
}

// A load held by its static friction against a load torque stays exactly put while the motor floats in the gap;
// once the motor tooth hits it, it leaves with the impact velocity and slides (no friction impulse).
TEST(DryFriction, StuckLoadStaysUntilTheMotorToothHitsIt)
{
  ServoParams p;
  p.backlash = 0.3;
  p.restitution = 0.5;
  p.load_torque = -0.2;
  p.load_coulomb_friction = 0.2;
  p.load_static_friction = 0.25;
  State start;
  start.contact = Contact::Apart;
  start.load_position = 0.0;
  start.motor_position = -0.15;  // gap 0.15 rad
  Simulator sim(p, start, 0.0);
  sim.setMotorTorque(0.3);
  test_helpers::Recorder rec;
  sim.advanceTo(0.2, &rec);  // the motor is still crossing the gap
  EXPECT_TRUE(rec.of(EventType::Impact).empty());
  EXPECT_EQ(sim.state().load_position, 0.0);
  EXPECT_EQ(sim.state().load_velocity, 0.0);
  sim.advanceTo(5.0, &rec);
  const std::vector<Event> impacts = rec.of(EventType::Impact);
  ASSERT_FALSE(impacts.empty());
  // Before the first impact the load never moved; the motor obeyed J_m ω̇ = u − f_m ω from rest.
  const Event& hit = impacts.front();
  EXPECT_EQ(hit.impact.load_velocity_before, 0.0);
  const double rate = p.motor_friction / p.motor_inertia;
  const double t = hit.state.time;
  const double travel = 0.3 / p.motor_friction * (t - (1.0 - std::exp(-rate * t)) / rate);
  EXPECT_NEAR(travel, 0.15, 1e-12);  // the gap it had to close
  EXPECT_GT(hit.impact.load_velocity_after, 0.0);
  EXPECT_NEAR(sim.energyBalanceError(), 0.0, 1e-12 * sim.energy().input_magnitude);
}

// The ledger closes with dry friction over random joints, continuous and sampled laws, stick-slip included.
TEST(DryFriction, EnergyBalanceClosesOnRandomJoints)
{
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto logu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u01(rng)); };
  int sticks = 0;
  for (int i = 0; i < 150; ++i)
  {
    ServoParams p;
    p.motor_inertia = logu(0.01, 1.0);
    p.load_inertia = logu(0.01, 1.0);
    p.motor_friction = u01(rng) < 0.2 ? 0.0 : logu(0.01, 1.0);
    p.load_friction = u01(rng) < 0.2 ? 0.0 : logu(0.01, 1.0);
    p.gain = logu(0.3, 3.0);
    p.gear_ratio = logu(0.5, 2.0);
    p.backlash = u01(rng) < 0.1 ? 0.0 : logu(0.01, 0.3);
    p.restitution = std::vector<double>{0.0, 0.5, 0.8}[i % 3];
    p.load_torque = u01(rng) < 0.5 ? 0.0 : 0.2 * (u01(rng) - 0.5);
    p.motor_coulomb_friction = 0.05 * u01(rng);
    p.motor_static_friction = p.motor_coulomb_friction * (1.0 + u01(rng));
    p.load_coulomb_friction = 0.05 * u01(rng);
    p.load_static_friction = p.load_coulomb_friction * (1.0 + u01(rng));
    try
    {
      p.validate();
    }
    catch (const InvalidParameterError&)
    {
      continue;  // outside the validated envelope
    }
    Simulator sim(p, State(), 1.0);
    DriveParams d;
    if (i % 2 == 1)
    {
      d.controller_rate = 200.0;
      d.control_law = "pid";
      d.integral_gain = 0.2 * p.gain;
      d.derivative_gain = 0.1 * p.gain;
    }
    sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, 1.0, 0.0));
    sim.setEventBudget(2000000);
    test_helpers::Recorder rec;
    sim.advanceTo(40.0, &rec);
    sticks += static_cast<int>(rec.of(EventType::Rest).size());
    const EnergyLedger& e = sim.energy();
    const double scale = e.input_magnitude + e.motor_dry_friction + e.load_dry_friction + std::fabs(e.load_work) +
                         e.motor_friction + e.load_friction + e.impact_loss + 1e-12;
    EXPECT_LE(std::fabs(sim.energyBalanceError()), 1e-9 * scale) << "case " << i;
    EXPECT_GE(e.motor_dry_friction, -1e-12 * scale) << "case " << i;
    EXPECT_GE(e.load_dry_friction, -1e-12 * scale) << "case " << i;
    const double g = sim.gap();
    EXPECT_GE(g, -1e-9) << "case " << i;
    EXPECT_LE(g, p.backlash + 1e-9) << "case " << i;
  }
  EXPECT_GT(sticks, 100);  // the sample really exercised rests and breakaways
}

// The digital drive's fast path through stick phases (samples taken in blocks while the rest rule keeps holding the
// joint) is exactly the sample-by-sample path: a sample observer forces the latter. Random dry joints, every law,
// delay, encoders, torque limits, preloads and compensators; events, final state, ledger and the event budget equal
// to the bit.
TEST(DryFriction, StickPhasesInBlocksAreTheSampleBySamplePathBitForBit)
{
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto logu = [&](double lo, double hi) { return lo * std::pow(hi / lo, u01(rng)); };
  std::uint64_t blocked = 0, samples = 0;
  int budget_cases = 0;
  for (int i = 0; i < 120; ++i)
  {
    ServoParams p;
    p.motor_inertia = logu(1e-4, 1.0);
    p.load_inertia = logu(0.01, 1.0);
    p.motor_friction = u01(rng) < 0.2 ? 0.0 : logu(1e-4, 1.0);
    p.load_friction = u01(rng) < 0.2 ? 0.0 : logu(0.01, 1.0);
    p.gear_ratio = u01(rng) < 0.3 ? 0.01 : logu(0.5, 2.0);
    p.gain = logu(0.3, 3.0) / p.gear_ratio;
    p.backlash = u01(rng) < 0.15 ? 0.0 : logu(0.001, 0.3);
    p.restitution = std::vector<double>{0.0, 0.5, 0.8}[i % 3];
    p.load_torque = u01(rng) < 0.5 ? 0.0 : 0.4 * (u01(rng) - 0.5);
    p.motor_coulomb_friction = 0.05 * u01(rng) * (u01(rng) < 0.2 ? 0.0 : 1.0);
    p.motor_static_friction = p.motor_coulomb_friction * (1.0 + u01(rng));
    p.load_coulomb_friction = 0.3 * u01(rng);
    p.load_static_friction = p.load_coulomb_friction * (1.0 + u01(rng));
    DriveParams d;
    d.controller_rate = std::vector<double>{100.0, 1000.0}[i % 2];
    d.control_law = std::vector<std::string>{"proportional", "pid", "cascade"}[i % 3];
    d.integral_gain = 0.5 * p.gain;
    d.derivative_gain = 0.05 * p.gain;
    d.position_loop_gain = logu(2.0, 20.0);
    d.velocity_loop_gain = logu(0.05, 0.5) * p.gain;
    d.velocity_loop_integral_gain = 0.5 * d.velocity_loop_gain;
    d.controller_delay = u01(rng) < 0.3 ? 1.0 : 0.0;
    d.load_encoder_resolution = u01(rng) < 0.3 ? 4096.0 : 0.0;
    d.motor_encoder_resolution = u01(rng) < 0.3 ? 1024.0 : 0.0;
    d.torque_limit = u01(rng) < 0.3 ? 0.5 * p.gain * 0.3 : 0.0;
    const double c = u01(rng);
    d.compensation = c < 0.15 ? "dither" : c < 0.3 ? "friction_feedforward" : "none";
    d.dither_amplitude = 0.02;
    d.dither_frequency = 37.0;
    d.compensation_friction = p.load_coulomb_friction * p.gear_ratio;
    try
    {
      p.validate();
      d.validate();
    }
    catch (const InvalidParameterError&)
    {
      continue;  // outside the validated envelope
    }
    const std::uint64_t budget = i % 10 == 0 ? 600 : 0;  // one case in ten runs out of samples midway
    struct Outcome
    {
      test_helpers::Recorder rec;
      State state;
      double balance = 0.0;
      std::string error;
      std::uint64_t blocked = 0;
    };
    auto run = [&](bool observe) {
      Outcome o;
      Simulator sim(p, State(), 0.3);
      sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, 0.3, 0.0));
      sim.setEventBudget(budget);
      if (observe)
      {
        sim.setSampleObserver([](const State&, const Drive&) {});
      }
      try
      {
        for (double t = 2.5; t <= 10.0; t += 2.5)
        {
          sim.advanceTo(t, &o.rec);
        }
      }
      catch (const EventBudgetExceeded& e)
      {
        o.error = e.what();
      }
      catch (const MotionDiverged& e)
      {
        o.error = e.what();  // an unstable draw: both paths must run away identically
      }
      o.state = sim.state();
      o.balance = sim.energyBalanceError();
      o.blocked = sim.heldSamples();
      return o;
    };
    const Outcome fast = run(false), slow = run(true);
    EXPECT_EQ(slow.blocked, 0u);
    blocked += fast.blocked;
    samples += static_cast<std::uint64_t>(10.0 * d.controller_rate);
    budget_cases += fast.error.find("event budget") != std::string::npos;
    EXPECT_EQ(fast.error, slow.error) << "case " << i;
    ASSERT_EQ(fast.rec.events.size(), slow.rec.events.size()) << "case " << i;
    for (std::size_t k = 0; k < fast.rec.events.size(); ++k)
    {
      const Event &a = fast.rec.events[k], &b = slow.rec.events[k];
      ASSERT_EQ(a.type, b.type) << "case " << i << " event " << k;
      ASSERT_EQ(a.state.time, b.state.time) << "case " << i << " event " << k;
      ASSERT_EQ(a.state.load_position, b.state.load_position) << "case " << i << " event " << k;
      ASSERT_EQ(a.state.motor_velocity, b.state.motor_velocity) << "case " << i << " event " << k;
    }
    EXPECT_EQ(fast.state.time, slow.state.time) << "case " << i;
    EXPECT_EQ(fast.state.load_position, slow.state.load_position) << "case " << i;
    EXPECT_EQ(fast.state.motor_position, slow.state.motor_position) << "case " << i;
    EXPECT_EQ(fast.state.load_velocity, slow.state.load_velocity) << "case " << i;
    EXPECT_EQ(fast.state.contact, slow.state.contact) << "case " << i;
    EXPECT_TRUE(fast.balance == slow.balance || (std::isnan(fast.balance) && std::isnan(slow.balance))) << "case " << i;
  }
  // The comparison means something: a good share of all samples went through blocks, and budgets ran out.
  EXPECT_GT(blocked, samples / 5) << blocked << " of " << samples;
  EXPECT_GE(budget_cases, 8);
  std::printf("%llu of %llu samples in blocks\n", static_cast<unsigned long long>(blocked),
              static_cast<unsigned long long>(samples));
}

// All dry friction 0: the same trajectory to the last bit as without the keys (the dry code path is not taken).
TEST(DryFriction, ZeroFrictionIsTheThesisServoBitForBit)
{
  ServoParams plain;
  ServoParams zero = plain;
  zero.motor_coulomb_friction = 0.0;
  zero.load_static_friction = 0.0;
  Simulator a(plain, State(), 1.0), b(zero, State(), 1.0);
  a.advanceTo(60.0);
  b.advanceTo(60.0);
  EXPECT_EQ(a.state().load_position, b.state().load_position);
  EXPECT_EQ(a.state().motor_velocity, b.state().motor_velocity);
}
