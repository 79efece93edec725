// The stepped-sine frequency response against independent truth: with Δ = 0 the joint is linear, and its response is
// the transfer function (times the hold, and the sampled loop's) written here from the equations of motion.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>

#include "backlash_servo/drive/command_profile.h"
#include "backlash_servo/frequency/broadband_response.h"
#include "backlash_servo/frequency/frequency_response.h"
#include "test_helpers.h"

using namespace backlash_servo;
using cd = std::complex<double>;

namespace
{
constexpr double PI = 3.14159265358979323846;

/// The thesis' D1 joint (ζ = 0.4, ω_n = 1 rad/s, ρ = 1) with the given backlash.
RunConfig d1(double backlash)
{
  RunConfig c;
  c.params.backlash = backlash;
  c.params.restitution = 0.8;
  return c;
}

/// The zero-order hold's gain at ω for a sample period T: the held sequence's component at ω over the sequence's.
cd hold(double w, double t)
{
  return (1.0 - std::exp(cd(0.0, -w * t))) / cd(0.0, w * t);
}

}  // namespace

TEST(FrequencyResponse, LockedTorqueToVelocityIsTheHeldTransferFunction)
{
  // Δ = 0: the teeth never part, the joint is one body on the motor shaft: J ω̇_m = T_m − F ω_m.
  for (const double w : {0.05, 0.7, 3.0, 40.0})
  {
    RunConfig c = d1(0.0);
    FrfSettings s;
    s.channel = FrfChannel::TorqueToMotorVelocity;
    s.injection_rate = 200.0;
    s.tolerance = 1e-13;
    const FrfPoint p = measureFrequencyResponse(c, s, 0.3, w);
    ASSERT_TRUE(p.periodic) << w;
    EXPECT_EQ(p.period_multiple, 1);
    const double jt = c.params.totalInertia(), f = c.params.totalFriction();
    const double wu = p.frequency;
    EXPECT_NEAR(wu, 2.0 * PI * 200.0 / std::round(2.0 * PI * 200.0 / w), 1e-12 * wu);
    const cd expected = 1.0 / cd(f, wu * jt) * hold(wu, 1.0 / 200.0);
    EXPECT_LT(std::abs(p.response - expected), 1e-9 * std::abs(expected)) << w << " " << p.response << expected;
    EXPECT_LT(p.distortion, 1e-9);
    EXPECT_EQ(p.flank_changes, 0.0);
  }
}

TEST(FrequencyResponse, TheSetpointInjectionMeasuresTheMechanicsWithTheLoopsClosed)
{
  // A torque injected into the digital drive's set-point, its loops closed: ω over the motor torque the drive applied
  // is the mechanics' own response, whatever the law — Δ = 0: ω_m/T_m = 1/(Jjω + F_T) on the motor shaft (ρ = 0.5 here,
  // J = J_m + ρ²J_L, F_T = f_m + ρ²f_L), ω_c/T_m = ρ times it, for a P law with a one-sample delay and a cascade.
  // With backlash and a speed offset a small injection leaves the teeth on one flank: the same response, to the
  // same 1e-9.
  for (const double w : {0.4, 6.0})
  {
    for (const bool cascade : {false, true})
    {
      RunConfig c = d1(0.0);
      c.params.gear_ratio = 0.5;
      c.drive.controller_rate = 500.0;
      if (cascade)
      {
        c.drive.control_law = "cascade";
        c.drive.position_loop_gain = 2.0;
        c.drive.velocity_loop_gain = 1.5;
        c.drive.velocity_loop_integral_gain = 1.0;
      }
      else
      {
        c.drive.controller_delay = 1.0;
      }
      FrfSettings s;
      s.channel = FrfChannel::SetpointToMotorVelocity;
      s.tolerance = 1e-12;
      const FrfPoint p = measureFrequencyResponse(c, s, 0.2, w);
      ASSERT_TRUE(p.periodic) << w;
      const double wu = p.frequency;
      const cd motor = 1.0 / cd(c.params.totalFriction(), wu * c.params.totalInertia());
      EXPECT_LT(std::abs(p.response - motor), 1e-9 * std::abs(motor)) << w << " " << cascade << " " << p.response;
      s.channel = FrfChannel::SetpointToLoadVelocity;
      const FrfPoint q = measureFrequencyResponse(c, s, 0.2, w);
      EXPECT_LT(std::abs(q.response - 0.5 * motor), 1e-9 * std::abs(motor)) << w << " " << cascade;
      c.params.backlash = 0.3;
      s.channel = FrfChannel::SetpointToMotorVelocity;
      s.offset = 0.5;  // [rad/s]
      const FrfPoint r = measureFrequencyResponse(c, s, 0.02, w);
      ASSERT_TRUE(r.periodic) << w;
      EXPECT_EQ(r.flank_changes, 0.0);
      EXPECT_LT(std::abs(r.response - motor), 1e-9 * std::abs(motor)) << w << " " << cascade << " " << r.response;
    }
  }
  // What it refuses, naming the key: no digital drive, an injection rate of its own, the sine itself.
  RunConfig c = d1(0.3);
  FrfSettings s;
  s.channel = FrfChannel::SetpointToMotorVelocity;
  try
  {
    measureFrequencyResponse(c, s, 0.1, 1.0);
    ADD_FAILURE() << "the continuous law has no set-point to inject into";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_EQ(e.field(), "controller_rate");
  }
  c.drive.controller_rate = 100.0;
  s.injection_rate = 1000.0;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
  s.injection_rate = 0.0;
  s.continuous = true;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
}

TEST(FrequencyResponse, TheReleaseAmplitudeIsWhereTheLinearJointsMeshTorqueReachesZero)
{
  // A load torque holds D1's teeth on a flank. Without backlash, under the continuous law's exact sine, the mesh
  // torque is Q = −T_ext + (−J_Lω² + jωf_L)T(jω)·A e^{jωt}, T the pair's transfer function: the flank is released
  // above A* = T_ext/|(−J_Lω² + jωf_L)T(jω)| (to 1e-9). The joint with backlash confirms it: at 0.98 A* its teeth stay
  // on the flank and its response is the linear one; at 1.02 A* they part. Under a digital drive (a held sine) A* is
  // read from the sampled period, and the same bracket holds.
  for (const bool sampled : {false, true})
  {
    RunConfig c = d1(0.2);
    c.params.load_torque = 0.2;
    if (sampled)
    {
      c.drive.controller_rate = 200.0;
    }
    RunConfig lin = c;
    lin.params.backlash = 0.0;
    FrfSettings s;
    s.tolerance = 1e-12;
    for (const double w : {0.5, 2.0})
    {
      const FrfPoint l = measureFrequencyResponse(lin, s, 0.05, w);
      const double release = releaseAmplitude(l);
      ASSERT_TRUE(std::isfinite(release)) << w;
      if (!sampled)
      {
        const double jl = c.params.load_inertia, fl = c.params.load_friction;
        const cd t = 1.0 / cd(1.0 - w * w, 0.8 * w);
        const double expected = 0.2 / std::abs(cd(-jl * w * w, fl * w) * t);
        EXPECT_NEAR(release, expected, 1e-9 * expected) << w;
      }
      const FrfPoint below = measureFrequencyResponse(c, s, 0.98 * release, w);
      EXPECT_EQ(below.separations, 0.0) << w << " " << sampled;
      EXPECT_LT(std::abs(below.response - l.response), 1e-9 * std::abs(l.response)) << w << " " << sampled;
      const FrfPoint above = measureFrequencyResponse(c, s, 1.02 * release, w);
      EXPECT_GT(above.separations, 0.0) << w << " " << sampled;
    }
  }
}

TEST(FrequencyResponse, ALoadTorqueSineGivesTheServosDynamicCompliance)
{
  // A sine torque on the load, the P loop holding the command. Δ = 0 under the continuous law: the locked joint
  // J θ̈_c + F_T θ̇_c + ρKθ_c = ρ²T_ext gives θ_c/T_ext = H = ρ²/(ρK − Jω² + jωF_T) (to 1e-9), and its mesh torque
  // Q = (−J_Lω² + jωf_L)θ_c − T_ext: with a constant load torque T₀ the flank is released above
  // A* = T₀/|(−J_Lω² + jωf_L)H − 1|. The joint with backlash pressed by T₀ follows the locked response below A* (to
  // 1e-9) and parts from its flank above it — under the continuous law and under a 1 kHz PID drive.
  for (const bool sampled : {false, true})
  {
    RunConfig c = d1(0.3);
    c.params.gear_ratio = 0.5;
    if (sampled)
    {
      c.drive.controller_rate = 1000.0;
      c.drive.control_law = "pid";
      c.drive.integral_gain = 0.5;
      c.drive.derivative_gain = 0.5;
    }
    RunConfig lin = c;
    lin.params.backlash = 0.0;
    FrfSettings s;
    s.channel = FrfChannel::LoadTorqueToLoadPosition;
    s.tolerance = 1e-12;
    s.offset = 0.3;  // T₀ [N·m]
    for (const double w : {0.3, 1.0, 3.0})
    {
      const FrfPoint l = measureFrequencyResponse(lin, s, 0.05, w);
      ASSERT_TRUE(l.periodic) << w;
      const double release = releaseAmplitude(l);
      if (!sampled)
      {
        const ServoParams& p = c.params;
        const double rho = p.gear_ratio;
        const cd h = rho * rho / (rho * p.gain - p.totalInertia() * w * w + cd(0.0, w * p.totalFriction()));
        EXPECT_LT(std::abs(l.response - h), 1e-9 * std::abs(h)) << w;
        const double expected = 0.3 / std::abs(cd(-p.load_inertia * w * w, p.load_friction * w) * h - 1.0);
        EXPECT_NEAR(release, expected, 1e-9 * expected) << w;
      }
      const FrfPoint below = measureFrequencyResponse(c, s, 0.98 * release, w);
      EXPECT_EQ(below.separations, 0.0) << w << " " << sampled;
      EXPECT_LT(std::abs(below.response - l.response), 1e-9 * std::abs(l.response)) << w << " " << sampled;
      const FrfPoint above = measureFrequencyResponse(c, s, 1.02 * release, w);
      EXPECT_GT(above.separations, 0.0) << w << " " << sampled;
    }
  }
  // Not by broadband, not held, not "continuous" (it always is), not on rigid teeth with dry friction.
  RunConfig c = d1(0.3);
  c.drive.controller_rate = 100.0;
  BroadbandSettings b;
  b.channel = FrfChannel::LoadTorqueToLoadPosition;
  EXPECT_THROW(measureBroadband(c, b, 0.1), InvalidParameterError);
  FrfSettings s;
  s.channel = FrfChannel::LoadTorqueToLoadPosition;
  s.injection_rate = 500.0;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
  s.injection_rate = 0.0;
  s.continuous = true;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
  s.continuous = false;
  c.params.load_coulomb_friction = c.params.load_static_friction = 0.05;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
}

TEST(FrequencyResponse, LockedSampledLoopIsTheSampledDataTransferFunction)
{
  // Δ = 0 under a digital P drive at f_s: the controller sees y_k = θ_c(t_k) through the ZOH-equivalent plant
  // G_d(z); u_k = K(r_k − y_k); the continuous output's fundamental is ρ P(jω) hold(ω) U with P(s) = 1/(s(Js + F)).
  const double fs = 20.0, ts = 1.0 / fs;
  for (const double w : {0.2, 1.0, 2.5, 10.0})
  {
    RunConfig c = d1(0.0);
    c.drive.controller_rate = fs;
    FrfSettings s;
    s.tolerance = 1e-13;
    s.max_periods = 5000;
    const double amp = 0.01;
    const FrfPoint p = measureFrequencyResponse(c, s, amp, w);
    ASSERT_TRUE(p.periodic) << w;
    const double jt = c.params.totalInertia(), f = c.params.totalFriction(), k = c.params.gain;
    const double rho = c.params.gear_ratio, a = f / jt, e = std::exp(-a * ts);
    // x = (θ_m, ω_m): Φ = [[1, (1 − e)/a], [0, e]], Γ = [(T/a − (1 − e)/a²)/J, ((1 − e)/a)/J].
    const double p01 = (1.0 - e) / a, g0 = (ts / a - (1.0 - e) / (a * a)) / jt, g1 = (1.0 - e) / a / jt;
    const cd z = std::exp(cd(0.0, p.frequency * ts));
    // (zI − Φ)⁻¹Γ, first row: [(z − e) g0 + p01 g1] / ((z − 1)(z − e)).
    const cd gd = rho * ((z - e) * g0 + p01 * g1) / ((z - 1.0) * (z - e));
    const cd r(0.0, -amp);
    const cd u = k * r / (1.0 + k * gd);
    const cd jw(0.0, p.frequency);
    const cd y = rho / (jw * (jt * jw + f)) * hold(p.frequency, ts) * u;
    const cd expected = y / r;
    EXPECT_LT(std::abs(p.response - expected), 1e-9 * std::abs(expected)) << w << " " << p.response << expected;
    EXPECT_NEAR(p.mean, 0.0, 1e-9);
  }
}

TEST(FrequencyResponse, TeethHeldOnOneFlankRespondLikeTheLockedJoint)
{
  // A load torque presses the teeth on one flank; a small sine never parts them, so the joint with backlash responds
  // exactly as the locked one (the constant load torque only shifts where it rests).
  for (const double w : {0.3, 2.0})
  {
    RunConfig c = d1(0.3);
    c.params.load_torque = -0.5;
    c.drive.controller_rate = 50.0;
    RunConfig locked = c;
    locked.params.backlash = 0.0;
    FrfSettings s;
    s.tolerance = 1e-12;
    const FrfPoint p = measureFrequencyResponse(c, s, 0.01, w), q = measureFrequencyResponse(locked, s, 0.01, w);
    ASSERT_TRUE(p.periodic && q.periodic) << w;
    EXPECT_EQ(p.flank_changes, 0.0);
    EXPECT_LT(std::abs(p.response - q.response), 1e-9 * std::abs(q.response)) << w;
    EXPECT_LT(p.distortion, 1e-9);
  }
}

TEST(FrequencyResponse, CompliantMeshPressedIsTheTwoMassTransferFunction)
{
  // Resilient teeth pressed by a torque offset (the joint drifts at a constant speed, the load's friction keeping the
  // forward flank loaded) and a small sine: the linear two-mass drive. With M = J_m s + f_m, L = (J_L + J_g)s + f_L,
  // K = c + d s (at the load shaft): ω_m/T_m = 1/(M + ρ²K L/(sL + K)), ω_c/T_m = ρK/(sL + K) · ω_m/T_m.
  RunConfig c = d1(0.1);
  c.params.gear_ratio = 0.5;
  c.params.mesh_stiffness = 100.0;
  c.params.mesh_damping = 1.0;
  const ServoParams& p = c.params;
  const double rate = 400.0;
  for (const FrfChannel ch : {FrfChannel::TorqueToMotorVelocity, FrfChannel::TorqueToLoadVelocity})
  {
    for (const double w : {3.0, 19.0, 45.0})
    {
      FrfSettings s;
      s.channel = ch;
      s.offset = 1.0;
      s.injection_rate = rate;
      s.tolerance = 1e-12;
      s.max_periods = 20000;
      const FrfPoint r = measureFrequencyResponse(c, s, 0.02, w);
      ASSERT_TRUE(r.periodic) << w;
      EXPECT_EQ(r.flank_changes, 0.0);
      const cd jw(0.0, r.frequency);
      const cd m = p.motor_inertia * jw + p.motor_friction,
               l = (p.load_inertia + p.gear_inertia) * jw + p.load_friction;
      const cd k = p.mesh_stiffness + p.mesh_damping * jw;
      const double rho = p.gear_ratio;
      const cd motor = 1.0 / (m + rho * rho * k * l / (jw * l + k));
      const cd expected = (ch == FrfChannel::TorqueToMotorVelocity ? motor : rho * k / (jw * l + k) * motor) *
                          hold(r.frequency, 1.0 / rate);
      EXPECT_LT(std::abs(r.response - expected), 1e-9 * std::abs(expected))
          << toString(ch) << " " << w << " " << r.response << expected;
      EXPECT_NEAR(r.mean,
                  (ch == FrfChannel::TorqueToMotorVelocity ? 1.0 : rho) * 1.0 /
                      (p.motor_friction + rho * rho * p.load_friction),
                  1e-9);
    }
  }
}

TEST(FrequencyResponse, ARunStartedOnTheSteadyStateRepeatsAtOnce)
{
  // D1 with impacts under a digital P drive (memoryless law): the settled state, taken as a new start with the same
  // excitation, repeats from its first period and gives the same response.
  RunConfig c = d1(0.3);
  c.drive.controller_rate = 100.0;
  FrfSettings s;
  s.tolerance = 1e-11;
  const FrfPoint p = measureFrequencyResponse(c, s, 0.5, 1.0);
  ASSERT_TRUE(p.periodic);
  EXPECT_EQ(p.period_multiple, 1);
  EXPECT_EQ(p.flank_changes, 2.0);  // forward and back once a period
  EXPECT_GT(p.distortion, 1e-3);    // the impacts distort it
  RunConfig again = c;
  again.initial = p.settled_state;
  const FrfPoint q = measureFrequencyResponse(again, s, 0.5, 1.0);
  ASSERT_TRUE(q.periodic);
  EXPECT_EQ(q.periods, 3);  // three period starts compared, then the analysed one
  EXPECT_LT(std::abs(p.response - q.response), 1e-9 * std::abs(p.response));
}

TEST(FrequencyResponse, RefusesWhatItCannotMeasure)
{
  RunConfig c = d1(0.3);
  FrfSettings s;
  c.params.load_coulomb_friction = c.params.load_static_friction = 0.01;
  // the continuous law on rigid teeth with dry friction: no exact sine
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
  c.params.load_coulomb_friction = c.params.load_static_friction = 0.0;
  c.drive.controller_rate = 10.0;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 20.0), InvalidParameterError);  // above f_s/4
  EXPECT_THROW(measureFrequencyResponse(c, s, NAN, 1.0), InvalidParameterError);
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, -1.0), InvalidParameterError);
  EXPECT_THROW(frfChannelFrom("torque:velocity", "channel"), InvalidParameterError);
}

TEST(BroadbandResponse, MaximumLengthSequencesHaveTwoValuedAutocorrelation)
{
  // An m-sequence of length L = 2ⁿ − 1: autocorrelation L at lag 0 and −1 at every other lag; one more +1 than −1.
  for (int order = 3; order <= 12; ++order)
  {
    const std::vector<int> s = maximumLengthSequence(order);
    const std::size_t length = s.size();
    ASSERT_EQ(length, (std::size_t{1} << order) - 1);
    long sum = 0;
    for (int v : s)
    {
      sum += v;
    }
    EXPECT_EQ(sum, 1) << order;
    for (std::size_t lag = 1; lag < length; ++lag)
    {
      long ac = 0;
      for (std::size_t i = 0; i < length; ++i)
      {
        ac += s[i] * s[(i + lag) % length];
      }
      ASSERT_EQ(ac, -1) << order << " " << lag;
    }
  }
  EXPECT_THROW(maximumLengthSequence(2), InvalidParameterError);
}

TEST(BroadbandResponse, AMeasurementBeyondItsSampleBudgetIsRefusedBeforeAnyWork)
{
  // 2^20 samples a period over 1002 periods: 1.05e9 samples, refused at once naming the figure and the keys; one
  // period fewer of the settling passes the check (and is not run here).
  RunConfig c = d1(0.3);
  c.drive.controller_rate = 1000.0;
  BroadbandSettings s;
  s.kind = BroadbandKind::Chirp;
  s.chirp_samples = 1 << 20;
  s.chirp_low = 10.0;    // [rad/s]
  s.chirp_high = 500.0;  // [rad/s]
  s.settle_periods = 2;
  s.periods = 1000;
  try
  {
    measureBroadband(c, s, 0.1);
    ADD_FAILURE() << "accepted";
  }
  catch (const InvalidParameterError& e)
  {
    const std::string what = e.what();
    EXPECT_NE(what.find("periods: 1048576 samples a period × (2 settling + 1000 recorded periods) = 1.05e+09"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("chirp_samples"), std::string::npos) << what;
  }
}

TEST(BroadbandResponse, LockedJointGivesTheSampledTransferFunctionWithUnitCoherence)
{
  // Backlash 0. Torque → motor speed sampled at the hold's instants: ω_{k+1} = e ω_k + b u_k, e = e^{−(F/J)T},
  // b = (1 − e)/F, so H(z) = b/(z − e). Command → load position under a sampled P drive: the closed loop
  // K G_d/(1 + K G_d) with G_d the ZOH-equivalent plant (as in the stepped-sine test). PRBS and chirp alike.
  const RunConfig c = d1(0.0);
  const double jt = c.params.totalInertia(), f = c.params.totalFriction(), k = c.params.gain;
  for (const BroadbandKind kind : {BroadbandKind::Prbs, BroadbandKind::Chirp})
  {
    BroadbandSettings s;
    s.kind = kind;
    s.prbs_order = 8;
    s.chirp_samples = 512;
    s.chirp_low = 0.2;
    s.chirp_high = 30.0;
    s.settle_periods = 8;  // the slowest transient (ζω_n = 0.4 /s) decays below 1e-12 over 8 periods
    s.periods = 2;
    {
      s.channel = FrfChannel::TorqueToMotorVelocity;
      s.injection_rate = 50.0;
      const BroadbandResponse r = measureBroadband(c, s, 0.5);
      ASSERT_GT(r.lines.size(), 50u);
      const double ts = 1.0 / 50.0, e = std::exp(-f / jt * ts), b = (1.0 - e) / f;
      for (const BroadbandLine& l : r.lines)
      {
        const cd z = std::exp(cd(0.0, l.frequency * ts));
        const cd expected = b / (z - e);
        EXPECT_LT(std::abs(l.h1 - expected), 1e-9 * std::abs(expected)) << l.frequency;
        EXPECT_NEAR(l.coherence, 1.0, 1e-9);
      }
    }
    {
      RunConfig loop = c;
      loop.drive.controller_rate = 20.0;
      s.channel = FrfChannel::CommandToLoadPosition;
      s.chirp_high = 15.0;
      const BroadbandResponse r = measureBroadband(loop, s, 0.01);
      ASSERT_GT(r.lines.size(), 50u);
      const double ts = 1.0 / 20.0, a = f / jt, e = std::exp(-a * ts);
      const double p01 = (1.0 - e) / a, g0 = (ts / a - (1.0 - e) / (a * a)) / jt, g1 = (1.0 - e) / a / jt;
      for (const BroadbandLine& l : r.lines)
      {
        const cd z = std::exp(cd(0.0, l.frequency * ts));
        const cd gd = c.params.gear_ratio * ((z - e) * g0 + p01 * g1) / ((z - 1.0) * (z - e));
        const cd expected = k * gd / (1.0 + k * gd);
        EXPECT_LT(std::abs(l.h1 - expected), 1e-9 * std::abs(expected)) << l.frequency;
        EXPECT_NEAR(l.coherence, 1.0, 1e-9);
      }
    }
  }
}

TEST(BroadbandResponse, TeethHeldOnOneFlankMatchTheLockedJointAndFreePlayLowersCoherence)
{
  // A load torque keeps the teeth on one flank under a small PRBS: the estimate is the locked joint's, coherent.
  RunConfig c = d1(0.3);
  c.params.load_torque = -0.5;
  c.drive.controller_rate = 20.0;
  RunConfig locked = c;
  locked.params.backlash = 0.0;
  BroadbandSettings s;
  s.prbs_order = 7;
  s.settle_periods = 12;
  s.periods = 2;
  const BroadbandResponse r = measureBroadband(c, s, 0.005), q = measureBroadband(locked, s, 0.005);
  ASSERT_EQ(r.lines.size(), q.lines.size());
  for (std::size_t i = 0; i < r.lines.size(); ++i)
  {
    EXPECT_LT(std::abs(r.lines[i].h1 - q.lines[i].h1), 1e-9 * std::abs(q.lines[i].h1)) << r.lines[i].frequency;
    EXPECT_NEAR(r.lines[i].coherence, 1.0, 1e-9);
  }
  // Without the load torque the teeth cross the free play and the joint's own limit cycle beats with the PRBS: the
  // output no longer repeats period to period, and the coherence falls (it stays a fraction in [0, 1]).
  c.params.load_torque = 0.0;
  s.periods = 8;
  const BroadbandResponse free = measureBroadband(c, s, 0.05);
  double mean = 0.0;
  for (const BroadbandLine& l : free.lines)
  {
    EXPECT_GE(l.coherence, 0.0);
    EXPECT_LE(l.coherence, 1.0 + 1e-12);
    mean += l.coherence / static_cast<double>(free.lines.size());
  }
  EXPECT_LT(mean, 0.5);
}

TEST(BroadbandResponse, TheSetpointInjectionGivesTheSampledMechanicsWithTheLoopsClosed)
{
  // A PRBS or a chirp injected into the digital drive's torque set-point, its loops closed: the estimate from the
  // torque the drive applied to the speed at its samples is the mechanics' own sampled transfer function, whatever the
  // law — Δ = 0: ω_{k+1} = e ω_k + b u_k on the motor shaft (e = e^{−(F_T/J)T}, b = (1 − e)/F_T, J = J_m + ρ²J_L), so
  // H = b/(z − e) and ρ times it on the load, coherence 1; for a P law one sample late and a cascade. With backlash
  // and a speed offset a small injection leaves the teeth on one flank: the same estimate, to the same 1e-9.
  for (const BroadbandKind kind : {BroadbandKind::Prbs, BroadbandKind::Chirp})
  {
    for (const bool cascade : {false, true})
    {
      RunConfig c = d1(0.0);
      c.params.gear_ratio = 0.5;
      c.drive.controller_rate = 50.0;
      if (cascade)
      {
        c.drive.control_law = "cascade";
        c.drive.position_loop_gain = 2.0;
        c.drive.velocity_loop_gain = 1.5;
        c.drive.velocity_loop_integral_gain = 1.0;
      }
      else
      {
        c.drive.controller_delay = 1.0;
      }
      BroadbandSettings s;
      s.kind = kind;
      s.channel = FrfChannel::SetpointToMotorVelocity;
      s.prbs_order = 7;
      s.chirp_samples = 128;
      s.chirp_low = 0.5;
      s.chirp_high = 60.0;
      s.periods = 2;  // (settling: the automatic number of periods)
      const double jt = c.params.totalInertia(), f = c.params.totalFriction(), ts = 1.0 / 50.0;
      const double e = std::exp(-f / jt * ts), b = (1.0 - e) / f;
      const auto expected = [&](double w) { return b / (std::exp(cd(0.0, w * ts)) - e); };
      const BroadbandResponse r = measureBroadband(c, s, 0.2);
      s.channel = FrfChannel::SetpointToLoadVelocity;
      const BroadbandResponse q = measureBroadband(c, s, 0.2);
      c.params.backlash = 0.3;
      s.channel = FrfChannel::SetpointToMotorVelocity;
      s.offset = 0.5;  // [rad/s]
      const BroadbandResponse flank = measureBroadband(c, s, 0.02);
      ASSERT_GT(r.lines.size(), 40u);
      ASSERT_EQ(q.lines.size(), r.lines.size());
      ASSERT_EQ(flank.lines.size(), r.lines.size());
      double worst = 0.0;
      for (std::size_t i = 0; i < r.lines.size(); ++i)
      {
        const cd h = expected(r.lines[i].frequency);
        worst = std::max({worst, std::abs(r.lines[i].h1 - h) / std::abs(h),
                          std::abs(q.lines[i].h1 - 0.5 * h) / std::abs(0.5 * h),
                          std::abs(flank.lines[i].h1 - h) / std::abs(h)});
        EXPECT_NEAR(r.lines[i].coherence, 1.0, 1e-9);
        EXPECT_NEAR(flank.lines[i].coherence, 1.0, 1e-9);
      }
      std::printf("%s, %s: %zu lines after %d settling periods, worst relative error %.2e\n",
                  kind == BroadbandKind::Prbs ? "PRBS" : "chirp", cascade ? "cascade" : "P one sample late",
                  r.lines.size(), r.settle_periods, worst);
      EXPECT_LT(worst, 1e-9);
    }
  }
}

TEST(FrequencyResponse, ExactSineOnAPressedCompliantMeshIsTheTwoMassTransferFunction)
{
  // The sine itself (no hold): the two-mass drive's G(jω) with nothing else, on both torque channels; and the command
  // under the continuous P law, the teeth pressed by a load torque: the closed loop solved here from
  //   (J_m s² + f_m s + ρ²K_m) Θ_m + (K − ρK_m) Θ_c = K R,   −ρK_m Θ_m + (J_L s² + f_L s + K_m) Θ_c = 0,
  // K_m = c + d s the mesh at the load shaft, K the law's gain.
  RunConfig c = d1(0.1);
  c.params.gear_ratio = 0.5;
  c.params.mesh_stiffness = 100.0;
  c.params.mesh_damping = 1.0;
  const ServoParams& p = c.params;
  const double rho = p.gear_ratio;
  for (const double w : {3.0, 19.0, 45.0})
  {
    const cd jw(0.0, w);
    const cd m = p.motor_inertia * jw + p.motor_friction, l = p.load_inertia * jw + p.load_friction;
    const cd km = p.mesh_stiffness + p.mesh_damping * jw;
    for (const FrfChannel ch : {FrfChannel::TorqueToMotorVelocity, FrfChannel::TorqueToLoadVelocity})
    {
      FrfSettings s;
      s.channel = ch;
      s.continuous = true;
      s.offset = 1.0;
      s.tolerance = 1e-12;
      const FrfPoint r = measureFrequencyResponse(c, s, 0.02, w);
      ASSERT_TRUE(r.periodic) << w;
      EXPECT_EQ(r.frequency, w);
      EXPECT_EQ(r.flank_changes, 0.0);
      const cd motor = 1.0 / (m + rho * rho * km * l / (jw * l + km));
      const cd expected = ch == FrfChannel::TorqueToMotorVelocity ? motor : rho * km / (jw * l + km) * motor;
      EXPECT_LT(std::abs(r.response - expected), 1e-9 * std::abs(expected)) << toString(ch) << " " << w;
      EXPECT_LT(r.distortion, 1e-8);  // (harmonics at the rounding of the speeds)
    }
    RunConfig loop = c;
    loop.params.load_torque = -0.5;
    FrfSettings s;
    s.tolerance = 1e-13;  // (above the resonance the load barely moves: its response settles last)
    const FrfPoint r = measureFrequencyResponse(loop, s, 0.1, w);  // (the teeth stay pressed: flank_changes 0)
    ASSERT_TRUE(r.periodic) << w;
    EXPECT_EQ(r.flank_changes, 0.0);
    EXPECT_EQ(r.separations, 0.0);
    const cd s2 = jw * jw, k = p.gain;
    const cd a11 = p.motor_inertia * s2 + p.motor_friction * jw + rho * rho * km, a12 = k - rho * km;
    const cd a21 = -rho * km, a22 = p.load_inertia * s2 + p.load_friction * jw + km;
    const cd expected = -a21 * k / (a11 * a22 - a12 * a21);  // Θ_c/R by Cramer's rule
    // (Above the anti-resonance the load moves 2e-5 rad about angles near 1 rad: its response is resolved to the
    // rounding those angles carry through the run's segments, ~1e-13 rad per rad of command, 6e-9 of it at 45 rad/s.)
    EXPECT_LT(std::abs(r.response - expected), std::max(1e-9 * std::abs(expected), 1e-12)) << "command " << w;
  }
}

TEST(FrequencyResponse, ExactSinesOnRigidTeethNeedNoDryFriction)
{
  RunConfig c = d1(0.3);
  FrfSettings s;
  s.channel = FrfChannel::TorqueToMotorVelocity;
  s.continuous = true;
  EXPECT_TRUE(measureFrequencyResponse(c, s, 0.1, 1.0).periodic);
  c.params.motor_coulomb_friction = c.params.motor_static_friction = 0.01;
  EXPECT_THROW(measureFrequencyResponse(c, s, 0.1, 1.0), InvalidParameterError);
  Simulator sim(c.params, State(), 0.0);
  EXPECT_THROW(sim.setMotorTorque(0.0, Sinusoid{1.0, 1.0, 0.0, 0.0}), InvalidParameterError);
  EXPECT_THROW(sim.setCommandWave(0.0, Sinusoid{1.0, 1.0, 0.0, 0.0}), InvalidParameterError);
}

TEST(FrequencyResponse, InputHorizonIsAHintOnly)
{
  // A torque held over 1 kHz samples on the compliant D1 joint crossing its free play, with and without the hint
  // that the next change comes at the next sample: the same motion to rounding (the search windows differ, so a
  // crossing refined to its last bit may end a bit apart), and the hinted run is chunk-independent.
  RunConfig c = d1(0.1);
  c.params.mesh_stiffness = 1e4;
  c.params.mesh_damping = 4.46;
  Simulator hinted = makeSimulator(c), plain = makeSimulator(c), chunked = makeSimulator(c);
  for (int k = 0; k < 3000; ++k)
  {
    const double t = k * 1e-3, u = 2.0 * std::sin(7.0 * t);
    hinted.advanceTo(t);
    plain.advanceTo(t);
    if (k > 0)
    {
      chunked.advanceTo(t - 2e-3 / 3.0);  // the same schedule, cut in thirds
      chunked.advanceTo(t - 1e-3 / 3.0);
    }
    chunked.advanceTo(t);
    for (Simulator* s : {&hinted, &plain, &chunked})
    {
      s->setMotorTorque(u);
    }
    hinted.setInputHorizon(t + 1e-3);
    chunked.setInputHorizon(t + 1e-3);
  }
  for (Simulator* s : {&hinted, &plain, &chunked})
  {
    s->advanceTo(3.0);
  }
  EXPECT_GT(plain.contactPhases(), 4u);
  const State a = hinted.state(), b = plain.state(), d = chunked.state();
  EXPECT_NEAR(a.load_position, b.load_position, 1e-12);
  EXPECT_NEAR(a.motor_position, b.motor_position, 1e-12);
  EXPECT_NEAR(a.load_velocity, b.load_velocity, 1e-10);
  EXPECT_NEAR(a.motor_velocity, b.motor_velocity, 1e-10);
  EXPECT_EQ(a.load_position, d.load_position);
  EXPECT_EQ(a.motor_velocity, d.motor_velocity);
}

TEST(FrequencyResponse, ASineProfileUnderTheContinuousLawIsExact)
{
  // The profile path (a sine segment, then the command holds its centre) gives the motion of the command wave set
  // directly, bit for bit, and after the segment's end the loop settles at the centre; rigid teeth with dry friction
  // refuse it.
  RunConfig c = d1(0.1);
  c.params.mesh_stiffness = 1e4;
  c.params.mesh_damping = 4.46;
  ProfileSegment sine;
  sine.kind = ProfileSegment::Kind::Sine;
  sine.time = 0.0;
  sine.amplitude = 0.5;
  sine.frequency = 0.3;
  sine.duration = 10.0;
  c.profile = std::make_shared<const CommandProfile>(1.0, std::vector<ProfileSegment>{sine});
  Simulator profiled = makeSimulator(c);
  RunConfig direct_config = c;
  direct_config.profile.reset();
  direct_config.command = 1.0;
  Simulator direct = makeSimulator(direct_config);
  direct.setCommandWave(1.0, Sinusoid{0.5, 2.0 * PI * 0.3, 0.0, 0.0});
  profiled.advanceTo(9.5);
  direct.advanceTo(9.5);
  EXPECT_EQ(profiled.state().load_position, direct.state().load_position);
  EXPECT_EQ(profiled.state().motor_velocity, direct.state().motor_velocity);
  profiled.advanceTo(200.0);
  EXPECT_NEAR(profiled.state().load_position, 1.0, 0.1);  // back about the centre (the loop with backlash)
  RunConfig rigid = c;
  rigid.params.mesh_stiffness = 0.0;
  rigid.params.mesh_damping = 0.0;
  EXPECT_NO_THROW(makeSimulator(rigid));  // rigid teeth take it exactly too …
  rigid.params.motor_coulomb_friction = rigid.params.motor_static_friction = 0.01;
  EXPECT_THROW(makeSimulator(rigid), InvalidParameterError);  // … but not with dry friction
}

// A loop reading a 17-bit load encoder (a 100:1 robot joint under gravity, a 1 kHz PID): the torque-set-point
// response repeats only to within one count, which is periodic as far as the loop can tell — said so, with how much
// one period differs from the next — and its gain is the one the same joint with an ideal encoder gives (strictly
// periodic), to that spread.
TEST(FrequencyResponse, ALoopThroughAQuantisedEncoderIsPeriodicToOneCount)
{
  RunConfig c = test_helpers::quantisedRobotJoint(15.0);
  c.drive.integral_gain = 100.0;
  FrfSettings s;
  s.channel = FrfChannel::SetpointToMotorVelocity;
  for (const double w : {10.0, 100.0})
  {
    const FrfPoint q = measureFrequencyResponse(c, s, 0.05, w);
    ASSERT_TRUE(q.periodic) << w;
    EXPECT_TRUE(q.periodic_to_count) << w;
    EXPECT_LT(q.count_spread, 0.05) << w;
    RunConfig ideal = c;
    ideal.drive.load_encoder_resolution = 0.0;
    const FrfPoint exact = measureFrequencyResponse(ideal, s, 0.05, w);
    ASSERT_TRUE(exact.periodic) << w;
    EXPECT_FALSE(exact.periodic_to_count) << w;
    EXPECT_TRUE(std::isnan(exact.count_spread)) << w;
    std::printf("w %g: |H| %.6g (ideal %.6g), relative difference %.2e, count spread %.2e, periods %d (ideal %d)\n", w,
                q.gain, exact.gain, std::abs(q.response - exact.response) / std::abs(exact.response), q.count_spread,
                q.periods, exact.periods);
    EXPECT_LT(std::abs(q.response - exact.response), 0.01 * std::abs(exact.response)) << w;
  }
}

TEST(FrequencyResponse, APointKeepsToItsWorkBudgetOrIsRefusedBeforeItRuns)
{
  // The D1 joint under the continuous law: 64 points a period. Far above the joint's band the automatic settling
  // (40 slowest time constants: millions of periods) is cut to the budget; the point runs no more than that and says
  // it did not settle. Far below, one period spans more of the joint's fastest time scale than a point may follow:
  // refused at once naming the frequency and the lowest one that fits; a max_periods beyond the budget names
  // max_periods.
  const RunConfig c = d1(0.3);
  FrfSettings s;
  const FrfSampling high = frfSampling(c, s, 1e5);
  EXPECT_LE(static_cast<double>(high.max_periods) * 64.0, 5e6);
  EXPECT_GE(high.max_periods, 10);
  const FrfPoint p = measureFrequencyResponse(c, s, 0.1, 1e5);
  EXPECT_LE(p.periods, high.max_periods + 4);
  EXPECT_FALSE(p.periodic);
  try
  {
    frfSampling(c, s, 1e-300);
    ADD_FAILURE() << "accepted";
  }
  catch (const InvalidParameterError& e)
  {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind("frequency: 1e-300 rad/s", 0), 0u) << what;
    EXPECT_NE(what.find("rad/s or above"), std::string::npos) << what;
  }
  EXPECT_NO_THROW(frfSampling(c, s, 1e-3));
  RunConfig digital = c;
  digital.drive.controller_rate = 1000.0;
  s.max_periods = 10000000;
  try
  {
    frfSampling(digital, s, 1.0);
    ADD_FAILURE() << "accepted";
  }
  catch (const InvalidParameterError& e)
  {
    EXPECT_EQ(std::string(e.what()).rfind("max_periods: ", 0), 0u) << e.what();
  }
}
