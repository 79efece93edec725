// LinearMode's event search: the exact location of an output's zero crossings along the closed form (the maths is in
// linear_mode.h's file comment, "Zero crossings, rigorously").
#include <algorithm>
#include <cmath>
#include <limits>

#include "numerics/linear_mode.h"
#include "numerics/mode_products.h"

#include "backlash_servo/model/constants.h"

namespace backlash_servo
{
using mode_detail::affine;
using mode_detail::product;

double LinearMode::balancedNorm(const ModeVector& v) const
{
  // (Plain loops: Eigen's expressions carry a dispatch overhead that dominates at these orders.)
  double size = 0.0;
  for (Eigen::Index j = 0; j < v.size(); ++j)
  {
    const double d = v(j) * basis_->inv_bal_(j);
    size += d * d;
  }
  return std::sqrt(size);
}

double LinearMode::rateNoise(const ModeVector& w, const ModeVector& v) const
{
  return basis_->rounding_ * basis_->reach(w).weight * balancedNorm(v);
}

const LinearMode::Point& LinearMode::pointAt(double tau, bool begins) const
{
  for (const Point& kept : points_)
  {
    if (kept.tau == tau)
    {
      return kept;
    }
  }
  Point& p = points_[begins ? 0 : 1];
  p.tau = tau;
  p.x = state(tau);
  p.xd = affine(basis_->a_, p.x, u_);
  p.dev_norm = balancedNorm(p.x - x0_);
  p.xd_norm = balancedNorm(p.xd);
  p.second = false;
  if (basis_->modal_)
  {
    p.decay.setConstant(x0_.size() - basis_->nil_, std::numeric_limits<double>::quiet_NaN());
  }
  return p;
}

LinearMode::Curvature LinearMode::curvature(const ModeVector& w) const
{
  Curvature k;
  const ModeBasis::OutputReach& reach = basis_->reach(w);
  k.weight = reach.weight;
  if (basis_->modal_)
  {
    // s''(τ) = Σ_k (wᵀD v_k) λ_k g_k e^{λ_k τ}, s''' the same with λ_k² — the drift of a zero eigenvalue has neither.
    const Eigen::Index r = reach.size.size();
    k.beta.resize(r);
    k.rate.resize(r);
    for (Eigen::Index i = 0; i < r; ++i)
    {
      // |wᵀD v_i λ_i| |g_i| (a pair's: both terms in the first).
      k.rate(i) = basis_->lambda_(i).real();
      k.beta(i) = basis_->weight_(i) * g_abs_(i) * reach.size(i);
      k.steady = k.steady && (k.beta(i) == 0.0 || k.rate(i) <= 0.0);
    }
    // The polynomial part: s'' = Σ_{j ≥ 1} (Dw)·P_j (j + 1) j τ^{j−1}, s''' = Σ_{j ≥ 2} (Dw)·P_j (j + 1) j (j − 1)
    // τ^{j−2}.
    k.poly = ModeVector::Zero(poly_.cols());
    for (Eigen::Index j = 1; j < poly_.cols(); ++j)
    {
      k.poly(j) = std::fabs(w.cwiseProduct(basis_->bal_).dot(poly_.col(j))) * static_cast<double>((j + 1) * j);
      k.steady = k.steady && (j < 2 || k.poly(j) == 0.0);
    }
  }
  else
  {
    k.wa = (w.cwiseProduct(basis_->bal_).transpose() * basis_->balanced_).norm();
    k.steady = false;
  }
  return k;
}

void LinearMode::curvatureBounds(const Curvature& k, const Point& p, double lo, double h, double* m2, double* m3) const
{
  constexpr double SAFE = 1.0 + 64.0 * std::numeric_limits<double>::epsilon();
  if (basis_->modal_)
  {
    // Each mode's term is largest at one end of the window.
    double b2 = 0.0, b3 = 0.0;
    for (Eigen::Index i = 0; i < k.beta.size(); ++i)
    {
      if (k.beta(i) != 0.0)
      {
        // (A decaying mode's factor is the instant's; a growing one's grows over the window.)
        double& decay = p.decay(i);
        if (k.rate(i) <= 0.0 && std::isnan(decay))
        {
          const double growth = k.rate(i) * lo;
          decay = growth == 0.0 ? 1.0 : std::exp(growth);
        }
        const double term = k.rate(i) <= 0.0 ? k.beta(i) * decay : k.beta(i) * std::exp(k.rate(i) * lo + k.rate(i) * h);
        b2 += term;
        b3 += term * basis_->speed_(i);
      }
    }
    // The polynomial part's terms are largest at the window's end (τ ≥ 0).
    double p2 = 0.0, p3 = 0.0;
    for (Eigen::Index j = k.poly.size() - 1; j >= 1; --j)
    {
      p2 = p2 * (lo + h) + k.poly(j);
    }
    for (Eigen::Index j = k.poly.size() - 1; j >= 2; --j)
    {
      p3 = p3 * (lo + h) + k.poly(j) * static_cast<double>(j - 1);
    }
    *m2 = (b2 + p2) * SAFE;
    *m3 = (b3 + p3) * SAFE;
    return;
  }
  // ‖(Dw)ᵀÂ‖₂ ‖D⁻¹ẋ(lo)‖₂ e^{‖Â‖₂ h}.
  *m2 = k.wa * p.xd.cwiseQuotient(basis_->bal_).norm() * std::exp(basis_->norm_a_ * h);
  *m3 = INF;
}

LinearMode::Local LinearMode::local(const ModeVector& w, double w0, double lo, double h, const Curvature& curv,
                                    bool begins) const
{
  const Point& p = pointAt(lo, begins);
  Local l;
  l.lo = lo;
  l.weight = curv.weight;
  l.s = w.dot(p.x) + w0;
  l.s1 = w.dot(p.xd);
  // The closed form's rounding: the motion is solved as its deviation δ = x − x₀, so each balanced coordinate of δ
  // carries an error of about rounding·‖D⁻¹δ‖ (the output sums them with weights |w_i| D_i), and adding x₀ a few ulps
  // of each |x_i|. (Relative to the whole state instead, a joint spinning at 3e4 rad/s had a penetration "within
  // rounding" over its whole 2 mrad excursion, and the search passed two crossings as one grazing.) The rate's
  // likewise (see rateNoise()).
  l.noise0 = valueNoise(w, w0, p, curv.weight);
  l.noise1 = basis_->rounding_ * curv.weight * p.xd_norm;
  curvatureBounds(curv, p, lo, h, &l.m2, &l.m3);
  return l;
}

double LinearMode::valueNoise(const ModeVector& w, double w0, const Point& p, double weight) const
{
  double size = std::fabs(w0);
  for (Eigen::Index j = 0; j < p.x.size(); ++j)
  {
    size += std::fabs(w(j) * p.x(j));
  }
  return basis_->rounding_ * weight * p.dev_norm + 8.0 * EPS * size;
}

void LinearMode::completeSecond(const ModeVector& w, Local* local) const
{
  if (!local->second)
  {
    // (The picture the Local was taken from, taken again if another has taken its place since: the same numbers.)
    const Point& p = pointAt(local->lo);
    if (!p.second)
    {
      p.xdd = product(basis_->a_, p.xd);  // ẍ = A ẋ
      p.xdd_norm = balancedNorm(p.xdd);
      p.second = true;
    }
    local->s2 = w.dot(p.xdd);
    local->noise2 = basis_->rounding_ * local->weight * p.xdd_norm;
    local->second = true;
  }
}

LinearMode::Verdict LinearMode::judge(const ModeVector& w, Local* local, double h) const
{
  const Local& l = *local;
  // Degree 1: s(lo + t) = s + s' t + R, |R| ≤ ½ m2 t² — beyond the remainder and the rounding of s and of s' t
  // (the window may be as long as this test allows, so neither rounding may be left out).
  const double margin = 0.5 * l.m2 * h * h + l.noise0 + l.noise1 * h;
  const double end = l.s + l.s1 * h;
  if ((l.s > margin && end > margin) || (l.s < -margin && end < -margin))
  {
    return Verdict::Clear;  // the linear part keeps one sign beyond the remainder: no zero here
  }
  // Degree 2: s(lo + t) = s + s' t + ½ s'' t² + R, |R| ≤ m3 t³/6 — the quadratic's least value on the window (at an
  // end, or at its vertex) beyond the remainder and the rounding of its coefficients.
  const bool second = std::isfinite(l.m3);
  if (second)
  {
    completeSecond(w, local);  // (only where degree 1 did not settle it)
  }
  if (second && l.s != 0.0)
  {
    const double sign = l.s > 0.0 ? 1.0 : -1.0;
    double least = std::min(sign * l.s, sign * (l.s + l.s1 * h + 0.5 * l.s2 * h * h));
    if (sign * l.s2 > 0.0)
    {
      const double vertex = -l.s1 / l.s2;
      if (vertex > 0.0 && vertex < h)
      {
        least = std::min(least, sign * (l.s + 0.5 * l.s1 * vertex));
      }
    }
    if (least > l.m3 * h * h * h / 6.0 + l.noise0 + l.noise1 * h + 0.5 * l.noise2 * h * h)
    {
      return Verdict::Clear;
    }
  }
  // s' keeps its sign on the window: by degree 1 (|s'(τ) − s'(lo)| ≤ m2 h, s'(lo) beyond its own rounding) or 2
  // (s'(lo + t) = s' + s'' t + R', |R'| ≤ ½ m3 t²).
  if (std::fabs(l.s1) > l.m2 * h + l.noise1)
  {
    return Verdict::Monotone;
  }
  if (second && l.s1 != 0.0)
  {
    const double sign = l.s1 > 0.0 ? 1.0 : -1.0;
    const double least = std::min(sign * l.s1, sign * (l.s1 + l.s2 * h));
    if (least > 0.5 * l.m3 * h * h + l.noise1 + l.noise2 * h)
    {
      return Verdict::Monotone;
    }
  }
  return Verdict::Unknown;
}

double LinearMode::reach(const ModeVector& w, Local* local, double rest) const
{
  const Local& l = *local;
  // The longest h with a h² + b h < c (c > 0): the positive root 2c / (b + √(b² + 4ac)), +inf where none.
  const auto below = [](double c, double b, double a) {
    if (!(c > 0.0))
    {
      return 0.0;
    }
    const double den = b + std::sqrt(b * b + 4.0 * a * c);
    return den > 0.0 ? 2.0 * c / den : INF;
  };
  // Degree 1 (as judge): |s| beyond ½m2h² + noise0 + noise1·h at both ends; |s'| beyond m2·h + noise1.
  const double a = std::fabs(l.s), b = l.s >= 0.0 ? l.s1 : -l.s1;
  double best =
      std::max(std::min(below(a - l.noise0, l.noise1, 0.5 * l.m2), below(a - l.noise0, l.noise1 - b, 0.5 * l.m2)),
               below(std::fabs(l.s1) - l.noise1, l.m2, 0.0));
  if (best >= rest || !std::isfinite(l.m3))
  {
    return std::min(best, rest);
  }
  completeSecond(w, local);
  // Degree 2, monotone: s' + s''t keeps its sign beyond ½m3t² + noise1 + noise2·t at both ends.
  const double a1 = std::fabs(l.s1), b1 = l.s1 >= 0.0 ? l.s2 : -l.s2;
  if (l.s1 != 0.0)
  {
    best = std::max(
        best, std::min(below(a1 - l.noise1, l.noise2, 0.5 * l.m3), below(a1 - l.noise1, l.noise2 - b1, 0.5 * l.m3)));
  }
  // Degree 2, exclusion: the quadratic's least value on [0, h] beyond m3h³/6 + noise0 + noise1·h + ½noise2·h² —
  // falling with h against a rising bound, so it holds below one length, found by bisection (in ratio).
  if (l.s != 0.0 && best < rest)
  {
    const double c = l.s >= 0.0 ? l.s2 : -l.s2;
    const auto holds = [&](double h) {
      double least = std::min(a, a + b * h + 0.5 * c * h * h);
      if (c > 0.0 && -b / c > 0.0 && -b / c < h)
      {
        least = std::min(least, a + 0.5 * b * (-b / c));
      }
      return least > l.m3 * h * h * h / 6.0 + l.noise0 + l.noise1 * h + 0.5 * l.noise2 * h * h;
    };
    if (holds(rest))
    {
      return rest;
    }
    double ok = best, no = rest;
    if (holds(ok > 0.0 ? ok * 1.0625 : rest * 1e-3))
    {
      ok = ok > 0.0 ? ok * 1.0625 : rest * 1e-3;
      for (int k = 0; k < 8; ++k)
      {
        const double mid = std::sqrt(ok * no);
        (holds(mid) ? ok : no) = mid;
      }
      best = ok;
    }
  }
  return std::min(best, rest);
}

double LinearMode::firstCrossing(const ModeVector& w, double w0, int direction, double horizon, double from,
                                 bool began_here) const
{
  if (!(horizon > 0.0) || (direction != 1 && direction != 0 && direction != -1))
  {
    return INF;
  }
  // In the balanced basis x = D x̂: s = (Dw)·x̂ + w₀, s'' = (Dw)ᵀ Â exp(Ât) (D⁻¹ẋ).
  const Curvature curv = curvature(w);
  const double scale = basis_->norm_a_ > 0.0 ? 1.0 / basis_->norm_a_ : horizon;  // the fastest time scale [s]
  const double floor = FLOOR_FRACTION * scale;
  const Local start =
      local(w, w0, from, horizon - from, curv, true);  // (the first window's, where the bounds are steady)
  {
    // An output that is zero with all its derivatives at the start (wᵀAᵏẋ = 0, k < n: the output does not see the
    // motion at all, e.g. the velocity of a body at rest on which nothing acts) stays zero: it never crosses.
    bool flat = std::fabs(start.s) <= start.noise0;
    if (flat)
    {
      ModeVector v = pointAt(from).xd;
      for (int k = 0; flat && k < order(); ++k)
      {
        flat = std::fabs(w.dot(v)) <= rateNoise(w, v);
        v = product(basis_->a_, v);
      }
    }
    if (flat)
    {
      return INF;
    }
  }
  const double origin = began_here ? from : std::numeric_limits<double>::quiet_NaN();
  double t = from;
  while (t < horizon)
  {
    const double rest = horizon - t;
    if (basis_->modal_ && curv.steady && std::isfinite(rest))
    {
      // The bounds do not grow with the window: the longest window the tests settle at once (reach(), arithmetic
      // only) — but at least where the remainder bound reaches about |s|, a window the search will halve if need be.
      // (A hair short of a root: there the tests' rounding may go either way.)
      Local l = t == from ? start : local(w, w0, t, rest, curv);
      const double least = l.m2 > 0.0 ? std::max(std::sqrt(std::fabs(l.s) / l.m2), 1e-3 * scale) : rest;
      const double longest = rest > least ? reach(w, &l, rest) : rest;
      const double h = std::min(std::max(longest < rest ? longest * (1.0 - 0x1p-20) : rest, least), rest);
      const double hit = searchWindow(w, w0, direction, t, t + h, curv, floor, origin, &l);
      if (hit < INF)
      {
        return hit;
      }
      t += h;
      continue;
    }
    // A window the exclusion test is likely to pass: where the remainder bound reaches about |s|.
    const Point& p = pointAt(t);
    const double s = w.dot(p.x) + w0;
    double m = 0.0, m3 = 0.0;
    curvatureBounds(curv, p, t, scale, &m, &m3);
    double h = m > 0.0 ? std::sqrt(std::fabs(s) / m) : horizon;
    // (At least a thousandth of the fastest time scale: an output hovering near zero is searched by halving the
    // window, not by crawling. At most that time scale for the norm bound, which grows as e^{‖Â‖h}, and four of
    // them for a modal bound with a growing mode.)
    h = std::min({std::max(h, 1e-3 * scale), basis_->modal_ ? 4.0 * scale : scale, rest});
    const double hit = searchWindow(w, w0, direction, t, t + h, curv, floor, origin);
    if (hit < INF)
    {
      return hit;
    }
    t += h;
  }
  return INF;
}

double LinearMode::searchWindow(const ModeVector& w, double w0, int direction, double lo, double hi,
                                const Curvature& curv, double floor, double origin, Local* at_lo) const
{
  const double h = hi - lo;
  Local computed;
  Local& l = at_lo != nullptr ? *at_lo : (computed = local(w, w0, lo, h, curv));  // m2, m3 bound its s'', s'''
  const Verdict verdict = judge(w, &l, h);
  if (verdict == Verdict::Clear)
  {
    return INF;
  }
  const double s = l.s, s1 = l.s1, m = l.m2, rounding = l.noise0;
  const double s_hi = output(w, w0, hi);
  // Exclusion by the ends, without the rate: where |s''| <= m2 on the window, s lies above the chord between its ends
  // less m2 h^2/8 (linear interpolation's error), so ends of one sign beyond that and their rounding leave no zero.
  // (An output tiny beside the state's rate — a load's velocity decaying to nothing while the motor drifts — has a
  // rate whose rounding dwarfs it: the Taylor tests above could clear only windows as short as |s|/noise1.)
  if (s * s_hi > 0.0 &&
      std::min(std::fabs(s), std::fabs(s_hi)) > m * h * h / 8.0 + rounding + valueNoise(w, w0, pointAt(hi), l.weight))
  {
    return INF;
  }
  // (Either direction: the one the window's end tells — a crossing can only end on the side the output ends on.)
  const int dir = direction != 0 ? direction : s_hi > 0.0 ? 1 : -1;
  // The start of a motion begun by this output's own crossing, where the output is within rounding of zero and
  // moving in the asked direction: that crossing, evaluated again — its sign there means nothing. (Only there: any
  // other output found within rounding of zero at a start, moving across, is searched by its signs like anywhere.)
  const bool behind = lo == origin && std::fabs(s) <= rounding && dir * s1 > 0.0;
  const bool changes = !behind && dir * s <= 0.0 && dir * s_hi > 0.0;
  // Within rounding of zero at both ends and in its slope, on a window much shorter than any of the mode's
  // oscillations (or by the bound all along): the output's turning points there cannot be resolved, only a sign
  // change between the ends counts. (Where an output leaves zero to high order — a load set moving from rest — the
  // curvature bound, a sum over the modes, stays far above the output itself: without this the search would halve
  // down to the floor across the whole band.)
  const bool short_window = h * basis_->norm_a_ <= 1e-3;
  if (std::fabs(s) + std::fabs(s1) * h + 0.5 * m * h * h <= rounding ||
      (short_window && std::fabs(s) <= rounding && std::fabs(s_hi) <= rounding && std::fabs(s1) * h <= rounding))
  {
    return changes ? refine(w, w0, dir, lo, hi, l) : INF;
  }
  if (verdict == Verdict::Monotone)
  {
    return changes ? refine(w, w0, dir, lo, hi, l) : INF;  // one zero at most
  }
  if (h <= floor)
  {
    // Within the floor of a turning point: a sign change is the crossing; none is a grazing (see the file comment).
    return changes ? refine(w, w0, dir, lo, hi, l) : INF;
  }
  const double mid = lo + 0.5 * h;
  const double first = searchWindow(w, w0, direction, lo, mid, curv, floor, origin);
  return first < INF ? first : searchWindow(w, w0, direction, mid, hi, curv, floor, origin);
}

double LinearMode::refine(const ModeVector& w, double w0, int direction, double lo, double hi, const Local& at_lo) const
{
  // The ITP method (Oliveira & Takahashi, ACM TOMS 2020): regula falsi, truncated a little past the root so that the
  // bracket closes from both sides, projected to within a shrinking distance of the midpoint so that it never takes
  // more steps than bisection plus one — superlinear in practice. Run down to adjacent doubles, or until the end past
  // the crossing is within a few ulps of the output's terms (the doubles the state is held in cannot place s closer
  // to zero; bisecting that band to the last bit cost two thirds of all evaluations), and that end is returned. (Not
  // the closed form's whole rounding, Local::noise0: a bound for the exclusion test, loose where the motion is fast —
  // stopping there placed a fast joint's crossing 1e-9 s off.)
  const ModeVector x_hi = state(hi);
  double f_lo = direction * at_lo.s, f_hi = direction * (w.dot(x_hi) + w0);
  const double band =
      4.0 * std::numeric_limits<double>::epsilon() * (w.cwiseAbs().dot(x_hi.cwiseAbs()) + std::fabs(w0));
  // Newton's method on the bracket first (s' = w·(Ax + u) costs a product beside the evaluation): from the root of
  // the window's Taylor model at lo (s + s't + ½s''t² where s'' is known, else the line; the secant where neither
  // lies in the bracket), each step kept inside the bracket and aimed half a band past the crossing, so that it ends
  // within the band on that side. Quadratic near a simple crossing — a few evaluations where the bracketing method
  // took about fifteen; where it stalls (a crossing at a turning point, s' ≈ 0) the bracketing method below takes
  // over from the bracket reached.
  {
    double t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    const double rise = direction * at_lo.s1;
    if (rise > 0.0)
    {
      double step = -f_lo / rise;
      if (at_lo.second)
      {
        // The smaller root of ½ s'' t² + s' t + s = 0 in the cancellation-free form 2|s| / (s' + √(s'² − 2 s s'')).
        const double disc = rise * rise - 2.0 * f_lo * direction * at_lo.s2;
        if (disc >= 0.0)
        {
          step = -2.0 * f_lo / (rise + std::sqrt(disc));
        }
      }
      if (lo + step > lo && lo + step < hi)
      {
        t = lo + step;
      }
    }
    for (int j = 0; j < NEWTON_STEPS && f_hi > band; ++j)
    {
      if (!(t > lo && t < hi))
      {
        t = lo + 0.5 * (hi - lo);
        if (!(t > lo && t < hi))
        {
          break;
        }
      }
      const ModeVector x = state(t);
      const double f = direction * (w.dot(x) + w0);
      (f > 0.0 ? hi : lo) = t;
      (f > 0.0 ? f_hi : f_lo) = f;
      const double slope = direction * w.dot(affine(basis_->a_, x, u_));
      if (!(slope > 0.0))
      {
        break;  // not rising towards the crossing here: leave it to the bracketing method
      }
      t = t - (f - 0.5 * band) / slope;  // (aimed half a band past the crossing)
    }
  }
  if (!(f_hi > band))
  {
    return hi;  // (Newton's method ended within the band: the usual case)
  }
  const double eps = 0.5 * std::max(std::nextafter(hi, INF) - hi, std::numeric_limits<double>::denorm_min());
  const double kappa1 = 0.2 / (hi - lo);
  const int n_half = static_cast<int>(std::ceil(std::log2(std::max((hi - lo) / (2.0 * eps), 1.0))));
  const int n_max = n_half + 1;
  for (int j = 0; j < 400 && f_hi > band; ++j)
  {
    const double half = lo + 0.5 * (hi - lo);
    if (!(half > lo && half < hi))
    {
      break;
    }
    double x = half;
    if (f_hi > 0.0 && f_lo <= 0.0 && std::isfinite(f_hi - f_lo))
    {
      const double width = hi - lo;
      const double r = std::max(eps * std::ldexp(1.0, std::max(n_max - j, 0)) - 0.5 * width, 0.0);
      const double delta = kappa1 * width * width;
      const double falsi = (hi * f_lo - lo * f_hi) / (f_lo - f_hi);
      const double sigma = half >= falsi ? 1.0 : -1.0;
      const double truncated = delta <= std::fabs(half - falsi) ? falsi + sigma * delta : half;
      x = std::fabs(truncated - half) <= r ? truncated : half - sigma * r;
      if (!(x > lo && x < hi))
      {
        x = half;
      }
    }
    const double f = direction * output(w, w0, x);
    if (f > 0.0)
    {
      hi = x;
      f_hi = f;
    }
    else
    {
      lo = x;
      f_lo = f;
    }
  }
  return hi;
}
}  // namespace backlash_servo
