// Rigid teeth under a law with a sine (compliant_joint.h, "Rigid teeth"; plant_compliant.cpp): the joint's closed
// forms carry the thesis' rigid mesh with its impacts. Against independent truth: the thesis' own modes (modes.h,
// another implementation of the same mesh) where both apply; the closed-form forced response of the meshed pair with
// Δ = 0; a sampled sine through the thesis modes tending to the exact one at first order in the sample period; the
// energy ledger; chunk-independence bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <vector>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/drive/drive.h"
#include "backlash_servo/plant/plant.h"
#include "backlash_servo/simulation/simulator.h"
#include "compliant/compliant_joint.h"
#include "test_helpers.h"

namespace
{
using namespace backlash_servo;
using cd = std::complex<double>;
constexpr double PI = 3.14159265358979323846;

using test_helpers::bouncing;

struct Impacts : EventSink
{
  std::vector<Event> impacts;
  bool wantsImpacts() const override { return true; }
  void onEvent(const Event& e) override
  {
    if (e.type == EventType::Impact)
    {
      impacts.push_back(e);
    }
  }
};

}  // namespace

TEST(RigidWave, TheJointsRigidTeethMoveAsTheThesisModesDo)
{
  // No wave: the step response of the P loop through the free play, with impacts and chatter, by the joint's closed
  // forms and by the thesis' modes — two implementations of one model — agree to rounding-level error over 30 s.
  const ServoParams p = bouncing();
  const double k = p.gain, command = 1.0;
  const MotorInput law(k * command, k);
  Plant plant(p, State(), law);
  CompliantJoint joint(p, law);
  joint.setState(Eigen::Vector4d::Zero());
  joint.setLaw(law);
  ASSERT_TRUE(joint.rigid());
  for (double t = 0.5; t <= 30.0; t += 0.5)
  {
    plant.advanceTo(t, nullptr);
    joint.advanceTo(t);
    const Eigen::VectorXd x = joint.state();
    const State& s = plant.state();
    ASSERT_NEAR(x(2), s.load_position, 1e-9) << "t = " << t;
    ASSERT_NEAR(x(3), s.load_velocity, 1e-9) << "t = " << t;
    ASSERT_NEAR(x(0), s.motor_position, 1e-9) << "t = " << t;
    ASSERT_NEAR(x(1), s.motor_velocity, 1e-9) << "t = " << t;
  }
  EXPECT_GT(plant.impactCount(), 10u);
  EXPECT_EQ(joint.impacts(), plant.impactCount());
  EXPECT_LT(std::fabs(joint.energyBalanceError()), 1e-12);
}

TEST(RigidWave, WithoutBacklashASineCommandGivesTheMeshedPairsForcedResponse)
{
  // Δ = 0: the teeth never part and the joint is one body, J θ̈_c + F_T θ̇_c + ρKθ_c = ρK θ_R. Started on the
  // forced response of θ_R = A sin ωt, θ_c = Im(T(jω) A e^{jωt}) with T = ρK/(ρK − Jω² + jωF_T), the run stays on it
  // — while the mesh torque changes sign twice a period and the teeth change flank.
  ServoParams p;
  p.backlash = 0.0;
  p.gear_ratio = 0.5;
  p.load_inertia = 2.0;
  p.load_friction = 0.3;
  const double rho = p.gear_ratio, K = p.gain, J = p.totalInertia(), F = p.totalFriction();
  for (const double w : {0.3, 1.7, 6.0})
  {
    const double a = 0.4;
    const cd t = rho * K / (rho * K - J * w * w + cd(0.0, w * F));
    Simulator sim(p, test_helpers::onForcedResponse(t * a, w, rho, 0.0), 0.0);
    Impacts flips;
    sim.setCommandWave(0.0, Sinusoid{a, w, 0.0, 0.0}, &flips);
    const double worst = test_helpers::worstFromForcedResponse(sim, t * a, w, &flips);
    EXPECT_LT(worst, 1e-9 * a) << "w = " << w;
    EXPECT_TRUE(flips.impacts.empty()) << "w = " << w;  // flank changes at relative rest: no impact
  }
}

TEST(RigidWave, ASampledSineThroughTheThesisModesTendsToTheExactOne)
{
  // The exact sine command against a digital P drive sampling it (the thesis' modes, a torque held per sample):
  // the held drive's error is first order in the sample period, so it falls ~10× per decade of the rate, and the
  // impacts happen at the same instants to within that error.
  const ServoParams p = bouncing();
  const Sinusoid sine{0.6, 1.3, 0.0, 0.0};
  Simulator exact(p, State(), 0.0);
  Impacts exact_impacts;
  exact.setCommandWave(0.0, sine, &exact_impacts);
  exact.advanceTo(6.0, &exact_impacts);
  ASSERT_GE(exact_impacts.impacts.size(), 2u);
  std::vector<double> errors;
  for (const double rate : {1e3, 1e4})
  {
    const auto profile = std::make_shared<const CommandProfile>(0.0, std::vector<ProfileSegment>{[&] {
                                                                  ProfileSegment s;
                                                                  s.kind = ProfileSegment::Kind::Sine;
                                                                  s.amplitude = sine.amplitude;
                                                                  s.frequency = sine.frequency / (2.0 * PI);
                                                                  s.duration = 100.0;
                                                                  return s;
                                                                }()});
    DriveParams drive;
    drive.controller_rate = rate;
    Simulator sampled(p, State(), 0.0);
    sampled.setDrive(std::make_unique<SampledDrive>(drive, p.gain, p.gear_ratio, 0.0, 0.0));
    sampled.setProfile(profile);
    Impacts sampled_impacts;
    sampled.advanceTo(6.0, &sampled_impacts);
    errors.push_back(std::fabs(sampled.state().load_position - exact.state().load_position));
    // The impacts (those faster than 1e-3 rad/s: a chatter's last few, near the plastic threshold, are rounding's)
    // one for one, each within a sample period of the exact instant (the held command lags by half a sample).
    const auto strong = [](const Impacts& seen) {
      std::vector<Event> out;
      for (const Event& e : seen.impacts)
      {
        if (e.impact.approach_speed > 1e-3)
        {
          out.push_back(e);
        }
      }
      return out;
    };
    const std::vector<Event> a = strong(sampled_impacts), b = strong(exact_impacts);
    ASSERT_EQ(a.size(), b.size()) << "rate " << rate;
    for (std::size_t i = 0; i < a.size(); ++i)
    {
      EXPECT_NEAR(a[i].state.time, b[i].state.time, 1.0 / rate) << "rate " << rate << ", impact " << i;
      EXPECT_NEAR(a[i].impact.approach_speed, b[i].impact.approach_speed, 20.0 / rate) << "rate " << rate;
    }
  }
  std::printf("load angle at 6 s, sampled at 1 kHz / 10 kHz − exact: %.3g / %.3g rad\n", errors[0], errors[1]);
  EXPECT_LT(errors[1], 1e-3);
  EXPECT_GT(errors[0] / errors[1], 5.0) << errors[0] << " " << errors[1];
  EXPECT_LT(errors[0] / errors[1], 20.0) << errors[0] << " " << errors[1];
}

TEST(RigidWave, TheLedgerBalancesThroughTheSineAndAfterItAndChunksCutNothing)
{
  // A sine segment on rigid teeth with bouncing impacts, then the command holds its centre (the thesis' modes take
  // over again): the energy ledger — motor work, friction, impact losses — balances to rounding across both, and a
  // run cut into many advanceTo() calls is bit-identical.
  const ServoParams p = bouncing();
  ProfileSegment sine;
  sine.kind = ProfileSegment::Kind::Sine;
  sine.amplitude = 0.5;
  sine.frequency = 0.4;
  sine.duration = 20.0;
  const auto profile = std::make_shared<const CommandProfile>(0.3, std::vector<ProfileSegment>{sine});
  Simulator whole(p, State(), 0.0), cut(p, State(), 0.0);
  whole.setProfile(profile);
  cut.setProfile(profile);
  Impacts seen;
  whole.advanceTo(15.0, &seen);
  EXPECT_NE(whole.plant().compliantJoint(), nullptr);  // the joint carries the sine
  EXPECT_GT(seen.impacts.size(), 5u);
  const double scale = whole.plant().energy().input_magnitude;
  EXPECT_LT(std::fabs(whole.plant().energyBalanceError()), 1e-11 * scale);
  EXPECT_GT(whole.plant().energy().impact_loss, 0.0);
  whole.advanceTo(40.0, &seen);
  EXPECT_EQ(whole.plant().compliantJoint(), nullptr);  // the thesis' modes again
  EXPECT_NEAR(whole.state().load_position, 0.3, 0.2);
  EXPECT_LT(std::fabs(whole.plant().energyBalanceError()), 1e-11 * whole.plant().energy().input_magnitude);
  for (double t = 0.0137; t < 40.0; t += 0.0137)
  {
    cut.advanceTo(t);
  }
  cut.advanceTo(40.0);
  EXPECT_EQ(cut.state().load_position, whole.state().load_position);
  EXPECT_EQ(cut.state().motor_velocity, whole.state().motor_velocity);
}

TEST(RigidWave, DryFrictionOnRigidTeethRefusesTheExactSineNamingTheKey)
{
  ServoParams p = bouncing();
  p.load_coulomb_friction = p.load_static_friction = 0.1;
  Simulator sim(p, State(), 0.0);
  try
  {
    sim.setCommandWave(0.0, Sinusoid{0.5, 1.0, 0.0, 0.0});
    ADD_FAILURE() << "accepted";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_EQ(e.field(), "load_static_friction");
    EXPECT_NE(std::string(e.what()).find("controller_rate"), std::string::npos) << e.what();
  }
  EXPECT_EQ(sim.plant().compliantJoint(), nullptr);  // nothing changed
  EXPECT_THROW(sim.setMotorTorque(0.0, Sinusoid{0.5, 1.0, 0.0, 0.0}), InvalidParameterError);
}

TEST(RigidWave, ASumOfSinesIsTheSumOfTheResponsesWhereTheJointIsLinear)
{
  // Without backlash (and, for a compliant mesh, damping) the joint is linear: from rest, the response to two sines is
  // the sum of the responses to each (superposition) — rigid teeth and a compliant mesh alike, the command under the
  // continuous law and a torque in effort mode. A sine profile with a dither is that sum, taken exactly; more sines
  // than the modes carry are refused naming the key.
  for (const double stiffness : {0.0, 400.0})
  {
    ServoParams p;
    p.backlash = 0.0;
    p.gear_ratio = 0.5;
    p.mesh_stiffness = stiffness;
    // (undamped: a damper's torque that would pull releases the flank, so a damped mesh is not linear even at Δ = 0)
    const Sinusoid a{0.3, 1.1, 0.2, 0.0}, b{0.05, 13.0, 0.0, 0.0};
    Waveform both = a;
    both.add(b);
    for (const bool torque : {false, true})
    {
      const auto run = [&](const Waveform& w) {
        Simulator sim(p, State(), 0.0);
        torque ? sim.setMotorTorque(0.0, w) : sim.setCommandWave(0.0, w);
        sim.advanceTo(7.3);
        return sim.state();
      };
      const State sa = run(a), sb = run(b), sum = run(both);
      EXPECT_NEAR(sum.load_position, sa.load_position + sb.load_position, 1e-11) << stiffness << " " << torque;
      EXPECT_NEAR(sum.motor_velocity, sa.motor_velocity + sb.motor_velocity, 1e-10) << stiffness << " " << torque;
      EXPECT_GT(std::fabs(sb.load_position), 1e-4);  // (the second sine matters)
    }
  }
  // The profile's sine with a dither under the continuous law: the two sines, bit for bit.
  ServoParams p = bouncing();
  ProfileSegment sine;
  sine.kind = ProfileSegment::Kind::Sine;
  sine.amplitude = 0.4;
  sine.frequency = 0.3;
  sine.dither_amplitude = 0.01;
  sine.dither_frequency = 5.0;
  sine.duration = 30.0;
  Simulator profiled(p, State(), 0.0), direct(p, State(), 0.0);
  profiled.setProfile(std::make_shared<const CommandProfile>(0.0, std::vector<ProfileSegment>{sine}));
  Waveform w = Sinusoid{0.4, 2.0 * PI * 0.3, 0.0, 0.0};
  w.add(Sinusoid{0.01, 2.0 * PI * 5.0, 0.0, 0.0});
  direct.setCommandWave(0.0, w);
  profiled.advanceTo(12.0);
  direct.advanceTo(12.0);
  EXPECT_EQ(profiled.state().load_position, direct.state().load_position);
  EXPECT_EQ(profiled.state().motor_velocity, direct.state().motor_velocity);
  // A torsional shaft's modes carry one sine: the dithered profile is refused, naming the key.
  ServoParams shaft;
  shaft.mesh_stiffness = 1e3;
  shaft.gear_inertia = 0.1;
  shaft.shaft_stiffness = 1e3;
  Simulator twisted(shaft, State(), 0.0);
  try
  {
    twisted.setProfile(std::make_shared<const CommandProfile>(0.0, std::vector<ProfileSegment>{sine}));
    ADD_FAILURE() << "accepted";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_EQ(e.field(), "profile");
  }
  EXPECT_THROW(twisted.setMotorTorque(0.0, w), InvalidParameterError);
}

TEST(RigidWave, NewParametersDuringTheSineTakeEffectAndTheLedgerGoesOn)
{
  // Live tuning while a sine runs on rigid teeth: the restitution and the backlash changed mid-run take effect (the
  // run then equals one started with them from the state just after the change), and the ledger still balances.
  const ServoParams p = bouncing();
  ServoParams q = p;
  q.restitution = 0.2;
  q.backlash = 0.1;
  const Sinusoid sine{0.5, 1.3, 0.0, 0.0};
  Simulator tuned(p, State(), 0.0);
  tuned.setCommandWave(0.0, sine);
  tuned.advanceTo(4.0);
  tuned.setParams(q);
  const State at_change = tuned.state();  // (re-expressed on the new mesh)
  ASSERT_NE(tuned.plant().compliantJoint(), nullptr);
  tuned.advanceTo(12.0);
  Simulator fresh(q, at_change, 0.0);
  fresh.setCommandWave(0.0, sine);
  fresh.advanceTo(12.0);
  EXPECT_NEAR(tuned.state().load_position, fresh.state().load_position, 1e-9);
  EXPECT_NEAR(tuned.state().motor_velocity, fresh.state().motor_velocity, 1e-9);
  EXPECT_LT(std::fabs(tuned.plant().energyBalanceError()), 1e-11 * tuned.plant().energy().input_magnitude);
  ServoParams dry = q;
  dry.motor_coulomb_friction = dry.motor_static_friction = 0.01;
  EXPECT_THROW(tuned.setParams(dry), InvalidParameterError);  // refused, the old parameters kept
  EXPECT_EQ(tuned.params().restitution, 0.2);
}
