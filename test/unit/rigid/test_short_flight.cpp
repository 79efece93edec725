// The chatter fast path (short_flight.h) against independent truth: the apart mode's closed form written out in
// long double (64-bit mantissa, ~2000x finer than double) with its return to the wall bisected in long double, the
// energy balance of each flight, and whole chatter runs with the fast path off (closed form everywhere).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <random>

#include "backlash_servo/plant/plant.h"
#include "backlash_servo/rigid/modes.h"
#include "backlash_servo/rigid/short_flight.h"
#include "backlash_servo/simulation/step_response.h"
#include "test_helpers.h"

using namespace backlash_servo;

namespace
{
constexpr double EPS = std::numeric_limits<double>::epsilon();

/// The apart mode's solution for α ≠ β, both > 0, in long double (as modes.h derives it; a load torque T_ext makes
/// ω_c relax to ω∞ = T_ext/f_L and adds a line to the motor's forcing).
struct ReferenceFlight
{
  long double alpha, beta, rho, x0, v0, m0, w0, a_over_j, k_over_j, v_inf;
  ReferenceFlight(const ServoParams& p, const MotorInput& in, const State& s)
      : alpha(static_cast<long double>(p.load_friction) / p.load_inertia),
        beta(static_cast<long double>(p.motor_friction) / p.motor_inertia),
        rho(p.gear_ratio),
        x0(s.load_position),
        v0(s.load_velocity),
        m0(s.motor_position),
        w0(s.motor_velocity),
        a_over_j(static_cast<long double>(in.offset) / p.motor_inertia),
        k_over_j(static_cast<long double>(in.stiffness) / p.motor_inertia),
        v_inf(static_cast<long double>(p.load_torque) / p.load_friction)
  {}
  /// θ_c = x0 + ω∞τ + c(1 − e^{−ατ}), c = (v0 − ω∞)/α; ω_m' + βω_m = f0 + f_l τ + f1 e^{−ατ}.
  void at(long double tau, long double* xc, long double* vc, long double* xm, long double* vm) const
  {
    const long double ea = std::exp(-alpha * tau), eb = std::exp(-beta * tau);
    const long double c = (v0 - v_inf) / alpha;
    *xc = x0 + v_inf * tau - c * std::expm1(-alpha * tau);
    *vc = v_inf + (v0 - v_inf) * ea;
    // a − kθ_c = (a − k(x0 + c)) − k ω∞ τ + k c e^{−ατ}
    const long double f0 = a_over_j - k_over_j * (x0 + c), fl = -k_over_j * v_inf, f1 = k_over_j * c;
    const long double b1 = fl / beta, b0 = (f0 - b1) / beta, q1 = f1 / (beta - alpha), q2 = w0 - b0 - q1;
    *vm = b0 + b1 * tau + q1 * ea + q2 * eb;
    *xm = m0 + b0 * tau + 0.5L * b1 * tau * tau - q1 * std::expm1(-alpha * tau) / alpha -
          q2 * std::expm1(-beta * tau) / beta;
  }
  long double gap(long double tau) const
  {
    long double xc, vc, xm, vm;
    at(tau, &xc, &vc, &xm, &vm);
    return xc - rho * xm;
  }
};

/// The apart mode's velocities as their full Taylor series in long double (40 terms: with M·τ ≤ 0.1 the rest is
/// below 1e-40 of the first): free of the cancellations of the closed form's large e^{−ατ}, e^{−βτ} coefficients,
/// and of the fast path's order choice, bounds and certification.
struct ReferenceSeries
{
  static constexpr int TERMS = 40;
  long double vc[TERMS + 1], vm[TERMS + 1];
  ReferenceSeries(const ServoParams& p, const MotorInput& in, const State& s)
  {
    const long double alpha = static_cast<long double>(p.load_friction) / p.load_inertia;
    const long double beta = static_cast<long double>(p.motor_friction) / p.motor_inertia;
    const long double k = static_cast<long double>(in.stiffness) / p.motor_inertia;
    long double xc = s.load_position;
    vc[0] = s.load_velocity;
    vm[0] = s.motor_velocity;
    // k = 0 → 1 with the constant inputs, then y_{k+1} = A y_k/(k+1).
    vc[1] = static_cast<long double>(p.load_torque) / p.load_inertia - alpha * vc[0];
    vm[1] = static_cast<long double>(in.offset) / p.motor_inertia - k * xc - beta * vm[0];
    xc = vc[0];  // θ_c's coefficient of order 1
    for (int n = 1; n < TERMS; ++n)
    {
      const long double next_xc = vc[n] / (n + 1);
      vc[n + 1] = -alpha * vc[n] / (n + 1);
      vm[n + 1] = (-k * xc - beta * vm[n]) / (n + 1);
      xc = next_xc;
    }
  }
  long double velocity(bool motor, long double tau) const
  {
    const long double* c = motor ? vm : vc;
    long double v = 0.0L;
    for (int n = TERMS; n >= 0; --n)
    {
      v = v * tau + c[n];
    }
    return v;
  }
};

struct Draw
{
  ServoParams params;
  MotorInput law;
  State start;
  bool forward = true;  // the wall the teeth leave
};

/// A state on a wall just after an impact: the teeth separating at `speed` [rad/s], the law pressing them back or
/// not (builds that fail are skipped by the caller).
Draw drawFlight(std::mt19937_64& rng)
{
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto logUniform = [&](double lo, double hi) { return lo * std::pow(hi / lo, u(rng)); };
  Draw d;
  // Half the draws with a small backlash: flights across to the other wall.
  const double delta = u(rng) < 0.5 ? 0.3 : logUniform(1e-7, 1e-2);
  d.params = test_helpers::chart(0.1 + 0.9 * u(rng), logUniform(0.01, 100.0), 0.05 + 0.9 * u(rng), u(rng), delta,
                                 logUniform(0.1, 10.0), logUniform(0.5, 2.0));
  const double gain = d.params.gain;
  d.law.stiffness = gain;
  d.law.offset = gain * (4.0 * u(rng) - 2.0);
  const double rho = d.params.gear_ratio;
  const bool forward = d.forward = u(rng) < 0.5;
  d.start.contact = Contact::Apart;
  d.start.load_position = 4.0 * u(rng) - 2.0;
  d.start.motor_position = (d.start.load_position - (forward ? 0.0 : d.params.backlash)) / rho;
  d.start.motor_velocity = 2.0 * u(rng) - 1.0;
  const double speed = logUniform(1e-7, 1e-1);
  d.start.load_velocity = rho * d.start.motor_velocity + (forward ? speed : -speed);
  return d;
}
}  // namespace

TEST(ShortFlight, AgreesWithTheLongDoubleClosedFormToRounding)
{
  std::mt19937_64 rng(20261125);
  int taken = 0, returns = 0, crossings = 0;
  double worst_time = 0.0, worst_closed_form = 0.0, worst_state = 0.0, worst_energy = 0.0;
  for (int i = 0; i < 8000 && taken < 600; ++i)
  {
    const Draw d = drawFlight(rng);
    ShortFlight f;
    const double horizon = 0.5 * 2.0 * M_PI / std::sqrt(d.params.gain / d.params.totalInertia());
    if (!f.build(d.params, d.law, d.start, horizon))
    {
      continue;
    }
    ++taken;
    const ReferenceFlight ref(d.params, d.law, d.start);
    const long double level = d.forward ? 0.0L : static_cast<long double>(d.params.backlash);
    const long double sign = d.forward ? 1.0L : -1.0L;
    const long double delta = d.params.backlash;
    // F = sign·(g − level) > 0 in the free space: the flight ends where F comes back to 0 after rising (the same
    // wall) or reaches Δ (the other wall) — the first of the two on a fine scan, then bisected.
    auto F = [&](long double tau) { return sign * (ref.gap(tau) - level); };
    const double t = f.impactTime();
    long double a = 0.0L, b = 0.0L;
    bool risen = false, across = false;
    for (int k = 1; k <= 4000; ++k)
    {
      const long double tau = 3.0L * t * k / 4000.0L;
      const long double fk = F(tau);
      if (fk >= delta)
      {
        across = true;
        b = tau;
        break;
      }
      if (fk > 0.0L)
      {
        risen = true;
        a = tau;
      }
      else if (risen)
      {
        b = tau;
        break;
      }
    }
    ASSERT_GT(b, 0.0L) << "case " << i << ": the reference flight does not end; flight " << t << " s";
    const Contact start_wall = d.forward ? Contact::Forward : Contact::Backward;
    const Contact other_wall = d.forward ? Contact::Backward : Contact::Forward;
    EXPECT_EQ(f.wall(), across ? other_wall : start_wall) << "case " << i;
    (across ? crossings : returns) += 1;
    for (int it = 0; it < 200; ++it)
    {
      const long double mid = 0.5L * (a + b);
      const bool before = across ? F(mid) < delta : F(mid) > 0.0L;
      (before ? a : b) = mid;
    }
    const long double t_ref = 0.5L * (a + b);
    // Tolerance: the rounding of the gap (positions) over the closing speed, plus a few ε of the time.
    const double position_scale =
        std::fabs(d.start.load_position) + d.params.gear_ratio * std::fabs(d.start.motor_position) + d.params.backlash;
    const long double h = 1e-6L * t_ref;
    const double speed = static_cast<double>(std::fabs(F(t_ref + h) - F(t_ref - h)) / (2.0L * h));  // at the wall
    const double tol = 64.0 * EPS * position_scale / speed + 16.0 * EPS * t;
    const double err = static_cast<double>(std::fabs(t - t_ref));
    EXPECT_LE(err, tol) << "case " << i << " flight " << t << " s";
    worst_time = std::max(worst_time, err / tol);
    // The double closed form's own error on the same flight, for the record.
    FreeMotion closed(d.params, d.law, d.start, horizon);
    Contact wall;
    const double t_closed = closed.impactTime(horizon, &wall);
    worst_closed_form = std::max(worst_closed_form, static_cast<double>(std::fabs(t_closed - t_ref)) / tol);
    // The state at the impact against the reference at the same instant.
    State s;
    f.at(t, &s);
    long double xc, vc, xm, vm;
    ref.at(t, &xc, &vc, &xm, &vm);
    const double velocity_scale = std::fabs(d.start.load_velocity) + std::fabs(d.start.motor_velocity) + 1e-3;
    const double state_err = std::max({static_cast<double>(std::fabs(s.load_position - xc)) / position_scale,
                                       static_cast<double>(std::fabs(s.motor_position - xm)) / position_scale,
                                       static_cast<double>(std::fabs(s.load_velocity - vc)) / velocity_scale,
                                       static_cast<double>(std::fabs(s.motor_velocity - vm)) / velocity_scale}) /
                             EPS;
    EXPECT_LE(state_err, 8.0) << "case " << i;
    worst_state = std::max(worst_state, state_err);
    // Energy balance of the flight: ΔKE = input − frictions (no impact inside it).
    const EnergyFlows e = f.energy(t);
    const double rho = d.params.gear_ratio;
    auto kinetic = [&](const State& x) {
      return 0.5 * d.params.load_inertia * x.load_velocity * x.load_velocity +
             0.5 * d.params.motor_inertia * x.motor_velocity * x.motor_velocity;
    };
    const double balance = kinetic(s) - kinetic(d.start) - (e.input - e.motor_friction - e.load_friction);
    const double energy_scale = kinetic(d.start) + std::fabs(e.input) + e.motor_friction + e.load_friction +
                                std::fabs(d.law.torque(d.start.load_position)) * position_scale / rho;
    EXPECT_LE(std::fabs(balance), 64.0 * EPS * energy_scale) << "case " << i;
    worst_energy = std::max(worst_energy, std::fabs(balance) / (EPS * energy_scale));
  }
  EXPECT_GE(returns, 200);
  EXPECT_GE(crossings, 100);
  std::printf(
      "short flights: %d cases (%d back to the wall, %d across); worst impact time error %.3g of the "
      "tolerance (the double closed form: %.3g); state %.3g eps; energy balance %.3g eps\n",
      taken, returns, crossings, worst_time, worst_closed_form, worst_state, worst_energy);
}

namespace
{
/// A continuous P law run (θ_R = 1 rad from rest) for `duration` [s], the fast path on or off; maxima of θ_c to
/// *maxima.
std::unique_ptr<Plant> runChatter(const ServoParams& params, bool short_flights, double duration,
                                  std::vector<Event>* maxima)
{
  MotorInput law;
  law.stiffness = params.gain;
  law.offset = params.gain * 1.0;
  auto plant = std::make_unique<Plant>(params, State(), law);
  plant->setShortFlights(short_flights);
  test_helpers::Recorder rec;
  plant->advanceTo(duration, &rec);
  *maxima = rec.of(EventType::Maximum);
  return plant;
}

/// The maxima of θ_c of two runs agree: as many, at least two, each to 1e-9 rad and 1e-8 s.
void expectSameMaxima(const std::vector<Event>& with, const std::vector<Event>& without)
{
  ASSERT_EQ(with.size(), without.size());
  ASSERT_GE(with.size(), 2u);
  for (std::size_t i = 0; i < with.size(); ++i)
  {
    EXPECT_NEAR(with[i].state.load_position, without[i].state.load_position, 1e-9) << "maximum " << i;
    EXPECT_NEAR(with[i].state.time, without[i].state.time, 1e-8) << "maximum " << i;
  }
}
}  // namespace

TEST(ShortFlight, ChatterRunsAgreeWithTheClosedFormEverywhere)
{
  // The thesis grid's costliest point (ζ = 0.8, ρ²J_L/J_m = 0.04, all friction on the load, e = 1): a light load
  // rattling against the motor ~35 000 times per simulated second; and a plastic-ish e = 0.6 case.
  for (const ServoParams& p : {test_helpers::chart(0.8, 0.04, 1.0, 1.0), test_helpers::chart(0.5, 0.04, 0.8, 0.6)})
  {
    std::vector<Event> with, without;
    const std::unique_ptr<Plant> fast = runChatter(p, true, 25.0, &with);
    const std::unique_ptr<Plant> slow = runChatter(p, false, 25.0, &without);
    const std::uint64_t fast_impacts = fast->impactCount(), flights = fast->shortFlightCount();
    EXPECT_EQ(slow->shortFlightCount(), 0u);
    EXPECT_GT(flights, fast_impacts / 2) << "the fast path was hardly used";
    expectSameMaxima(with, without);
    EXPECT_LE(std::fabs(fast->energyBalanceError()), 1e-12 * fast->energy().input);
    EXPECT_LE(std::fabs(slow->energyBalanceError()), 1e-12 * slow->energy().input);
    std::printf("chatter e = %.1f: %llu impacts (%llu short flights) vs %llu with the closed form\n", p.restitution,
                static_cast<unsigned long long>(fast_impacts), static_cast<unsigned long long>(flights),
                static_cast<unsigned long long>(slow->impactCount()));
  }
}

TEST(ShortFlight, AFlightShorterThanTheClockIsLeftToTheClosedForm)
{
  // Regression: a heavy, slow joint at rest to ~1e-40 rad/s on a wall at t ≈ 5568 s; a "flight" of the
  // teeth there lasts less than an ulp of the clock and looped without advancing time. It is the closed form's.
  RunConfig c;
  c.params.motor_inertia = 0.1353220952460959;
  c.params.load_inertia = 452410.49684263207;
  c.params.motor_friction = 0.029472619056328284;
  c.params.load_friction = 17480.744184480591;
  c.params.gain = 0.34508804219038375;
  c.params.gear_ratio = 0.0015582381501891426;
  c.params.backlash = 1.2285908981316866;
  c.params.restitution = 0.13076007930694492;
  c.command = -63.901033223641178;
  c.initial.contact = Contact::Forward;
  c.initial.load_position = -82.176558081743266;
  c.initial.load_velocity = -1.2336954810232209e-06;
  c.initial.motor_position = -52736.841330555595;
  c.initial.motor_velocity = -0.00079172460311889559;
  c.duration = 6019.4164035323556;
  RunSummary with, without;
  ASSERT_NO_THROW(with = runResponse(c, nullptr));
  c.short_flights = false;
  ASSERT_NO_THROW(without = runResponse(c, nullptr));
  EXPECT_EQ(with.status.verdict, without.status.verdict);
  EXPECT_NEAR(with.final_state.load_position, without.final_state.load_position, 1e-9);
}

TEST(ShortFlight, AZenoSequenceUnderALoadTorqueEnds)
{
  // Regression: a light load (0.018 kg·m²) pressed onto the motor by a 1966 N·m load torque bounces with
  // e = 0.91 — a Zeno sequence: the bounce speeds fall by e per impact, so from the first bounce (~0.1 rad/s) to the
  // stick rule's floor (~1e-8 rad/s) it takes ~log(1e-7)/log(e) ≈ 175 impacts, and the teeth then stay in contact.
  // The closed form's flight times blur at these scales and it ran into an impact storm (the event budget).
  ServoParams p;
  p.motor_inertia = 11.455467237803855;
  p.load_inertia = 0.017811151141035708;
  p.motor_friction = 0.043660632886314006;
  p.load_friction = 0.25636777675638511;
  p.gain = 14484.597308214459;
  p.backlash = 0.0088220795059651552;
  p.restitution = 0.9124706047265817;
  p.load_torque = 1965.7241299690593;
  State s;
  s.contact = Contact::Apart;
  s.load_position = s.motor_position = -0.048483557636273857;
  s.load_velocity = 2.7293263088460525e-06;
  s.motor_velocity = 5.5821290370738982e-06;
  MotorInput law;
  law.stiffness = p.gain;
  law.offset = p.gain * -0.080380605444080128;
  Plant plant(p, s, law);
  plant.setEventBudget(100000);
  ASSERT_NO_THROW(plant.advanceTo(0.5, nullptr));
  EXPECT_NE(plant.state().contact, Contact::Apart);
  EXPECT_GT(plant.impactCount(), 50u);
  EXPECT_LT(plant.impactCount(), 1000u);
  EXPECT_GT(plant.shortFlightCount(), plant.impactCount() / 2);
}

TEST(ShortFlight, DryFrictionRestTimesAgreeWithTheLongDoubleSeries)
{
  // Both bodies sliding apart under dry friction: the kinetic friction folded into constant torques (a load torque,
  // a motor offset). A body decelerating towards rest during the flight: its rest time on the series against the
  // velocities' full series in long double, scanned and bisected.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int rests = 0, none = 0, uncertified = 0;
  double worst = 0.0;
  for (int i = 0; i < 20000 && rests < 300; ++i)
  {
    Draw d = drawFlight(rng);
    // Velocities of the size of the separation speed (so that a body can come to rest within the flight) and a
    // load torque of the size of the motor's acceleration (the folded Coulomb friction).
    const double rho = d.params.gear_ratio;
    const double speed = std::fabs(d.start.load_velocity - rho * d.start.motor_velocity);
    const double separating = d.start.load_velocity - rho * d.start.motor_velocity;
    d.start.motor_velocity = 4.0 * (u(rng) - 0.5) * speed / rho;
    d.start.load_velocity = rho * d.start.motor_velocity + separating;
    const double motor_accel = std::fabs(d.law.torque(d.start.load_position)) / d.params.motor_inertia;
    d.params.load_torque = 4.0 * (u(rng) - 0.5) * rho * motor_accel * d.params.load_inertia;
    ShortFlight f;
    if (!f.build(d.params, d.law, d.start, 10.0))
    {
      continue;
    }
    const ReferenceSeries ref(d.params, d.law, d.start);
    for (bool motor : {false, true})
    {
      const double v0 = motor ? d.start.motor_velocity : d.start.load_velocity;
      const double sign = v0 > 0.0 ? 1.0 : -1.0;
      const double t = f.restTime(motor, sign, f.impactTime());
      if (std::isnan(t))
      {
        ++uncertified;
        continue;
      }
      // Reference: the first zero of sign·ω in (0, impact], scanned and bisected in long double.
      const long double h = f.impactTime();
      long double a = 0.0L, b = -1.0L;
      for (int k = 1; k <= 2000; ++k)
      {
        const long double tau = h * k / 2000.0L;
        if (sign * ref.velocity(motor, tau) <= 0.0L)
        {
          b = tau;
          break;
        }
        a = tau;
      }
      // Tolerance: the velocity's rounding over the deceleration, and a few ε of the time.
      const double decel =
          std::fabs(static_cast<double>(ref.velocity(motor, 0.0L) - ref.velocity(motor, h))) / static_cast<double>(h);
      const double tol = 64.0 * EPS * (std::fabs(v0) + decel * static_cast<double>(h)) / decel + 16.0 * EPS * h;
      if (std::isinf(t))
      {
        ++none;
        if (b > 0.0L)  // the reference stops: only within the tolerance of the flight's end (rounding)
        {
          EXPECT_LE(static_cast<double>(h - b), tol) << "case " << i << (motor ? " motor" : " load");
        }
        continue;
      }
      ++rests;
      ASSERT_GT(b, 0.0L) << "case " << i << ": the reference does not stop";
      for (int it = 0; it < 200; ++it)
      {
        const long double mid = 0.5L * (a + b);
        (sign * ref.velocity(motor, mid) > 0.0L ? a : b) = mid;
      }
      const double err = static_cast<double>(std::fabs(t - 0.5L * (a + b)));
      EXPECT_LE(err, tol) << "case " << i << (motor ? " motor" : " load");
      worst = std::max(worst, err / tol);
    }
  }
  EXPECT_GE(rests, 100);
  std::printf(
      "dry flights: %d rests within the flight, %d none, %d left to the closed form; worst rest time error "
      "%.3g of the tolerance\n",
      rests, none, uncertified, worst);
}

TEST(ShortFlight, DryChatterRunsAgreeWithTheClosedForm)
{
  // An elastic tooth rattling while both bodies slide with Coulomb friction (the fast path's dry branch) against
  // the closed form everywhere: the same maxima of θ_c, the energy balance closed.
  ServoParams p = test_helpers::chart(0.6, 0.04, 0.8, 0.9);
  p.load_coulomb_friction = p.load_static_friction = 0.002;
  p.motor_coulomb_friction = p.motor_static_friction = 0.001;
  std::vector<Event> with, without;
  const std::unique_ptr<Plant> fast = runChatter(p, true, 30.0, &with);
  const std::unique_ptr<Plant> slow = runChatter(p, false, 30.0, &without);
  EXPECT_GT(fast->shortFlightCount(), 100u);
  expectSameMaxima(with, without);
  EXPECT_LE(std::fabs(fast->energyBalanceError()), 1e-12 * fast->energy().input);
  std::printf("dry chatter: %llu impacts (%llu short flights) vs %llu with the closed form\n",
              static_cast<unsigned long long>(fast->impactCount()),
              static_cast<unsigned long long>(fast->shortFlightCount()),
              static_cast<unsigned long long>(slow->impactCount()));
}
