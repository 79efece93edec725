// External load torque T_ext (docs/model.md Part 2): checked against closed forms written here, the
// reference case of test/joint_cases/reference_cases.json, conservation of energy, and T_ext = 0 reproducing the servo.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "backlash_servo/plant/plant.h"
#include "backlash_servo/rigid/modes.h"
#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;

TEST(LoadTorque, RigidMeshFollowsTheClosedFormStepWithAShiftedEquilibrium)
{
  // Δ = 0: J θ'' + F θ' + ρK θ = ρK θ_R + ρ² T_ext, an underdamped step towards θ_eq = θ_R + ρ T_ext / K.
  ServoParams p;
  p.backlash = 0.0;
  p.gear_ratio = 2.0;
  p.load_torque = -0.15;
  Simulator sim(p, State(), 1.0);
  const double j = p.totalInertia(), f = p.totalFriction(), k = p.gear_ratio * p.gain;
  const double eq = 1.0 + p.gear_ratio * p.load_torque / p.gain;
  const double sigma = f / (2 * j), omega = std::sqrt(k / j - sigma * sigma);
  for (double t : {0.5, 2.0, 7.3, 20.0})
  {
    sim.advanceTo(t);
    const double y0 = -eq;  // θ(0) = 0
    const double x = eq + std::exp(-sigma * t) * (y0 * std::cos(omega * t) + sigma * y0 / omega * std::sin(omega * t));
    EXPECT_NEAR(sim.state().load_position, x, 1e-12) << t;
  }
  EXPECT_NEAR(eq, 1.0 - 0.3, 1e-15);
}

TEST(LoadTorque, ReferenceCasePreloadLargeD1)
{
  // joint_cases_public.json "preload_large_D1": D1 with e = 0.8 and T_ext = −0.3 N·m: the teeth never leave the
  // forward flank, no maxima, converged with steady error ρ T_ext / K = −0.3 rad.
  RunConfig c;
  c.params.restitution = 0.8;
  c.params.load_torque = -0.3;
  c.duration = 300.0;
  struct Flanks : EventSink
  {
    int left = 0;
    void onEvent(const Event& e) override { left += e.type == EventType::Separation || e.type == EventType::Impact; }
  } flanks;
  const RunSummary r = runResponse(c, &flanks);
  EXPECT_EQ(flanks.left, 0);
  EXPECT_TRUE(r.maxima.empty());
  EXPECT_EQ(r.status.verdict, Verdict::Converged);
  EXPECT_NEAR(r.final_state.load_position - 1.0, -0.30000000000000004, 1e-9);
}

TEST(LoadTorque, SeparationsHappenWhereTheMeshTorqueVanishes)
{
  // A load torque large enough to pull the teeth apart against the P law: at every separation the contact mesh
  // torque Q = J_L θc'' + f_L θc' − T_ext evaluated from the state is zero (to rounding).
  for (double text : {0.4, -0.05, 0.9})
  {
    ServoParams p;
    p.load_torque = text;
    p.restitution = 0.7;
    struct Seps : EventSink
    {
      ServoParams p;
      MotorInput law;
      int n = 0;
      double worst = 0.0;
      void onEvent(const Event& e) override
      {
        if (e.type == EventType::Separation && p.backlash > 0.0)
        {
          ++n;
          worst = std::max(worst, std::fabs(contactMeshTorque(p, e.law, e.state.load_position, e.state.load_velocity)));
        }
      }
    } seps;
    seps.p = p;
    Simulator sim(p, State(), 1.0);
    sim.advanceTo(60.0, &seps);
    EXPECT_GT(seps.n, 0) << text;
    EXPECT_LE(seps.worst, 1e-12) << text;
    const double scale = sim.energy().input + std::fabs(sim.energy().load_work) + sim.energy().initial_kinetic;
    EXPECT_LE(std::fabs(sim.energyBalanceError()), 1e-12 * scale) << text;
    EXPECT_NE(sim.energy().load_work, 0.0);
  }
}

TEST(LoadTorque, FloatingLoadFallsUnderItsTorqueExactly)
{
  // Apart, the load alone: J_L ω' + f_L ω = T_ext ⇒ ω = v∞ + (v0 − v∞) e^{−αt}, v∞ = T_ext / f_L; also slow α.
  for (double fl : {0.32, 3e-6, 0.0})
  {
    ServoParams p;
    p.load_friction = fl;
    p.load_torque = 0.05;
    p.backlash = 1000.0;  // the motor never reaches it
    p.gain = 1e-3;
    State s;
    s.contact = Contact::Apart;
    s.load_position = 500.0;
    s.load_velocity = 0.2;
    s.motor_position = 0.0;
    Simulator sim(p, s, 0.0);
    sim.setMotorTorque(0.0);
    sim.advanceTo(5.0);
    const double alpha = fl / p.load_inertia, t = 5.0;
    const double v = fl > 0.0 ? p.load_torque / fl + (0.2 - p.load_torque / fl) * std::exp(-alpha * t)
                              : 0.2 + p.load_torque / p.load_inertia * t;
    // Position: integral of the above, written with expm1 so that the slow case does not cancel.
    const double x = fl > 0.0
                         ? 500.0 + p.load_torque / fl * t - (0.2 - p.load_torque / fl) * std::expm1(-alpha * t) / alpha
                         : 500.0 + 0.2 * t + 0.5 * p.load_torque / p.load_inertia * t * t;
    EXPECT_NEAR(sim.state().load_velocity, v, 1e-12) << fl;
    EXPECT_NEAR(sim.state().load_position, x, fl == 3e-6 ? 1e-8 : 1e-12) << fl;
    // (the reference is itself a difference of positions near 500 rad: its rounding is ~1e-14 J)
    EXPECT_NEAR(sim.energy().load_work, p.load_torque * (sim.state().load_position - 500.0), 1e-13);
  }
}

TEST(LoadTorque, ALoadTurnedRoundInFlightIsAMaximum)
{
  // Apart, a load thrown up against a load torque T < 0 turns round in the air: ω = v∞ + (v0 − v∞) e^{−ατ},
  // v∞ = T/f_L, crosses zero at τ* = ln(1 − v0/v∞)/α, where θ_c = θ0 + v∞τ* + v0/α (without friction: τ* = v0 J_L/(−T),
  // θ_c = θ0 + v0² J_L/(2(−T))). That is a maximum of θ_c (docs/model.md: ω_c from + to −) and must be reported — from
  // a long flight in mid-gap (the closed form) and from a short one leaving the wall (the fast path), before the load
  // falls back onto the motor tooth.
  for (double fl : {0.32, 0.0})
  {
    for (bool short_flight : {false, true})
    {
      ServoParams p;
      p.load_friction = fl;
      p.load_torque = -1.0;
      p.restitution = 0.5;
      p.backlash = 2.0;
      const double v0 = short_flight ? 1e-3 : 0.5;
      State s;
      s.contact = Contact::Apart;
      s.load_position = short_flight ? 0.0 : 1.0;  // on the forward wall (g = 0), or mid-gap
      s.load_velocity = v0;
      s.motor_position = 0.0;
      MotorInput law;  // no motor torque
      Plant plant(p, s, law);
      test_helpers::Recorder rec;
      plant.advanceTo(short_flight ? 0.01 : 1.0, &rec);
      const std::vector<Event> maxima = rec.of(EventType::Maximum);
      ASSERT_EQ(maxima.size(), 1u) << "fl " << fl << (short_flight ? " short" : " long");
      const double jl = p.load_inertia;
      double tau, top;
      if (fl > 0.0)
      {
        const double alpha = fl / jl, v_inf = p.load_torque / fl;
        tau = std::log1p(-v0 / v_inf) / alpha;
        top = s.load_position + v_inf * tau + v0 / alpha;
      }
      else
      {
        tau = v0 * jl / -p.load_torque;
        top = s.load_position + v0 * v0 * jl / (2.0 * -p.load_torque);
      }
      EXPECT_NEAR(maxima[0].state.time, tau, 1e-12 * tau + 1e-15);
      EXPECT_NEAR(maxima[0].state.load_position, top, 1e-13);
      EXPECT_NEAR(maxima[0].state.load_velocity, 0.0, 1e-12 * v0);
      if (short_flight)
      {
        EXPECT_GT(plant.shortFlightCount(), 0u);
      }
    }
  }
}

}  // namespace

namespace
{
TEST(LoadTorque, LevelCrossingSeparationMatchesABruteForceScan)
{
  // The separation of an oscillatory contact with a load torque is where L + e^{−στ}(C cos ωτ + D sin ωτ) first
  // crosses zero: compared with a fine scan of the mesh torque, for many starting phases (a missed first monotone
  // piece makes the rigid mesh flip flanks for ever).
  ServoParams p;
  p.load_torque = 0.35;
  p.backlash = 0.2;
  const MotorInput law{p.gain * 1.0, p.gain};
  for (int i = 0; i < 40; ++i)
  {
    const double x0 = -0.5 + 0.05 * i;
    const double v0 = std::sin(1.7 * i);
    const ContactMotion m(p, law, x0, v0);
    for (double side : {1.0, -1.0})
    {
      if (side * m.meshTorque(0.0) <= 0.0)
      {
        continue;  // that flank does not hold here
      }
      const double horizon = 12.0;
      const int n = 200000;
      double scan = INFINITY;
      for (int k = 1; k <= n; ++k)
      {
        if (side * m.meshTorque(horizon * k / n) < 0.0)
        {
          scan = horizon * k / n;
          break;
        }
      }
      const double t = m.separationTime(side, horizon);
      if (std::isinf(scan))
      {
        EXPECT_TRUE(std::isinf(t)) << i << " " << side << " " << t;
      }
      else
      {
        EXPECT_NEAR(t, scan, horizon / n) << i << " " << side;
      }
    }
  }
}
}  // namespace

// A load torque balancing the motor's exactly at the start: the mesh torque and the velocity have no oscillating
// part (constant level), the joint stays where it is. The search for the first critical point of a sinusoid with
// zero amplitude must not loop for ever (`backlash_sim --load-torque -1`).
TEST(LoadTorque, ABalancedStartStaysAtRestWithoutHanging)
{
  ServoParams p;         // App. D1: K = 1 N·m/rad, unit step from 0 → motor torque 1 N·m
  p.load_torque = -1.0;  // holds the load against it through the forward flank
  Simulator sim(p, State(), 1.0);
  sim.advanceTo(20.0);
  EXPECT_EQ(sim.state().load_position, 0.0);
  EXPECT_EQ(sim.state().load_velocity, 0.0);
  EXPECT_EQ(sim.impactCount(), 0u);
}

// Regression: a lightly damped load drifting apart under T_ext towards
// u = T_ext/f_L = 0.012 rad/s with α = 0.28 1/s while it moves at ~1e-4 rad/s. The apart closed form's terms
// (θ_c ~ (v0 − u)/α ~ 0.04 rad, ω_m ~ k/J_m times those ~ 0.6 rad/s) are 1e4–1e5× the motion, and the energy flows
// integrated from their products cancelled ~9 digits (the run's balance off by 2e-8 of its energy scale). Truth:
// the apart-mode ODE with the flows as extra states, integrated by classical RK4 in long double (its right-hand side
// has no large terms), and the load's flows in closed form in long double (ω_c = u + (v0 − u) e^{−ατ}, expm1).
// Both apart forms (compact and wide), short and long flights.
struct ApartFlows
{
  long double input = 0, motor_friction = 0, load_friction = 0;
};

ApartFlows rk4Flows(const ServoParams& p, const MotorInput& law, const State& s, double tau, int steps)
{
  using L = long double;
  // y = (θ_c, ω_c, θ_m, ω_m, ∫T_m ω_m, ∫ω_m², ∫ω_c²)
  L y[7] = {s.load_position, s.load_velocity, s.motor_position, s.motor_velocity, 0, 0, 0};
  auto f = [&](const L* x, L* d) {
    const L torque = static_cast<L>(law.offset) - static_cast<L>(law.stiffness) * x[0];
    d[0] = x[1];
    d[1] = (static_cast<L>(p.load_torque) - static_cast<L>(p.load_friction) * x[1]) / p.load_inertia;
    d[2] = x[3];
    d[3] = (torque - static_cast<L>(p.motor_friction) * x[3]) / p.motor_inertia;
    d[4] = torque * x[3];
    d[5] = x[3] * x[3];
    d[6] = x[1] * x[1];
  };
  test_helpers::rk4(f, y, static_cast<L>(tau) / steps, steps);
  return {y[4], p.motor_friction * y[5], p.load_friction * y[6]};
}

template <class Motion>
void expectExactFlows(const ServoParams& p, const MotorInput& law, const State& s, double tau, const ApartFlows& ref)
{
  const Motion m(p, law, s, tau);
  const EnergyFlows e = m.energy(tau);
  const double input = static_cast<double>(ref.input), motor = static_cast<double>(ref.motor_friction);
  const double load = static_cast<double>(ref.load_friction);
  EXPECT_NEAR(e.input, input, 1e-12 * std::fabs(input)) << tau;
  EXPECT_NEAR(e.motor_friction, motor, 1e-12 * motor) << tau;
  EXPECT_NEAR(e.load_friction, load, 1e-12 * load) << tau;
  // The load alone, in closed form (long double).
  using L = long double;
  const L alpha = static_cast<L>(p.load_friction) / p.load_inertia;
  const L u = static_cast<L>(p.load_torque) / p.load_friction, w = s.load_velocity - u;
  const L em1 = std::expm1(-alpha * tau), em2 = std::expm1(-2 * alpha * tau);
  const double displacement = static_cast<double>(u * tau - w * em1 / alpha);
  const double friction =
      static_cast<double>(p.load_friction * (u * u * tau - 2 * u * w * em1 / alpha - w * w * em2 / (2 * alpha)));
  EXPECT_NEAR(e.load_displacement, displacement, 1e-14 * std::fabs(displacement)) << tau;
  EXPECT_NEAR(load, friction, 1e-13 * friction) << tau;  // the reference itself
}

TEST(LoadTorque, ALightlyDampedDriftKeepsItsEnergyFlowsExact)
{
  ServoParams p;
  p.motor_inertia = 0.0035079845442365682;
  p.load_inertia = 9.878924459762661e-05;
  p.motor_friction = 0.00027603721286588033;
  p.load_friction = 2.7609253606252575e-05;
  p.gain = 0.010018095558593799;
  p.backlash = 5.6715467154069532e-05;
  p.load_torque = 3.3808121719035958e-07;
  const double command = 0.00034696651579279003;
  const MotorInput law{p.gain * command, p.gain};
  State s;
  s.contact = Contact::Apart;
  s.load_position = 3.5e-4;
  s.load_velocity = 1e-4;
  s.motor_position = 3.5e-4 - 2e-5;
  s.motor_velocity = -2e-7;
  int compact = 0;
  for (double tau : {0.01, 0.1, 1.0, 3.0})
  {
    const ApartFlows ref = rk4Flows(p, law, s, tau, 20000);
    expectExactFlows<WideFreeMotion>(p, law, s, tau, ref);
    if (!apartNeedsSeries(p, tau))  // the compact form where it applies (every rate fast over the window)
    {
      expectExactFlows<FreeMotion>(p, law, s, tau, ref);
      ++compact;
    }
  }
  EXPECT_GE(compact, 1);
}

namespace
{
TEST(LoadTorque, TheMeshTorqueBoundIsAboveTheComputedMeshTorque)
{
  // The impact rule decides a rebound against MeshTorqueBound first and computes the mesh torque only when the bound
  // does not decide: the bound must lie above contactMeshTorque()'s computed value for every parameter set and state
  // (else a rebound would be called elastic that the torque calls plastic), and be its terms' magnitudes (a loose
  // bound would decide nothing). Checked against the torque written out here in long double.
  std::mt19937 rng(5);
  auto logUniform = [&](double lo, double hi) {
    return std::exp(std::uniform_real_distribution<double>(std::log(lo), std::log(hi))(rng));
  };
  auto signedLog = [&](double lo, double hi) { return (rng() % 2 ? 1.0 : -1.0) * logUniform(lo, hi); };
  int tight = 0;
  for (int i = 0; i < 100000; ++i)
  {
    ServoParams p;
    p.motor_inertia = logUniform(1e-5, 1e2);
    p.load_inertia = logUniform(1e-5, 1e2);
    p.gear_ratio = logUniform(1e-2, 1e2);
    p.motor_friction = i % 7 == 0 ? 0.0 : logUniform(1e-4, 1e2);
    p.load_friction = i % 5 == 0 ? 0.0 : logUniform(1e-4, 1e2);
    p.load_torque = i % 3 == 0 ? 0.0 : signedLog(1e-4, 1e3);
    MotorInput law;
    law.offset = signedLog(1e-4, 1e3);
    law.stiffness = logUniform(1e-3, 1e3);
    const double x = signedLog(1e-6, 1e3), v = signedLog(1e-9, 1e3);
    const double bound = MeshTorqueBound(p)(law.torque(x), v);
    const double computed = std::fabs(contactMeshTorque(p, law, x, v));
    ASSERT_GE(bound, computed) << "case " << i;
    // Independent: J_L (ρ T_m + ρ² T_ext − F v)/J + f_L v − T_ext and its terms by magnitude, in long double.
    using L = long double;
    const L rho = p.gear_ratio, jl = p.load_inertia, j = L(p.motor_inertia) + rho * rho * jl;
    const L f = L(p.motor_friction) + rho * rho * L(p.load_friction);
    const L tm = law.torque(x), te = p.load_torque;
    const L exact = jl * (rho * tm + rho * rho * te - f * v) / j + L(p.load_friction) * v - te;
    const L terms = jl / j * (rho * std::fabs(tm) + rho * rho * std::fabs(te) + f * std::fabs(v)) +
                    L(p.load_friction) * std::fabs(L(v)) + std::fabs(te);
    ASSERT_GE(L(bound), std::fabs(exact)) << "case " << i;
    ASSERT_GE(L(bound), terms) << "case " << i;
    ASSERT_LE(L(bound), 1.0011L * terms) << "case " << i;
    tight += L(bound) <= 1.0011L * std::fabs(exact);  // no cancellation: the bound is the torque itself (+0.1 %)
  }
  EXPECT_GT(tight, 10000);  // the same-sign states are decided at the torque's own size
}
}  // namespace

namespace
{
TEST(LoadTorque, ANewLoadTorqueKeepsTheTeethOnTheirFlank)
{
  // A joint whose load torque is updated at every sample (an arm's gravity) stays on the flank it rests on: the gap
  // read back from the positions may differ from Δ in its last bits, which must not count as the teeth parting
  // (each parting is a new flight and an impact, thousands a second).
  ServoParams p;
  p.gear_ratio = 0.01;
  p.backlash = 0.0026;
  p.motor_inertia = 2e-4;  // a robot joint: 100:1, reflected motor twice the load
  p.load_inertia = 1.0;
  p.motor_friction = 1e-3;
  p.load_friction = 0.5;
  p.gain = 30.0;
  p.load_torque = 2.0;  // presses the load in +: the motor's tooth holds it back on the g = Δ flank
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> where(-3.0, 3.0);
  for (int k = 0; k < 200; ++k)
  {
    State s;
    s.load_position = where(rng);
    s.motor_position = (s.load_position - p.backlash) / p.gear_ratio;
    s.contact = Contact::Backward;
    Simulator sim(p, s, s.load_position);
    ServoParams q = p;
    q.load_torque = 2.0 + 1e-3 * k;
    sim.setParams(q);
    EXPECT_EQ(sim.state().contact, Contact::Backward) << s.load_position;
    EXPECT_NEAR(sim.gap(), p.backlash, 1e-12) << s.load_position;
    q.backlash = 0.003;  // a larger backlash: now the teeth float inside it
    sim.setParams(q);
    EXPECT_EQ(sim.state().contact, Contact::Apart) << s.load_position;
  }
}
}  // namespace
