#include "backlash_servo/frequency/driven_backlash.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "backlash_servo/model/constants.h"
#include "frequency/driven_periods.h"

namespace backlash_servo
{
namespace
{
enum class Phase
{
  Free,
  Forward,   // on the flank g = 0: the tooth pushes the load in +
  Backward,  // on the flank g = Δ: the tooth pushes the load in −
};

/// The element's motion, event by event (file comment of driven_backlash.h).
class Element
{
 public:
  Element(const ServoParams& p, double amplitude, double omega)
      : a_(amplitude),
        w_(omega),
        delta_(p.backlash),
        j_(p.load_inertia),
        f_(p.load_friction),
        tc_(p.load_coulomb_friction),
        e_(p.restitution),
        period_(2.0 * PI / omega),
        rounding_(1e-13 * (p.backlash + amplitude))
  {
    c0_ = 0.5 * delta_;  // at rest in the middle of the free play
  }

  double x(double t) const { return a_ * std::sin(w_ * t); }
  double xd(double t) const { return a_ * w_ * std::cos(w_ * t); }

  /// Advances to t [s], through every event.
  void advanceTo(double t)
  {
    while (t0_ < t)
    {
      if (phase_ == Phase::Free)
      {
        advanceFree(t);
      }
      else
      {
        advanceContact(t);
      }
    }
  }

  Phase phase() const { return phase_; }
  double time() const { return t0_; }
  double position() const { return c0_; }  // (at time(): the phase is re-based at every stop)
  double velocity() const { return v0_; }
  long impacts() const { return impacts_; }

 private:
  /// The free load τ [s] after the phase's start.
  void freeAt(double tau, double* c, double* v) const
  {
    const double s = v0_ > 0.0 ? 1.0 : v0_ < 0.0 ? -1.0 : 0.0;
    if (s == 0.0)
    {
      *c = c0_;
      *v = 0.0;
      return;
    }
    if (f_ > 0.0)
    {
      const double lambda = f_ / j_, v_inf = -tc_ * s / f_;
      const double decay = -std::expm1(-lambda * tau);  // 1 − e^{−λτ}
      *v = v_inf + (v0_ - v_inf) * (1.0 - decay);
      *c = c0_ + v_inf * tau + (v0_ - v_inf) * decay / lambda;
    }
    else
    {
      const double acc = -tc_ * s / j_;
      *v = v0_ + acc * tau;
      *c = c0_ + v0_ * tau + 0.5 * acc * tau * tau;
    }
  }

  /// When the free load stops [s after the phase's start] (∞: it does not).
  double stopTime() const
  {
    if (v0_ == 0.0 || tc_ == 0.0)
    {
      return INFINITY;
    }
    const double s = v0_ > 0.0 ? 1.0 : -1.0;
    if (f_ > 0.0)
    {
      const double v_inf = -tc_ * s / f_;
      return std::log1p(-v0_ / v_inf) / (f_ / j_);
    }
    return v0_ / (tc_ * s / j_);
  }

  double gapAt(double tau) const
  {
    double c, v;
    freeAt(tau, &c, &v);
    return c - x(t0_ + tau);
  }

  /// The free load's acceleration τ [s] after the phase's start [rad/s²] (monotone in τ: its velocity is).
  double accelerationAt(double tau) const
  {
    double c, v;
    freeAt(tau, &c, &v);
    const double s = v0_ > 0.0 ? 1.0 : v0_ < 0.0 ? -1.0 : 0.0;
    return s == 0.0 ? 0.0 : -(f_ * v + tc_ * s) / j_;
  }

  /// The largest and smallest of sin ωt over [t_a, t_b].
  void sineRange(double ta, double tb, double* lo, double* hi) const
  {
    const double a = w_ * ta, b = w_ * tb;
    *lo = std::min(std::sin(a), std::sin(b));
    *hi = std::max(std::sin(a), std::sin(b));
    if (std::ceil((a - 0.5 * PI) / (2.0 * PI)) <= std::floor((b - 0.5 * PI) / (2.0 * PI)))
    {
      *hi = 1.0;  // a crest inside
    }
    if (std::ceil((a + 0.5 * PI) / (2.0 * PI)) <= std::floor((b + 0.5 * PI) / (2.0 * PI)))
    {
      *lo = -1.0;  // a trough inside
    }
  }

  /// q(τ) = q₀ + q₁τ + ½Lτ² > 0 on (0, h]? (q₀ ≤ 0 is a start on the flank: it must leave it.)
  static bool positive(double q0, double q1, double l, double h)
  {
    const auto q = [&](double t) { return q0 + q1 * t + 0.5 * l * t * t; };
    if (q(h) <= 0.0)
    {
      return false;
    }
    if (l > 0.0)
    {
      const double vertex = -q1 / l;
      if (vertex > 0.0 && vertex < h && q(vertex) <= 0.0)
      {
        return false;
      }
    }
    return q0 > 0.0 || q1 > 0.0 || (q1 == 0.0 && l > 0.0);
  }

  /// The gap stays strictly inside (0, Δ) on (τ_a, τ_b] (ga: the gap at τ_a), by a second-order Taylor bound: with
  /// L ≤ g̈ ≤ U on the window (the load's acceleration is monotone there, the tooth's from the sine's range),
  /// g ≥ g_a + ġ_a τ + ½Lτ² and Δ − g ≥ Δ − g_a − ġ_a τ − ½Uτ².
  bool clear(double ta, double tb, double ga) const
  {
    double c, v;
    freeAt(ta, &c, &v);
    const double rate = v - xd(t0_ + ta);
    const double acc_a = accelerationAt(ta), acc_b = accelerationAt(tb);
    double lo, hi;
    sineRange(t0_ + ta, t0_ + tb, &lo, &hi);
    const double tooth_lo = -a_ * w_ * w_ * hi, tooth_hi = -a_ * w_ * w_ * lo;  // ẍ = −Aω² sin ωt
    const double l = std::min(acc_a, acc_b) - tooth_hi, u = std::max(acc_a, acc_b) - tooth_lo, h = tb - ta;
    return positive(ga, rate, l, h) && positive(delta_ - ga, -rate, -u, h);
  }

  /// The first τ in (lo, hi] where the free load's gap leaves [0, Δ], or NaN; *forward: the flank it reaches.
  double firstHit(double lo, double hi, bool* forward) const
  {
    const double graze = 1e-12 * period_, window = period_ / 64.0;
    struct Span
    {
      double a, b;
    };
    std::vector<Span> stack;
    // Windows in time order: the stack holds the later ones underneath.
    for (double b = hi; b > lo;)
    {
      const double a = std::max(lo, b - window);
      stack.push_back({a, b});
      b = a;
    }
    while (!stack.empty())
    {
      const Span s = stack.back();
      stack.pop_back();
      const double ga = gapAt(s.a), gb = gapAt(s.b);
      if (gb < -rounding_ || gb > delta_ + rounding_)  // (a penetration within rounding is none)
      {
        *forward = gb < 0.0;
        return refine(s.a, s.b, *forward);
      }
      if (clear(s.a, s.b, ga))
      {
        continue;  // clear of both flanks throughout
      }
      const double h = s.b - s.a;
      if (h < graze)
      {
        continue;  // a graze within the tolerance
      }
      const double m = 0.5 * (s.a + s.b);
      stack.push_back({m, s.b});
      stack.push_back({s.a, m});
    }
    return NAN;
  }

  /// Bisection to the last bit: the gap inside at a, past the flank at b.
  double refine(double a, double b, bool forward) const
  {
    for (int i = 0; i < 200 && b - a > 0.0; ++i)
    {
      const double m = 0.5 * (a + b);
      if (m <= a || m >= b)
      {
        break;
      }
      const double g = gapAt(m);
      if (forward ? g < -rounding_ : g > delta_ + rounding_)
      {
        b = m;
      }
      else
      {
        a = m;
      }
    }
    return b;
  }

  void advanceFree(double t_end)
  {
    const double stop = stopTime(), horizon = std::min(t_end - t0_, stop);
    bool forward = false;
    const double hit = firstHit(0.0, horizon, &forward);
    if (std::isnan(hit))
    {
      double c, v;
      freeAt(horizon, &c, &v);
      t0_ = horizon == stop ? t0_ + stop : t_end;
      c0_ = c;
      v0_ = horizon == stop ? 0.0 : v;  // (stopped: at rest exactly)
      return;
    }
    double c, v;
    freeAt(hit, &c, &v);
    t0_ += hit;
    impact(forward, v);
  }

  /// The torque the load needs to move with the tooth at time t (sgn ẋ taken just after t) [N·m].
  double needed(double t) const
  {
    const double xd_now = xd(t), xdd = -a_ * w_ * w_ * std::sin(w_ * t);
    double s = xd_now > 0.0 ? 1.0 : xd_now < 0.0 ? -1.0 : 0.0;
    if (s == 0.0)
    {
      s = xdd > 0.0 ? 1.0 : -1.0;  // (the tooth turns: the sign it moves with next)
    }
    return j_ * xdd + f_ * xd_now + tc_ * s;
  }

  void impact(bool forward, double v)
  {
    ++impacts_;
    if (impacts_ > IMPACT_BUDGET)
    {
      throw InvalidParameterError("frequency",
                                  "the driven element chattered beyond " + std::to_string(IMPACT_BUDGET) + " impacts");
    }
    // A chatter: impacts in a row, each within 1e-9 of a period of the one before.
    chatter_ = t0_ - last_impact_ < 1e-9 * period_ ? chatter_ + 1 : 0;
    last_impact_ = t0_;
    const double wall = xd(t0_), offset = forward ? 0.0 : delta_;
    c0_ = x(t0_) + offset;
    const double after = wall - e_ * (v - wall);
    const double sign = forward ? 1.0 : -1.0;
    // The chatter ends on the flank once the bounce is slower than what an arrival found within the rounding
    // tolerance (a penetration ε under the relative acceleration |F|/J_L gives 2√(ε|F|/J_L)) or 1e-10 Aω.
    const double floor_speed = std::max(1e-10 * a_ * w_, 4.0 * std::sqrt(rounding_ * std::fabs(needed(t0_)) / j_));
    if (e_ == 0.0 || std::fabs(v - wall) <= floor_speed || chatter_ > 64)
    {
      if (sign * needed(t0_) >= 0.0)
      {
        phase_ = forward ? Phase::Forward : Phase::Backward;
        v0_ = wall;
        return;
      }
      v0_ = wall;  // the tooth leaves it at once
      phase_ = Phase::Free;
      return;
    }
    v0_ = after;
    phase_ = Phase::Free;
  }

  void advanceContact(double t_end)
  {
    const double sign = phase_ == Phase::Forward ? 1.0 : -1.0, offset = phase_ == Phase::Forward ? 0.0 : delta_;
    // Candidate instants where sign·F may turn negative: the tooth's reversals (cos ωt = 0: F jumps by 2T_cL) and the
    // zeros of F = R sin(ωt + φ) + T_cL sgn ẋ between them.
    std::vector<double> marks;
    const double theta0 = w_ * t0_, theta1 = w_ * t_end;
    for (double k = std::floor((theta0 - 0.5 * PI) / PI); k * PI + 0.5 * PI <= theta1; k += 1.0)
    {
      const double turn = (k * PI + 0.5 * PI) / w_;
      if (turn > t0_ && turn < t_end)
      {
        marks.push_back(turn);
      }
    }
    const double p = -j_ * a_ * w_ * w_, q = f_ * a_ * w_, r = std::hypot(p, q), phi = std::atan2(q, p);
    if (r > 0.0)
    {
      for (double level : {tc_, -tc_})  // R sin ψ = −T_cL sgn ẋ for either sign
      {
        if (std::fabs(level) > r)
        {
          continue;
        }
        const double base = std::asin(-level / r);
        for (double root : {base, PI - base})
        {
          for (double k = std::floor((theta0 + phi - root) / (2.0 * PI)); root + 2.0 * PI * k - phi <= theta1; k += 1.0)
          {
            const double t = (root + 2.0 * PI * k - phi) / w_;
            if (t > t0_ && t < t_end)
            {
              marks.push_back(t);
            }
          }
        }
      }
    }
    marks.push_back(t_end);
    std::sort(marks.begin(), marks.end());
    double start = t0_;
    for (double mark : marks)
    {
      if (sign * needed(0.5 * (start + mark)) < 0.0)
      {
        // The tooth stops pushing at `start`: the load leaves it with the tooth's velocity.
        t0_ = start;
        c0_ = x(start) + offset;
        v0_ = xd(start);
        phase_ = Phase::Free;
        return;
      }
      start = mark;
    }
    t0_ = t_end;
    c0_ = x(t_end) + offset;
    v0_ = xd(t_end);
  }

  double a_, w_, delta_, j_, f_, tc_, e_, period_;
  double rounding_;                        // [rad]: a gap beyond a flank by less is rounding, not an impact
  double t0_ = 0.0, c0_ = 0.0, v0_ = 0.0;  // the phase's start (re-based at every event and advance)
  Phase phase_ = Phase::Free;
  long impacts_ = 0;
  long chatter_ = 0;
  double last_impact_ = -INFINITY;
  static constexpr long IMPACT_BUDGET = 100000;
};

}  // namespace

void requireDrivableBacklash(const ServoParams& params)
{
  // (The element's own values only: a massless-looking load is a limit worth driving, outside the joint's envelope.)
  requireThat(std::isfinite(params.load_inertia) && params.load_inertia > 0.0, "load_inertia", "must be > 0 kg·m²");
  requireThat(std::isfinite(params.load_friction) && params.load_friction >= 0.0, "load_friction",
              "must be >= 0 N·m·s/rad");
  requireThat(std::isfinite(params.load_coulomb_friction) && params.load_coulomb_friction >= 0.0,
              "load_coulomb_friction", "must be >= 0 N·m");
  requireThat(params.restitution >= 0.0 && params.restitution <= 1.0, "restitution", "must be in [0, 1]");
  requireThat(params.backlash > 0.0, "backlash", "must be > 0 rad: the element is the free play");
  requireThat(params.load_torque == 0.0, "load_torque",
              "must be 0: with a load torque the element's cycle is not symmetric about its centre");
}

DrivenBacklash drivenBacklash(const ServoParams& params, double amplitude, double omega, double tolerance,
                              int max_periods)
{
  requireDrivableBacklash(params);
  requireThat(std::isfinite(amplitude) && amplitude > 0.0, "amplitude", "must be > 0 rad");
  requireThat(std::isfinite(omega) && omega > 0.0, "frequency", "must be > 0 rad/s");
  requireThat(max_periods >= 1 && tolerance > 0.0, "tolerance", "must be > 0, with at least one period");
  const double period = 2.0 * PI / omega;
  Element element(params, amplitude, omega);
  DrivenBacklash out;
  double last_gap = NAN, last_speed = NAN;
  Phase last_phase = Phase::Free;
  out.periods = settlePeriods(
      element, period, max_periods,
      [&](double t) {
        const double gap = element.position() - element.x(t), speed = element.velocity();
        if (std::fabs(gap - last_gap) <= tolerance * params.backlash &&
            std::fabs(speed - last_speed) <= tolerance * amplitude * omega && element.phase() == last_phase)
        {
          return true;
        }
        last_gap = gap;
        last_speed = speed;
        last_phase = element.phase();
        return false;
      },
      &out.periodic);
  // The next period (or, not periodic, the mean over the next DRIVEN_ANALYSED periods), sampled: the fundamentals of
  // θ_c and sgn θ̇_c.
  const double start = out.periods * period;
  const long impacts_before = element.impacts();
  std::complex<double> position(0.0, 0.0), sign(0.0, 0.0);
  const int analysed = samplePeriods(element, period, out.periods, out.periodic, [&](std::complex<double> rotor) {
    const double v = element.velocity();
    position += element.position() * rotor;
    sign += (v > 0.0 ? 1.0 : v < 0.0 ? -1.0 : 0.0) * rotor;
  });
  element.advanceTo(start + analysed * period);
  out.impacts = static_cast<int>((element.impacts() - impacts_before) / analysed);
  const std::complex<double> j(0.0, 1.0);
  // y₁ = (2/T)∫ y e^{−jωt} dt, N = j y₁ / A (y = A sin ωt → N = 1).
  const double scale = 2.0 / (static_cast<double>(DRIVEN_SAMPLES) * analysed);
  out.position = j * scale * position / amplitude;
  const std::complex<double> sign_df = j * scale * sign / amplitude;
  out.torque = std::complex<double>(-omega * omega * params.load_inertia, omega * params.load_friction) * out.position +
               params.load_coulomb_friction * sign_df;
  return out;
}

}  // namespace backlash_servo
