// The compliant mesh inside the simulator (plant_compliant.cpp): the same joint through the Plant's interface and the
// drives, against independent truth — the reference maxima of the independent implementation, a Runge–Kutta
// integration of the linear two-mass drive written here (Δ = 0, where the mesh is linear), Modelica's
// Rotational.Examples.First eigenvalues, chunk-independence bit for bit, and a sampled P law tending to the
// continuous one at first order.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <vector>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/drive/drive.h"
#include "backlash_servo/simulation/simulator.h"
#include "backlash_servo/simulation/step_response.h"
#include "compliant/compliant_joint.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

using test_helpers::compliantD1;

struct Collect : EventSink
{
  std::vector<Event> events;
  void onEvent(const Event& e) override { events.push_back(e); }
  std::vector<Event> of(EventType t) const
  {
    std::vector<Event> out;
    for (const Event& e : events)
    {
      if (e.type == t)
      {
        out.push_back(e);
      }
    }
    return out;
  }
};

TEST(CompliantPlant, TheSimulatorRunsTheReferenceJointAndChunksCutNothing)
{
  const ServoParams p = compliantD1();
  State start;  // at rest at 0, touching the forward flank
  Simulator whole(p, start, 1.0);
  Collect a;
  whole.advanceTo(24.0, &a);
  // The reference maxima (independent implementation, DOP853 at rtol 1e-12).
  const std::vector<std::array<double, 2>> ref = {{3.436600908566362, 1.3399487298441173},
                                                  {11.164785917382483, 1.1069107911761091},
                                                  {21.095993869958512, 1.0712889517337925}};
  std::vector<Event> maxima;
  for (const Event& e : a.of(EventType::Maximum))
  {
    if (e.state.load_position > 1.0)
    {
      maxima.push_back(e);
    }
  }
  ASSERT_EQ(maxima.size(), ref.size());
  for (std::size_t i = 0; i < ref.size(); ++i)
  {
    EXPECT_NEAR(maxima[i].state.time, ref[i][0], 1e-6) << i;
    EXPECT_NEAR(maxima[i].state.load_position, ref[i][1], 1e-6) << i;
  }
  // Contact phases begin and end in pairs, on both flanks, with the mesh torque on the pressing side; the first is
  // the one in progress at the start (the law presses the touching teeth together), begun without an event.
  const auto engaged = a.of(EventType::Engagement), released = a.of(EventType::Separation);
  EXPECT_GE(engaged.size(), 10u);
  ASSERT_FALSE(released.empty());
  EXPECT_LT(released.front().state.time, engaged.front().state.time);
  EXPECT_LE(engaged.size() + 1 - released.size(), 1u);
  int backward = 0;
  for (const Event& e : engaged)
  {
    backward += e.state.contact == Contact::Backward;
    EXPECT_TRUE(e.state.contact != Contact::Apart);
  }
  EXPECT_GT(backward, 0);
  EXPECT_EQ(whole.contactPhases(), engaged.size() + 1);
  // The same run cut into 2400 uneven chunks: every bit the same.
  Simulator cut(p, start, 1.0);
  Collect b;
  for (int k = 1; k <= 2400; ++k)
  {
    cut.advanceTo(std::min(24.0, k * 0.01 + 0.003 * std::sin(k)), &b);
  }
  cut.advanceTo(24.0, &b);
  ASSERT_EQ(a.events.size(), b.events.size());
  for (std::size_t i = 0; i < a.events.size(); ++i)
  {
    EXPECT_EQ(a.events[i].state.time, b.events[i].state.time) << i;
    EXPECT_EQ(a.events[i].state.load_position, b.events[i].state.load_position) << i;
  }
  EXPECT_EQ(whole.state().load_position, cut.state().load_position);
  EXPECT_EQ(whole.state().motor_velocity, cut.state().motor_velocity);
  EXPECT_EQ(whole.energy().input, cut.energy().input);
  EXPECT_EQ(whole.energy().mesh_loss, cut.energy().mesh_loss);
}

// The energy ledger closes: the motor's and the load torque's work less the viscous, mesh and shaft losses equals the
// change of kinetic and stored energy computed from the state — to 1e-10 of the energy exchanged, for both mesh laws,
// a damped torsional shaft, an undamped mesh at Δ = 0, a load torque and a sampled PID loop, and a heavily damped
// contact.
TEST(CompliantPlant, TheEnergyLedgerCloses)
{
  struct Case
  {
    const char* name;
    ServoParams params;
    double rate;  // sampled PID [Hz], 0 = continuous P law
  };
  std::vector<Case> cases;
  cases.push_back({"spring_damper", compliantD1(), 0.0});
  ServoParams msl = compliantD1();
  msl.mesh_law = "msl_elastobacklash";
  cases.push_back({"msl_elastobacklash", msl, 0.0});
  ServoParams shaft = compliantD1();
  shaft.gear_inertia = 0.1;
  shaft.shaft_stiffness = 100.0;
  shaft.shaft_damping = 0.3;
  cases.push_back({"torsional shaft", shaft, 0.0});
  ServoParams zero = compliantD1();
  zero.backlash = 0.0;
  zero.mesh_damping = 0.0;
  cases.push_back({"undamped, no backlash", zero, 0.0});
  ServoParams loaded = compliantD1();
  loaded.load_torque = -0.4;
  cases.push_back({"load torque, sampled PID", loaded, 500.0});
  ServoParams damped = compliantD1();  // contact damping ratio 13: its fast decay's pieces lengthened once it is over
  damped.mesh_stiffness = 1000.0;
  damped.mesh_damping = 8000.0;
  cases.push_back({"heavily damped contact", damped, 0.0});
  for (const Case& k : cases)
  {
    Simulator sim(k.params, State(), 1.0);
    if (k.rate > 0.0)
    {
      DriveParams d;
      d.controller_rate = k.rate;
      d.control_law = "pid";
      d.integral_gain = 0.2;
      d.derivative_gain = 0.3;
      sim.setDrive(makePositionDrive(d, k.params.gain, k.params.gear_ratio, 1.0, 0.0));
    }
    sim.advanceTo(30.0);
    const EnergyLedger& e = sim.energy();
    ASSERT_TRUE(sim.energyValid()) << k.name;
    const double scale = e.input_magnitude + std::fabs(e.input) + std::fabs(e.load_work) + sim.kineticEnergy();
    EXPECT_GT(scale, 0.1) << k.name;
    EXPECT_LT(std::fabs(sim.energyBalanceError()), 1e-10 * scale) << k.name << ": " << sim.energyBalanceError();
    EXPECT_GT(e.motor_friction + e.load_friction, 0.1 * std::fabs(e.input)) << k.name;
    if (k.params.mesh_damping > 0.0)
    {
      EXPECT_GT(e.mesh_loss, 0.0) << k.name;
    }
    if (k.params.shaft_damping > 0.0)
    {
      EXPECT_GT(e.shaft_loss, 0.0) << k.name;
    }
  }
}

// With Δ = 0 and an undamped mesh the two flanks' torques are c·y and −c·y of one penetration y = ρθ_m − θ_c, so the
// mesh is the linear spring c(ρθ_m − θ_c) on both sides of zero: the joint is the linear two-mass drive (with a mesh
// damper it is not: a flank that would pull is released). Against classical RK4 on its four equations with a step of
// 1e-5 s (error ~1e-13), through several reversals of the mesh torque (each a switch of flank at y = 0).
TEST(CompliantPlant, WithoutBacklashItIsTheLinearTwoMassDrive)
{
  ServoParams p;
  p.backlash = 0.0;
  p.mesh_stiffness = 100.0;
  const double command = 1.0;
  Simulator sim(p, State(), command);
  Collect events;
  using X = std::array<double, 4>;  // θ_m, ω_m, θ_c, ω_c
  auto f = [&](const X& x) {
    const double q = p.mesh_stiffness * (p.gear_ratio * x[0] - x[2]) + p.mesh_damping * (p.gear_ratio * x[1] - x[3]);
    const double tm = p.gain * (command - x[2]);
    return X{x[1], (tm - p.motor_friction * x[1] - p.gear_ratio * q) / p.motor_inertia, x[3],
             (q - p.load_friction * x[3]) / p.load_inertia};
  };
  X x{0, 0, 0, 0};
  const double h = 1e-5;
  long step = 0;
  for (int check = 1; check <= 6; ++check)
  {
    const double t = check;
    for (; step * h < t - h / 2; ++step)
    {
      const X k1 = f(x);
      X y;
      for (int i = 0; i < 4; ++i)
        y[i] = x[i] + 0.5 * h * k1[i];
      const X k2 = f(y);
      for (int i = 0; i < 4; ++i)
        y[i] = x[i] + 0.5 * h * k2[i];
      const X k3 = f(y);
      for (int i = 0; i < 4; ++i)
        y[i] = x[i] + h * k3[i];
      const X k4 = f(y);
      for (int i = 0; i < 4; ++i)
        x[i] += h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    }
    sim.advanceTo(t, &events);
    const State s = sim.state();
    EXPECT_NEAR(s.motor_position, x[0], 1e-9) << t;
    EXPECT_NEAR(s.motor_velocity, x[1], 1e-9) << t;
    EXPECT_NEAR(s.load_position, x[2], 1e-9) << t;
    EXPECT_NEAR(s.load_velocity, x[3], 1e-9) << t;
  }
  // The mesh torque reversed on the way (the overshoot): both flanks were used.
  int backward = 0;
  for (const Event& e : events.of(EventType::Engagement))
  {
    backward += e.state.contact == Contact::Backward;
  }
  EXPECT_GT(backward, 0);
}

// Modelica.Mechanics.Rotational.Examples.First (MSL 4.0): motor inertia 0.1 kg·m² driven by a torque source, an ideal
// gear of ratio 10 to inertia2 (2 kg·m², with a bearing damper of 10 N·m·s/rad to the housing), a spring of 1e4 N·m/rad
// to the load inertia3 (2 kg·m²). In this package's terms the motor and inertia2 move as one body behind the ideal
// gear: motor_inertia 0.1 + ρ²·2 = 0.12, motor_friction ρ²·10 = 0.1, gear_ratio ρ = 1/10, the spring is the mesh
// (mesh_stiffness 1e4, mesh_damping 0, backlash 0), load_inertia 2, load_friction 0; the torque source is effort
// mode. Its published eigenvalues: 0, −0.714296126, −0.0595186 ± 76.3756818i [1/s].
TEST(CompliantPlant, ModelicaExamplesFirstHasItsEigenvalues)
{
  ServoParams p;
  p.motor_inertia = 0.12;
  p.motor_friction = 0.1;
  p.gear_ratio = 0.1;
  p.backlash = 0.0;
  p.mesh_stiffness = 1e4;
  p.load_inertia = 2.0;
  p.load_friction = 0.0;
  const CompliantJoint joint(p, MotorInput{10.0, 0.0});  // a torque presses the forward flank
  ASSERT_EQ(joint.mode(), MeshMode::Forward);
  std::vector<std::complex<double>> ev;
  for (int i = 0; i < 4; ++i)
  {
    ev.push_back(joint.eigenvalues()(i));
  }
  std::sort(ev.begin(), ev.end(),
            [](auto a, auto b) { return a.real() != b.real() ? a.real() > b.real() : a.imag() < b.imag(); });
  EXPECT_NEAR(std::abs(ev[0]), 0.0, 1e-9);
  EXPECT_NEAR(ev[1].real(), -0.0595186, 5e-8);
  EXPECT_NEAR(std::fabs(ev[1].imag()), 76.3756818, 5e-8);
  EXPECT_NEAR(ev[2].real(), -0.0595186, 5e-8);
  EXPECT_NEAR(ev[3].real(), -0.714296126, 5e-10);
  EXPECT_NEAR(ev[3].imag(), 0.0, 1e-12);
}

// A digital P drive samples θ_c and holds K(θ_R − θ_c): as its rate grows it tends to the continuous law on the
// compliant joint too, at first order (the hold's error is half a sample period of the loop's motion).
TEST(CompliantPlant, ASampledPLawTendsToTheContinuousOneAtFirstOrder)
{
  const ServoParams p = compliantD1();
  auto trajectory = [&](double rate) {
    Simulator sim(p, State(), 1.0);
    if (rate > 0.0)
    {
      DriveParams d;
      d.controller_rate = rate;
      sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, 1.0, 0.0));
    }
    std::vector<double> out;
    for (int i = 1; i <= 400; ++i)
    {
      sim.advanceTo(0.01 * i);
      out.push_back(sim.state().load_position);
    }
    return out;
  };
  const std::vector<double> exact = trajectory(0.0);
  double worst[2] = {0.0, 0.0};
  const double rates[2] = {1000.0, 4000.0};
  for (int r = 0; r < 2; ++r)
  {
    const std::vector<double> sampled = trajectory(rates[r]);
    for (std::size_t i = 0; i < exact.size(); ++i)
    {
      worst[r] = std::max(worst[r], std::fabs(sampled[i] - exact[i]));
    }
  }
  EXPECT_LT(worst[0], 5e-3);
  EXPECT_GT(worst[1], 0.15 * worst[0]);  // first order: a quarter of the error for four times the rate
  EXPECT_LT(worst[1], 0.4 * worst[0]);
}

// A robot joint (ρ = 0.01, a harmonic-drive-like mesh) under a 1 kHz motor-side cascade with a backlash inverse comes
// to rest on the backward flank with no force between the teeth; half a second later the motor reverses into that
// flank. The flank must take the load along: at every millisecond the mesh torque is what its law says of the state
// (written here: a flank with y > 0 transmits max(0, c·y + d·ẏ)), and at the end the load sits on the motor within
// the free play. (A contact begun within the rounding of a sample's start was once lost there: the motor turned back
// 20 rad while the load stayed, the gap 40 times the backlash.)
TEST(CompliantPlant, AFlankTouchingWithoutForceTakesTheLoadWhenPushed)
{
  ServoParams p = test_helpers::compliantRobotJoint();
  DriveParams d;
  d.controller_rate = 1000.0;
  d.control_law = "cascade";
  d.feedback = "motor";
  d.position_loop_gain = 10.0;
  d.velocity_loop_gain = 1.0;
  d.velocity_loop_integral_gain = 10.0;
  d.compensation = "inverse";
  d.compensation_backlash = 0.005;
  ProfileSegment out, back;
  out.kind = back.kind = ProfileSegment::Kind::Move;
  out.distance = 0.5;
  back.time = 5.0;
  back.distance = -0.2;
  out.max_velocity = back.max_velocity = 0.5;
  out.max_acceleration = back.max_acceleration = 2.0;
  auto profile = std::make_shared<const CommandProfile>(0.0, std::vector<ProfileSegment>{out, back});
  Simulator sim(p, State(), 0.0);
  sim.setDrive(makePositionDrive(d, p.gain, p.gear_ratio, 0.0, 0.0));
  sim.setProfile(profile);
  double worst = 0.0;
  for (int i = 1; i <= 10000; ++i)
  {
    sim.advanceTo(1e-3 * i);
    const State& s = sim.state();
    const double g = s.load_position - p.gear_ratio * s.motor_position;
    const double gd = s.load_velocity - p.gear_ratio * s.motor_velocity;
    double law = 0.0;
    if (g < 0.0)
    {
      law = std::max(0.0, p.mesh_stiffness * -g + p.mesh_damping * -gd);
    }
    else if (g > p.backlash)
    {
      law = -std::max(0.0, p.mesh_stiffness * (g - p.backlash) + p.mesh_damping * gd);
    }
    worst = std::max(worst, std::fabs(sim.meshTorque() - law));
  }
  EXPECT_LT(worst, 1e-6);  // [N·m]; the mesh carries up to ~1 N·m
  const State& s = sim.state();
  const double g = s.load_position - p.gear_ratio * s.motor_position;
  EXPECT_GT(g, -1e-6);
  EXPECT_LT(g, p.backlash + 1e-6);
  EXPECT_NEAR(s.load_position, 0.3, 0.01);
}

// The compliant keys are validated together, and a run cannot switch between rigid teeth and a compliant mesh.
TEST(CompliantPlant, KeysAreValidatedTogether)
{
  auto refused = [](const ServoParams& p, const std::string& key) {
    try
    {
      p.validate();
    }
    catch (const InvalidParameterError& e)
    {
      return e.field() == key;
    }
    return false;
  };
  ServoParams p;
  p.mesh_damping = 1.0;
  EXPECT_TRUE(refused(p, "mesh_damping"));
  p = compliantD1();
  p.shaft_stiffness = 100.0;
  EXPECT_TRUE(refused(p, "shaft_stiffness"));  // needs gear_inertia
  p.gear_inertia = 0.1;
  EXPECT_NO_THROW(p.validate());
  p.shaft_damping = 1.0;
  p.shaft_stiffness = 0.0;
  EXPECT_TRUE(refused(p, "shaft_damping"));
  p = compliantD1();
  p.mesh_law = "hertz";
  EXPECT_TRUE(refused(p, "mesh_law"));
  p = compliantD1();
  p.mesh_stiffness = -1.0;
  EXPECT_TRUE(refused(p, "mesh_stiffness"));

  Simulator sim(compliantD1(), State(), 1.0);
  sim.advanceTo(1.0);
  const State before = sim.state();
  EXPECT_THROW(sim.setParams(ServoParams()), InvalidParameterError);  // rigid teeth mid-run
  EXPECT_EQ(sim.state().load_position, before.load_position);
  ServoParams stiffer = compliantD1();
  stiffer.mesh_stiffness = 2e4;
  EXPECT_NO_THROW(sim.setParams(stiffer));
  EXPECT_EQ(sim.state().load_position, before.load_position);
  EXPECT_EQ(sim.params().mesh_stiffness, 2e4);
}

// A load coasting in the free play towards a flank it never quite reaches (1e-14 rad short, its speed decaying as
// e^{-t f_L/J_L} to 1e-33 rad/s) while the motor, held by a cascade, drifts at 1e-13 rad/s: the search for the load's
// turning point once halved every sample down to windows of |v|/(the rate's rounding) — a cost growing as e^t, 60 s
// taking minutes. The coasting is the closed form: between two samples 10 s apart its speed falls by exactly e^{-10}.
// (Guarded in wall time, generously: 60 simulated seconds take about 0.1 s.)
TEST(CompliantPlant, ALoadCoastingTowardsAFlankItNeverReachesIsNotSearchedToTheFloor)
{
  RunConfig c;
  c.params = test_helpers::compliantRobotJoint();
  c.drive.controller_rate = 1000.0;
  c.drive.control_law = "cascade";
  c.drive.feedback = "motor";
  c.drive.position_loop_gain = 10.0;
  c.drive.velocity_loop_gain = 1.0;
  c.drive.velocity_loop_integral_gain = 10.0;
  c.drive.compensation = "inverse";
  c.drive.compensation_backlash = c.params.backlash;
  c.command = 0.3;
  c.duration = 60.0;
  Simulator sim = makeSimulator(c);
  const auto start = std::chrono::steady_clock::now();
  sim.advanceTo(50.0);
  const State at50 = sim.state();
  sim.advanceTo(60.0);
  const State at60 = sim.state();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(at50.contact, Contact::Apart);
  ASSERT_EQ(at60.contact, Contact::Apart);
  ASSERT_GT(at50.load_velocity, 0.0);
  EXPECT_NEAR(at60.load_velocity / at50.load_velocity, std::exp(-10.0 * c.params.load_friction / c.params.load_inertia),
              1e-9);
  EXPECT_LT(wall, 10.0);
}
}  // namespace
