// A sinusoidal torque on the load (Plant::setLoadWave, Simulator::setLoadTorqueWave): exact, on rigid teeth and on
// a compliant mesh. Against independent truth: the forced responses of the locked joint (Δ = 0) and of the undamped
// two-mass drive, solved here; the energy ledger through the sine and after it; chunk-independence bit for bit;
// refusals naming the key, nothing changed.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include "backlash_servo/plant/plant.h"
#include "backlash_servo/simulation/simulator.h"
#include "compliant/compliant_joint.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;
using cd = std::complex<double>;
constexpr double PI = 3.14159265358979323846;

struct Impacts : EventSink
{
  int count = 0;
  bool wantsImpacts() const override { return true; }
  void onEvent(const Event& e) override { count += e.type == EventType::Impact ? 1 : 0; }
};

std::string refusal(const std::function<void()>& f)
{
  try
  {
    f();
  }
  catch (const InvalidParameterError& e)
  {
    return e.field();
  }
  return "accepted";
}

}  // namespace

TEST(LoadWave, WithoutBacklashTheJointFollowsTheLockedForcedResponse)
{
  // Δ = 0: the teeth never part and the joint is one body on the load shaft, J θ̈_c + F_T θ̇_c + ρKθ_c = ρ²T_ext
  // (J = J_m + ρ²J_L, F_T = f_m + ρ²f_L) under the continuous P law, K = 0 in effort mode. Started on the forced
  // response of T_ext = B sin ωt, θ_c = Im(H B e^{jωt}) with H = ρ²/(ρK − Jω² + jωF_T), the run stays on it while
  // the mesh torque changes sign and the teeth change flank (no impact).
  ServoParams p;
  p.backlash = 0.0;
  p.gear_ratio = 0.5;
  p.load_inertia = 2.0;
  p.load_friction = 0.3;
  const double rho = p.gear_ratio, J = p.totalInertia(), F = p.totalFriction(), b = 0.4;
  for (const bool loop : {true, false})
  {
    for (const double w : {0.3, 1.7, 6.0})
    {
      const double k = loop ? p.gain : 0.0;
      const cd h = rho * rho / (rho * k - J * w * w + cd(0.0, w * F));
      Simulator sim(p, test_helpers::onForcedResponse(h * b, w, rho, 0.0), 0.0);
      if (!loop)
      {
        sim.setMotorTorque(0.0);
      }
      Impacts impacts;
      sim.setLoadTorqueWave(Sinusoid{b, w, 0.0, 0.0}, &impacts);
      const double worst = test_helpers::worstFromForcedResponse(sim, h * b, w, &impacts);
      EXPECT_LT(worst, 1e-9 * std::abs(h) * b) << (loop ? "P law" : "effort") << " w = " << w;
      EXPECT_EQ(impacts.count, 0) << "w = " << w;
    }
  }
}

TEST(LoadWave, AnUndampedCompliantMeshFollowsTheTwoMassForcedResponse)
{
  // An undamped mesh without backlash is a linear spring c(ρθ_m − θ_c): the motor J_m θ̈_m + f_m θ̇_m =
  // −Kθ_c − ρc(ρθ_m − θ_c), the load J_L θ̈_c + f_L θ̇_c = c(ρθ_m − θ_c) + B sin ωt — solved here as a 2 × 2 system —,
  // below, between and above the two-mass drive's anti-resonance and resonance.
  ServoParams p;
  p.backlash = 0.0;
  p.gear_ratio = 0.5;
  p.mesh_stiffness = 400.0;
  p.mesh_damping = 0.0;
  const double rho = p.gear_ratio, c = p.mesh_stiffness, b = 0.3;
  for (const double w : {0.8, 16.0, 60.0})
  {
    const cd s(0.0, w);
    const cd m = p.motor_inertia * s * s + p.motor_friction * s + rho * rho * c;
    const cd l = p.load_inertia * s * s + p.load_friction * s + c;
    // [m, K − ρc; −ρc, l] (Θ_m, Θ_c) = (0, B)
    const cd det = m * l - (p.gain - rho * c) * (-rho * c);
    const cd tm = -(p.gain - rho * c) * b / det, tc = m * b / det;
    const auto at = [&](cd amp, double time, double* x, double* v) {
      const cd z = amp * std::exp(cd(0.0, w * time));
      *x = z.imag();
      *v = (cd(0.0, w) * z).imag();
    };
    State s0;
    at(tc, 0.0, &s0.load_position, &s0.load_velocity);
    at(tm, 0.0, &s0.motor_position, &s0.motor_velocity);
    Simulator sim(p, s0, 0.0);
    sim.setLoadTorqueWave(Sinusoid{b, w, 0.0, 0.0});
    double worst = 0.0;
    for (int i = 1; i <= 40; ++i)
    {
      const double time = i * 0.25 * PI / w;
      sim.advanceTo(time);
      double x, v, xm, vm;
      at(tc, time, &x, &v);
      at(tm, time, &xm, &vm);
      worst = std::max({worst, std::fabs(sim.state().load_position - x), std::fabs(sim.state().motor_position - xm)});
    }
    EXPECT_LT(worst, 1e-9 * std::max(std::abs(tc), std::abs(tm))) << "w = " << w;
  }
}

TEST(LoadWave, TheLedgerBalancesThroughTheSineAndAfterItAndChunksCutNothing)
{
  // Rigid teeth with bouncing impacts under the P loop, a load sine for 15 s and then none (the thesis' modes take the
  // motion again); and a compliant mesh with damping: the ledger — the load torque's work included — balances to
  // rounding, and a run cut into many advanceTo() calls is bit-identical.
  for (const bool compliant : {false, true})
  {
    ServoParams p = test_helpers::bouncing();
    p.load_torque = 0.1;
    if (compliant)
    {
      p.mesh_stiffness = 300.0;
      p.mesh_damping = 2.0;
    }
    const Sinusoid sine{0.6, 1.3, 0.0, 0.0};
    Simulator whole(p, State(), 1.0), cut(p, State(), 1.0);
    Impacts seen;
    whole.setLoadTorqueWave(sine);
    cut.setLoadTorqueWave(sine);
    whole.advanceTo(15.0, &seen);
    EXPECT_NE(whole.plant().compliantJoint(), nullptr);
    EXPECT_LT(std::fabs(whole.plant().energyBalanceError()), 1e-11 * whole.plant().energy().input_magnitude);
    EXPECT_NE(whole.plant().energy().load_work, 0.0);
    whole.setLoadTorqueWave(Waveform());
    cut.advanceTo(15.0);
    cut.setLoadTorqueWave(Waveform());
    whole.advanceTo(40.0, &seen);
    EXPECT_EQ(whole.plant().compliantJoint() != nullptr, compliant);  // rigid teeth: the thesis' modes again
    EXPECT_LT(std::fabs(whole.plant().energyBalanceError()), 1e-11 * whole.plant().energy().input_magnitude);
    if (!compliant)
    {
      EXPECT_GT(seen.count, 5);
    }
    for (double t = 15.0137; t < 40.0; t += 0.0137)
    {
      cut.advanceTo(t);
    }
    cut.advanceTo(40.0);
    EXPECT_EQ(cut.state().load_position, whole.state().load_position) << compliant;
    EXPECT_EQ(cut.state().motor_velocity, whole.state().motor_velocity) << compliant;
  }
}

TEST(LoadWave, WhatCannotCarryItIsRefusedNamingTheKeyAndNothingChanges)
{
  ServoParams p;
  p.load_coulomb_friction = p.load_static_friction = 0.1;
  Simulator dry(p, State(), 1.0);
  EXPECT_EQ(refusal([&] { dry.setLoadTorqueWave(Sinusoid{0.2, 1.0, 0.0, 0.0}); }), "load_static_friction");
  EXPECT_EQ(dry.plant().compliantJoint(), nullptr);
  EXPECT_FALSE(dry.plant().loadWave().active());
  Simulator plain(ServoParams(), State(), 1.0);
  EXPECT_EQ(refusal([&] { plain.setLoadTorqueWave(Sinusoid{NAN, 1.0, 0.0, 0.0}); }), "load_wave");
  // A torsional shaft holds one sine: the motor's and the load's together.
  ServoParams shaft;
  shaft.mesh_stiffness = 1e3;
  shaft.gear_inertia = 0.1;
  shaft.shaft_stiffness = 500.0;
  Simulator sim(shaft, State(), 0.0);
  sim.setMotorTorque(0.0, Sinusoid{0.1, 2.0, 0.0, 0.0});
  EXPECT_EQ(refusal([&] { sim.setLoadTorqueWave(Sinusoid{0.2, 1.0, 0.0, 0.0}); }), "load_wave");
  EXPECT_FALSE(sim.plant().loadWave().active());
  sim.advanceTo(1.0);  // (still runs, on the motor's sine)
  EXPECT_TRUE(std::isfinite(sim.state().load_position));
}
