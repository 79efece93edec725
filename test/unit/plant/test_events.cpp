// Event location: no event is missed (brute-force tiny-step reference), results do not depend on the caller's
// steps, Zeno sequences end in contact at the analytic accumulation time, elastic teeth do not chatter forever.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "backlash_servo/rigid/modes.h"
#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

using namespace backlash_servo;
using test_helpers::chart;
using test_helpers::Recorder;

namespace
{
/**
 * Test-only brute-force reference: classical RK4 with a tiny fixed step on the same hybrid model, impacts located
 * by bisection of the step, contact kept while the mesh torque presses. Independent of the closed forms.
 */
class BruteForce
{
 public:
  explicit BruteForce(const ServoParams& p, double command) : p_(p), command_(command) {}
  std::vector<double> impactTimes(double t_end, double dt)
  {
    std::vector<double> out;
    double x[4] = {0, 0, 0, 0};  // θ_c, ω_c, θ_m, ω_m
    bool contact = true;
    int wall = 0;  // 0 forward, 1 backward
    double t = 0.0;
    while (t < t_end)
    {
      double y[4];
      step(x, dt, contact, wall, y);
      if (contact)
      {
        const double tl = meshTorque(y);
        if ((wall == 0 && tl < 0.0) || (wall == 1 && tl > 0.0))
        {
          contact = false;
        }
      }
      else
      {
        const double g = y[0] - p_.gear_ratio * y[2];
        if (g < 0.0 || g > p_.backlash)
        {
          // Bisect the step length for the crossing.
          const double level = g < 0.0 ? 0.0 : p_.backlash;
          double lo = 0.0, hi = dt;
          for (int i = 0; i < 60; ++i)
          {
            const double mid = 0.5 * (lo + hi);
            double z[4];
            step(x, mid, false, wall, z);
            const double gm = z[0] - p_.gear_ratio * z[2];
            ((level == 0.0) ? (gm < 0.0) : (gm > level)) ? hi = mid : lo = mid;
          }
          step(x, hi, false, wall, y);
          t += hi;
          out.push_back(t);
          wall = level == 0.0 ? 0 : 1;
          y[2] = (y[0] - level) / p_.gear_ratio;
          const double rho = p_.gear_ratio, jm = p_.motor_inertia, jl = p_.load_inertia, e = p_.restitution;
          const double v = y[1], w = y[3];
          const double vn = jm / (jm + rho * rho * jl) * (rho * w * (1 + e) + v * (rho * rho * jl / jm - e));
          y[1] = vn;
          y[3] = (vn - e * (rho * w - v)) / rho;
          // Below the reference's resolution a bounce is treated as sticking (contact kept while it presses).
          if (std::fabs(rho * y[3] - y[1]) < 1e-5)
          {
            y[3] = y[1] / rho;
            contact = true;
          }
          std::copy(y, y + 4, x);
          continue;
        }
      }
      std::copy(y, y + 4, x);
      t += dt;
    }
    return out;
  }

 private:
  double meshTorque(const double* s) const
  {
    const double acc = (p_.gear_ratio * p_.gain * (command_ - s[0]) - p_.totalFriction() * s[1]) / p_.totalInertia();
    return p_.load_inertia * acc + p_.load_friction * s[1];
  }
  void deriv(const double* s, bool contact, double* d) const
  {
    const double tm = p_.gain * (command_ - s[0]);
    if (contact)
    {
      const double acc = (p_.gear_ratio * tm - p_.totalFriction() * s[1]) / p_.totalInertia();
      d[0] = s[1];
      d[1] = acc;
      d[2] = s[1] / p_.gear_ratio;
      d[3] = acc / p_.gear_ratio;
      return;
    }
    d[0] = s[1];
    d[1] = -p_.load_friction * s[1] / p_.load_inertia;
    d[2] = s[3];
    d[3] = (tm - p_.motor_friction * s[3]) / p_.motor_inertia;
  }
  void step(const double* x, double h, bool contact, int wall, double* y) const
  {
    double k1[4], k2[4], k3[4], k4[4], s[4];
    deriv(x, contact, k1);
    for (int i = 0; i < 4; ++i)
      s[i] = x[i] + 0.5 * h * k1[i];
    deriv(s, contact, k2);
    for (int i = 0; i < 4; ++i)
      s[i] = x[i] + 0.5 * h * k2[i];
    deriv(s, contact, k3);
    for (int i = 0; i < 4; ++i)
      s[i] = x[i] + h * k3[i];
    deriv(s, contact, k4);
    for (int i = 0; i < 4; ++i)
      y[i] = x[i] + h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
    if (contact)
    {
      y[2] = (y[0] - (wall == 0 ? 0.0 : p_.backlash)) / p_.gear_ratio;
    }
  }
  ServoParams p_;
  double command_;
};

}  // namespace

TEST(Events, NoImpactMissedAgainstTinyStepReference)
{
  // Cases with well-separated impacts (the reference cannot resolve Zeno tails).
  for (const ServoParams& p : {chart(0.4, 1.0, 0.4, 0.6), chart(0.2, 4.0, 0.4, 0.8), chart(0.3, 0.25, 0.2, 0.0)})
  {
    Recorder rec;
    Simulator sim(p, State(), 1.0);
    sim.advanceTo(20.0, &rec);
    const std::vector<double> ours = rec.times(EventType::Impact);
    const std::vector<double> ref = BruteForce(p, 1.0).impactTimes(20.0, 1e-4);
    ASSERT_GT(ours.size(), 2u);
    // Compare every impact of the reference that is not part of a sub-step chatter burst.
    std::size_t j = 0;
    for (double tr : ref)
    {
      while (j < ours.size() && ours[j] < tr - 1e-3)
      {
        ++j;
      }
      ASSERT_LT(j, ours.size()) << "reference impact at " << tr << " s has no counterpart";
      EXPECT_NEAR(ours[j], tr, 1e-3) << "reference impact at " << tr;
    }
    // And ours are all seen by the reference, down to its resolution (closing speed 1e-3 rad/s).
    for (const Event& ev : rec.events)
    {
      if (ev.type != EventType::Impact || ev.impact.approach_speed < 1e-3)
      {
        continue;
      }
      const double to = ev.state.time;
      double best = 1e9;
      for (double tr : ref)
      {
        best = std::min(best, std::fabs(tr - to));
      }
      EXPECT_LT(best, 1e-3) << "impact at " << to << " s not in the reference";
    }
  }
}

TEST(Events, ResultsDoNotDependOnTheCallersSteps)
{
  const ServoParams p;  // thesis limit-cycle case, e = 1
  Recorder one, fine, ragged;
  Simulator a(p, State(), 1.0), b(p, State(), 1.0), c(p, State(), 1.0);
  a.advanceTo(150.0, &one);
  for (int i = 1; i <= 15000; ++i)
  {
    b.advanceTo(0.01 * i, &fine);
  }
  double t = 0.0;
  unsigned seed = 7;
  while (t < 150.0)
  {
    seed = seed * 1664525u + 1013904223u;
    t = std::min(150.0, t + 1e-6 + (seed >> 8) % 1000 * 1e-3);
    c.advanceTo(t, &ragged);
  }
  const auto m1 = one.times(EventType::Maximum), m2 = fine.times(EventType::Maximum),
             m3 = ragged.times(EventType::Maximum);
  ASSERT_EQ(m1.size(), m2.size());
  ASSERT_EQ(m1.size(), m3.size());
  for (std::size_t i = 0; i < m1.size(); ++i)
  {
    EXPECT_NEAR(m1[i], m2[i], 1e-9);
    EXPECT_NEAR(m1[i], m3[i], 1e-9);
  }
  EXPECT_EQ(a.impactCount(), b.impactCount());
  EXPECT_EQ(a.impactCount(), c.impactCount());
  EXPECT_NEAR(a.state().load_position, b.state().load_position, 1e-9);
  EXPECT_NEAR(a.state().load_position, c.state().load_position, 1e-9);
}

TEST(Events, ASinkThatSkipsImpactsGetsEveryOtherEventBitForBit)
{
  // Elastic chatter with maxima at impacts (a light load rattling: e = 1, ρ²J_L/J_m = 0.04) and a Zeno case with
  // separations: a sink that does not want impacts gets none, and every other event — maxima at impacts included —
  // and the final state exactly as a sink that takes everything.
  struct NoImpacts : Recorder
  {
    bool wantsImpacts() const override { return false; }
  };
  int at_impacts = 0;  // maxima where an impact turned the load round
  for (const ServoParams& p : {chart(0.5, 0.04, 1.0, 1.0), chart(0.4, 9.0, 0.4, 0.8)})
  {
    Recorder all;
    NoImpacts some;
    Simulator a(p, State(), 1.0), b(p, State(), 1.0);
    a.advanceTo(25.0, &all);
    b.advanceTo(25.0, &some);
    ASSERT_GT(all.of(EventType::Impact).size(), 100u);
    EXPECT_TRUE(some.of(EventType::Impact).empty());
    std::vector<Event> rest;
    for (const Event& e : all.events)
    {
      if (e.type != EventType::Impact)
      {
        rest.push_back(e);
      }
    }
    ASSERT_EQ(rest.size(), some.events.size());
    ASSERT_GE(all.of(EventType::Maximum).size(), 3u);
    const std::vector<double> impacts = all.times(EventType::Impact);
    for (double t : all.times(EventType::Maximum))
    {
      at_impacts += std::binary_search(impacts.begin(), impacts.end(), t);
    }
    for (std::size_t i = 0; i < rest.size(); ++i)
    {
      EXPECT_EQ(rest[i].type, some.events[i].type) << i;
      EXPECT_EQ(rest[i].state.time, some.events[i].state.time) << i;
      EXPECT_EQ(rest[i].state.load_position, some.events[i].state.load_position) << i;
      EXPECT_EQ(rest[i].state.load_velocity, some.events[i].state.load_velocity) << i;
    }
    EXPECT_EQ(a.impactCount(), b.impactCount());
    EXPECT_EQ(a.state().motor_position, b.state().motor_position);
    EXPECT_EQ(a.state().motor_velocity, b.state().motor_velocity);
  }
  EXPECT_GT(at_impacts, 0);
}

TEST(Events, ZenoBouncesEndInContactAtTheAnalyticAccumulationTime)
{
  for (double e : {0.5, 0.8})
  {
    // Frictionless, effort mode: relative acceleration of the gap is −ρu/J_m while apart, so after a first impact
    // with closing speed s the bounces last Σ 2 eⁿ s / a = 2 e s / (a (1 − e)).
    ServoParams p;
    p.motor_inertia = 1.0;
    p.load_inertia = 1.0;
    p.motor_friction = 0.0;
    p.load_friction = 0.0;
    p.gear_ratio = 1.0;
    p.backlash = 0.1;
    p.restitution = e;
    State s;
    s.contact = Contact::Apart;
    s.motor_position = -0.05;  // gap 0.05
    Simulator sim(p, s, 0.0);
    const double u = 1.0;
    sim.setMotorTorque(u);
    Recorder rec;
    const double t1 = std::sqrt(0.1);  // 0.05 = a t²/2 with a = 1
    const double closing = t1;
    const double t_zeno = t1 + 2.0 * e * closing / (1.0 - e);
    sim.advanceTo(t_zeno + 1.0, &rec);
    const auto impacts = rec.times(EventType::Impact);
    EXPECT_NEAR(impacts.front(), t1, 1e-12);
    // The stick rule ends the sequence once a bounce could not rise above the gap's rounding (~1e-7 rad/s here),
    // cutting a tail of at most 2 v_stick / (a (1 − e)) ≈ 1e-5 s.
    EXPECT_LE(impacts.back(), t_zeno + 1e-12);
    EXPECT_NEAR(impacts.back(), t_zeno, 2e-5);
    EXPECT_LT(impacts.size(), 200u);
    EXPECT_EQ(sim.state().contact, Contact::Forward);
    // Afterwards one body: total momentum u t shared, v = u t / (J_m + ρ² J_L).
    EXPECT_NEAR(sim.state().load_velocity, u * (t_zeno + 1.0) / 2.0, 1e-9);
    EXPECT_LT(std::fabs(sim.energyBalanceError()), 1e-9 * sim.energy().input);
  }
}

TEST(Events, ElasticTeethUnderPressingTorqueDoNotChatter)
{
  ServoParams p;
  p.restitution = 1.0;
  Simulator sim(p, State(), 0.0);
  sim.setMotorTorque(0.7);  // presses the forward wall from rest
  sim.advanceTo(50.0);
  EXPECT_EQ(sim.impactCount(), 0u);
  EXPECT_EQ(sim.state().contact, Contact::Forward);
  // A numerically zero closing speed on arrival sticks instead of starting endless micro-bounces.
  State s;
  s.contact = Contact::Apart;
  s.load_velocity = 0.0;
  s.motor_velocity = 1e-13;
  Simulator touch(p, s, 0.0);
  touch.setMotorTorque(0.7);
  touch.advanceTo(10.0);
  EXPECT_LE(touch.impactCount(), 1u);
  EXPECT_EQ(touch.state().contact, Contact::Forward);
}

TEST(Events, ZenoHeavyAndElasticStepResponsesTerminate)
{
  for (double e : {0.5, 0.8, 1.0})
  {
    for (double zeta : {0.1, 0.4})
    {
      RunConfig c;
      c.params = chart(zeta, 9.0, 0.4, e);
      c.duration = 500.0;
      const RunSummary r = runResponse(c);
      EXPECT_DOUBLE_EQ(r.final_state.time, 500.0);
      EXPECT_LT(r.impacts, 100000u);
    }
  }
}

TEST(Events, SeparationHappensWhereTheMeshTorqueChangesSign)
{
  const ServoParams p = chart(0.4, 9.0, 0.4, 1.0);
  Recorder rec;
  Simulator sim(p, State(), 1.0);
  sim.advanceTo(30.0, &rec);
  int checked = 0;
  for (const Event& e : rec.events)
  {
    if (e.type != EventType::Separation || e.state.time == 0.0)
    {
      continue;
    }
    // Just before, the contact mesh torque was on the pressing side; at the event it is zero.
    const MotorInput in{p.gain * 1.0, p.gain};
    const double tl = contactMeshTorque(p, in, e.state.load_position, e.state.load_velocity);
    EXPECT_NEAR(tl, 0.0, 1e-12) << "separation at " << e.state.time;
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(Events, RoundingLevelPenetrationAfterSeparationDoesNotStall)
{
  // Regression: at t ≈ 58.2487 s this point separated with the gap at −7e-17 rad (rounding of θ_c − ρθ_m ≈ 1.3 − 1.3)
  // and the merged coefficients' bound (6e-17) called it a penetration at τ = 0 again and again.
  RunConfig c;
  c.params = chart(0.2, 0.04, 1.0, 0.8);
  c.duration = 120.0;
  const RunSummary r = runResponse(c);
  EXPECT_DOUBLE_EQ(r.final_state.time, 120.0);
  EXPECT_LT(std::fabs(r.balance_error), 1e-9 * r.energy.input);
  RunConfig settle = c;
  settle.duration = 0.0;
  EXPECT_EQ(runResponse(settle).status.verdict, Verdict::LimitCycle);
}

// A state set apart on a wall with the teeth closing collides at once: slow, light motions
// penetrate the wall by less than the rounding bound of their closed forms, so the search alone missed the impact
// and the gap ran to −6e-12 rad before a rest. Truth: the impact is at t = 0 with the initial closing speed
// ρω_m − ω_c (e = 0: the teeth then move together), and the gap never leaves [0, Δ] afterwards. With and without
// dry friction, on both walls.
TEST(Events, AStartOnAWallWithTheTeethClosingCollidesAtOnce)
{
  for (bool dry : {true, false})
  {
    for (Contact side : {Contact::Forward, Contact::Backward})
    {
      ServoParams p;
      p.motor_inertia = 0.0057774582019258763;
      p.load_inertia = 0.017059847633572687;
      p.motor_friction = 6.9150430185100522e-07;
      p.load_friction = 0.00033017955136067033;
      p.gain = 1.0933114040029365e-06;
      p.gear_ratio = 0.073468162407119203;
      p.backlash = 0.0031987871432082129;
      p.restitution = 0.0;
      if (dry)
      {
        p.motor_coulomb_friction = p.motor_static_friction = 2.5364334251130444e-07;
        p.load_coulomb_friction = 7.7876648399855584e-08;
        p.load_static_friction = 1.1681497259978338e-07;
      }
      State s;
      s.contact = Contact::Apart;
      s.load_velocity = 3.4556385326083573e-08;
      s.motor_velocity = 1.1872099363839593e-06;  // ρω_m = 8.7e-8 rad/s: the motor catches up with the load
      const GearMesh mesh(p);
      s.motor_position = mesh.motorPosition(0.0, side == Contact::Forward ? 0.0 : p.backlash);
      if (side == Contact::Backward)
      {
        s.load_velocity = 1.1872099363839593e-06 * p.gear_ratio;  // the load runs into the motor's backward flank
        s.motor_velocity = 3.4556385326083573e-08 / p.gear_ratio;
      }
      const double closing = mesh.closingSpeed(side, s.load_velocity, s.motor_velocity);
      ASSERT_GT(closing, 0.0);
      Simulator sim(p, s, -15.711913504728198);
      test_helpers::Recorder rec;
      double worst = 0.0;
      for (int i = 1; i <= 200; ++i)
      {
        sim.advanceTo(0.01 * i, &rec);
        const double g = sim.gap();
        worst = std::max({worst, -g, g - p.backlash});
      }
      const std::vector<Event> impacts = rec.of(EventType::Impact);
      ASSERT_FALSE(impacts.empty()) << "dry " << dry << " side " << static_cast<int>(side);
      EXPECT_EQ(impacts.front().state.time, 0.0);
      EXPECT_NEAR(impacts.front().impact.approach_speed, closing, 1e-12 * closing);
      EXPECT_EQ(impacts.front().impact.wall, side);
      for (const Event& e : rec.events)
      {
        const double g = mesh.gap(e.state.load_position, e.state.motor_position);
        worst = std::max({worst, -g, g - p.backlash});
      }
      EXPECT_LE(worst, 1e-15) << "dry " << dry << " side " << static_cast<int>(side);
    }
  }
}

// A light load under huge torques (J_L 1e-6 kg·m², 8e4 N·m of Coulomb friction, a 3e5 N·m load torque: 1e11 rad/s²)
// stops within 5e-12 s. Its closed form θ_c = c − c e^{−ατ} + v_∞τ has c ≈ 2e8 rad for a motion of 1e-11 rad: the
// direct evaluation put the load 2.5e-7 rad past the wall at its rest. Positions of such forms are
// the start plus an expm1-based increment. Truth: the kinematics of the first 5e-12 s — the gap moves by
// (ω_c − ρω_m)τ ≈ −2.4e-11 rad, i.e. stays inside [0, Δ] to 1e-12 of the position scale at every event.
TEST(Events, AClosedFormWithHugeTermsKeepsTheGapExact)
{
  ServoParams p;
  p.motor_inertia = 0.00016740080468400991;
  p.load_inertia = 1.0070088631139422e-06;
  p.motor_friction = 6.0165511942545076e-05;
  p.load_friction = 4.4253544288056484e-05;
  p.gain = 3.9902573063468636;
  p.gear_ratio = 0.60672683800376337;
  p.backlash = 1.1514120781005301;
  p.restitution = 0.0;
  p.load_torque = -327328.20665273757;
  p.motor_coulomb_friction = 71.957810780712876;
  p.motor_static_friction = 215.87343234213864;
  p.load_coulomb_friction = p.load_static_friction = 81835.422790512544;
  State s;
  s.contact = Contact::Apart;
  s.load_velocity = 2.1423835322335676;
  s.motor_position = -1.897743771956546;
  s.motor_velocity = 11.107679787037464;
  Simulator sim(p, s, -46906.764636574728);
  test_helpers::Recorder rec;
  sim.setEventBudget(100000);
  sim.advanceTo(0.05, &rec);
  const GearMesh mesh(p);
  ASSERT_FALSE(rec.events.empty());
  for (const Event& e : rec.events)
  {
    const double g = mesh.gap(e.state.load_position, e.state.motor_position);
    const double tol =
        1e-12 * (std::fabs(e.state.load_position) + p.gear_ratio * std::fabs(e.state.motor_position) + p.backlash);
    EXPECT_GE(g, -tol) << toString(e.type) << " at " << e.state.time;
    EXPECT_LE(g, p.backlash + tol) << toString(e.type) << " at " << e.state.time;
  }
  // The load's first stop: within 5e-12 s, having moved ω_c τ/2-ish ≈ 5e-12 rad, not 2.5e-7.
  const Event& first = rec.events.front();
  EXPECT_LT(first.state.time, 1e-11);
  EXPECT_LT(std::fabs(first.state.load_position), 1e-10);
}
