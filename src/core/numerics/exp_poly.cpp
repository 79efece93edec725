#include "backlash_servo/numerics/exp_poly.h"
#include "backlash_servo/model/constants.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace backlash_servo
{
namespace
{
/// Drops exactly-zero leading coefficients; returns false when the whole polynomial is zero.
template <class Term>
bool trimDegree(Term& t)
{
  while (t.degree > 0 && t.coef[t.degree] == 0.0)
  {
    --t.degree;
  }
  return !(t.degree == 0 && t.coef[0] == 0.0);
}

/// ∫_0^T τ^k e^{rτ} dτ by its power series; used where |rT| < 1 (no cancellation).
double seriesMomentIntegral(int k, double r, double upper)
{
  double term = upper;  // r^n T^{n+k+1} / n!
  for (int j = 0; j < k; ++j)
  {
    term *= upper;
  }
  double sum = 0.0;
  for (int n = 0; n < 60; ++n)
  {
    const double add = term / (n + k + 1);
    sum += add;
    if (std::fabs(add) <= 1e-18 * std::fabs(sum))
    {
      break;
    }
    term *= r * upper / (n + 1);
  }
  return sum;
}
}  // namespace

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::constant(double c)
{
  ExpPoly f;
  f.addTerm(0.0, &c, 0);
  return f;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::monomial(double c, int k, double rate)
{
  std::array<double, D + 1> coef{};
  coef[k] = c;
  ExpPoly f;
  f.addTerm(rate, coef.data(), k);
  return f;
}

template <int D>
void BasicExpPoly<D>::addTerm(double rate, const double* coef, int degree)
{
  if (degree > D)
  {
    throw std::logic_error("ExpPoly: polynomial degree limit exceeded");
  }
  for (int i = 0; i < n_; ++i)
  {
    if (terms_[i].rate == rate)
    {
      ExpTerm& t = terms_[i];
      for (int k = 0; k <= degree; ++k)
      {
        t.coef[k] += coef[k];
      }
      t.degree = std::max(t.degree, degree);
      if (!trimDegree(t))
      {
        terms_[i] = terms_[n_ - 1];
        --n_;
      }
      return;
    }
  }
  if (n_ == EXP_POLY_MAX_TERMS)
  {
    throw std::logic_error("ExpPoly: term limit exceeded");
  }
  ExpTerm& t = terms_[n_];
  t.rate = rate;
  t.degree = degree;
  std::copy(coef, coef + degree + 1, t.coef.begin());
  std::fill(t.coef.begin() + degree + 1, t.coef.end(), 0.0);  // invariant: coef[k] = 0 above the degree
  if (trimDegree(t))
  {
    ++n_;
  }
}

template <int D>
double BasicExpPoly<D>::operator()(double tau) const
{
  double sum = 0.0;
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    double p = t.coef[t.degree];
    for (int k = t.degree - 1; k >= 0; --k)
    {
      p = p * tau + t.coef[k];
    }
    sum += t.rate == 0.0 ? p : p * std::exp(t.rate * tau);
  }
  return sum;
}

template <int D>
double BasicExpPoly<D>::increment(double tau) const
{
  double sum = 0.0;
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    // q(τ) = (p(τ) − p(0))/τ by Horner on c_1 … c_d; p(τ) = c_0 + τ q(τ).
    double q = 0.0;
    for (int k = t.degree; k >= 1; --k)
    {
      q = q * tau + t.coef[k];
    }
    const double rise = q * tau;
    sum += t.rate == 0.0 ? rise : (t.coef[0] + rise) * std::expm1(t.rate * tau) + rise;
  }
  return sum;
}

template <int D>
double BasicExpPoly<D>::evaluate(double tau, double* rounding_bound) const
{
  double sum = 0.0;
  double magnitude = 0.0;
  const double at = std::fabs(tau);
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    double p = t.coef[t.degree];
    double pa = std::fabs(p);
    for (int k = t.degree - 1; k >= 0; --k)
    {
      p = p * tau + t.coef[k];
      pa = pa * at + std::fabs(t.coef[k]);
    }
    const double ex = t.rate == 0.0 ? 1.0 : std::exp(t.rate * tau);
    sum += p * ex;
    magnitude += pa * ex * (t.degree + 2);
  }
  if (rounding_bound != nullptr)
  {
    *rounding_bound = 16.0 * EPS * magnitude;
  }
  return sum;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::derivative() const
{
  ExpPoly d;
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    std::array<double, D + 1> c{};
    for (int k = 0; k <= t.degree; ++k)
    {
      c[k] = t.rate * t.coef[k] + (k < t.degree ? (k + 1) * t.coef[k + 1] : 0.0);
    }
    d.addTerm(t.rate, c.data(), t.degree);
  }
  return d;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::solveFirstOrder(double s) const
{
  ExpPoly y;
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    const double c = t.rate + s;
    std::array<double, D + 1> q{};
    int degree = t.degree;
    if (c == 0.0)
    {
      // Resonance: Q' = P, Q(0) = 0.
      ++degree;
      if (degree > D)
      {
        throw std::logic_error("ExpPoly: polynomial degree limit exceeded");
      }
      for (int k = 0; k <= t.degree; ++k)
      {
        q[k + 1] = t.coef[k] / (k + 1);
      }
    }
    else
    {
      // Q' + c Q = P solved from the top coefficient down.
      q[degree] = t.coef[degree] / c;
      for (int k = degree - 1; k >= 0; --k)
      {
        q[k] = (t.coef[k] - (k + 1) * q[k + 1]) / c;
      }
    }
    y.addTerm(t.rate, q.data(), degree);
  }
  return y;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::antiderivative() const
{
  return solveFirstOrder(0.0);
}

template <int D>
double BasicExpPoly<D>::integral(double upper) const
{
  double sum = 0.0;
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    const double rt = t.rate * upper;
    if (std::fabs(rt) < 1.0)
    {
      for (int k = 0; k <= t.degree; ++k)
      {
        if (t.coef[k] != 0.0)
        {
          sum += t.coef[k] * seriesMomentIntegral(k, t.rate, upper);
        }
      }
    }
    else
    {
      std::array<double, D + 1> q{};
      q[t.degree] = t.coef[t.degree] / t.rate;
      for (int k = t.degree - 1; k >= 0; --k)
      {
        q[k] = (t.coef[k] - (k + 1) * q[k + 1]) / t.rate;
      }
      double qt = q[t.degree];
      for (int k = t.degree - 1; k >= 0; --k)
      {
        qt = qt * upper + q[k];
      }
      sum += qt * std::exp(rt) - q[0];
    }
  }
  return sum;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly& BasicExpPoly<D>::operator+=(const ExpPoly& other)
{
  for (int i = 0; i < other.n_; ++i)
  {
    addTerm(other.terms_[i].rate, other.terms_[i].coef.data(), other.terms_[i].degree);
  }
  return *this;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::operator+(const ExpPoly& other) const
{
  ExpPoly r = *this;
  r += other;
  return r;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::operator*(double s) const
{
  ExpPoly r = *this;
  if (s == 0.0)
  {
    r.n_ = 0;
    return r;
  }
  for (int i = 0; i < r.n_; ++i)
  {
    for (int k = 0; k <= r.terms_[i].degree; ++k)
    {
      r.terms_[i].coef[k] *= s;
    }
  }
  return r;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::operator*(const ExpPoly& other) const
{
  ExpPoly r;
  for (int i = 0; i < n_; ++i)
  {
    for (int j = 0; j < other.n_; ++j)
    {
      const ExpTerm& a = terms_[i];
      const ExpTerm& b = other.terms_[j];
      const int degree = a.degree + b.degree;
      if (degree > D)
      {
        throw std::logic_error("ExpPoly: polynomial degree limit exceeded in product");
      }
      std::array<double, D + 1> c{};
      for (int k = 0; k <= a.degree; ++k)
      {
        for (int l = 0; l <= b.degree; ++l)
        {
          c[k + l] += a.coef[k] * b.coef[l];
        }
      }
      r.addTerm(a.rate + b.rate, c.data(), degree);
    }
  }
  return r;
}

template <int D>
int BasicExpPoly<D>::complexity() const
{
  int c = -1;
  for (int i = 0; i < n_; ++i)
  {
    c += terms_[i].degree + 1;
  }
  return c;
}

template <int D>
typename BasicExpPoly<D>::ExpPoly BasicExpPoly<D>::deflatedDerivative() const
{
  // (f e^{-r0 τ})' e^{r0 τ}... written with shifted rates: Σ (P_i' + (r_i − r0) P_i) e^{(r_i − r0) τ}.
  // The reference is the largest rate, so every shifted rate is <= 0 and nothing overflows on long horizons.
  ExpPoly d;
  int ref = 0;
  for (int i = 1; i < n_; ++i)
  {
    if (terms_[i].rate > terms_[ref].rate)
    {
      ref = i;
    }
  }
  const double r0 = terms_[ref].rate;
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    const double dr = i == ref ? 0.0 : t.rate - r0;
    std::array<double, D + 1> c{};
    for (int k = 0; k <= t.degree; ++k)
    {
      c[k] = dr * t.coef[k] + (k < t.degree ? (k + 1) * t.coef[k + 1] : 0.0);
    }
    d.addTerm(dr, c.data(), t.degree);
  }
  return d;
}

template <int D>
int BasicExpPoly<D>::signChangeRoots(double a, double b, double* out, double rel_tol) const
{
  for (int i = 0; i < n_; ++i)
  {
    for (int k = 0; k <= terms_[i].degree; ++k)
    {
      if (!std::isfinite(terms_[i].coef[k]) || !std::isfinite(terms_[i].rate))
      {
        // A NaN never deflates away: refuse instead of recursing for ever.
        throw std::domain_error(
            "backlash_servo: the motion overflowed (non-finite closed form); the parameters or the "
            "state lie outside the validated envelope (docs/validation.md)");
      }
    }
  }
  return isolateRoots(a, b, out, rel_tol);
}

template <int D>
int BasicExpPoly<D>::isolateRoots(double a, double b, double* out, double rel_tol) const
{
  if (n_ == 0 || complexity() <= 0 || !(b > a))
  {
    return 0;
  }
  // Closed forms for the two simplest shapes (the bottom of every recursion): c0 e^{r0 τ} + c1 e^{r1 τ} and a
  // linear polynomial times an exponential. Each has at most one root, a simple one.
  if (complexity() == 1)
  {
    double root = 0.0;
    if (n_ == 2)
    {
      const ExpTerm& t0 = terms_[0];
      const ExpTerm& t1 = terms_[1];
      const double ratio = -t0.coef[0] / t1.coef[0];
      if (!(ratio > 0.0))
      {
        return 0;
      }
      root = std::log(ratio) / (t1.rate - t0.rate);  // e^{(r1 − r0) τ} = −c0/c1
    }
    else
    {
      root = -terms_[0].coef[0] / terms_[0].coef[1];
    }
    if (!(root > a && root < b))
    {
      return 0;
    }
    out[0] = root;
    return 1;
  }
  double crit[EXP_POLY_MAX_ROOTS];
  const int m = deflatedDerivative().isolateRoots(a, b, crit, CRITICAL_POINT_TOLERANCE);
  int count = 0;
  double prev = a;
  double fprev = (*this)(a);
  // Sign of the last nonzero value, and an exact zero seen since then (if any).
  int last_sign = fprev > 0.0 ? 1 : (fprev < 0.0 ? -1 : 0);
  bool pending_zero = false;
  double zero_at = a;
  for (int i = 0; i <= m; ++i)
  {
    const double q = i < m ? crit[i] : b;
    const double fq = (*this)(q);
    const int s = fq > 0.0 ? 1 : (fq < 0.0 ? -1 : 0);
    if (s == 0)
    {
      if (last_sign != 0 && q < b)
      {
        pending_zero = true;
        zero_at = q;
      }
    }
    else
    {
      if (last_sign != 0 && s != last_sign && count < EXP_POLY_MAX_ROOTS)
      {
        out[count++] = pending_zero ? zero_at : refineBracket(0.0, prev, fprev, q, fq, rel_tol);
      }
      last_sign = s;
      pending_zero = false;
    }
    prev = q;
    fprev = fq;
  }
  return count;
}

template <int D>
void BasicExpPoly<D>::evaluateWithDerivative(double tau, double* value, double* slope, double* magnitude,
                                             double* curvature) const
{
  double f = 0.0, df = 0.0, ddf = 0.0, mag = 0.0;
  const double at = std::fabs(tau);
  for (int i = 0; i < n_; ++i)
  {
    const ExpTerm& t = terms_[i];
    double p = t.coef[t.degree];
    double pa = std::fabs(p);
    double dp = 0.0, ddp = 0.0;
    for (int k = t.degree - 1; k >= 0; --k)
    {
      ddp = ddp * tau + 2.0 * dp;
      dp = dp * tau + p;
      p = p * tau + t.coef[k];
      pa = pa * at + std::fabs(t.coef[k]);
    }
    const double ex = t.rate == 0.0 ? 1.0 : std::exp(t.rate * tau);
    f += p * ex;
    df += (dp + t.rate * p) * ex;
    ddf += (ddp + 2.0 * t.rate * dp + t.rate * t.rate * p) * ex;
    mag += pa * ex;
  }
  *value = f;
  *slope = df;
  if (magnitude != nullptr)
  {
    *magnitude = mag;
  }
  if (curvature != nullptr)
  {
    *curvature = ddf;
  }
}

template <int D>
double BasicExpPoly<D>::refineBracket(double level, double a, double fa, double b, double fb, double rel_tol) const
{
  const double tol = std::max(rel_tol, 2.0 * EPS);
  if (fa == 0.0)
  {
    return a;
  }
  if (fb == 0.0)
  {
    return b;
  }
  if ((fa < 0.0) == (fb < 0.0))
  {
    return std::fabs(fa) < std::fabs(fb) ? a : b;
  }
  // Halley (cubic convergence; f'' costs no extra exponentials) inside the shrinking bracket while its steps at
  // least halve; otherwise (a step would leave the bracket, or convergence is slow as at a flat start) bisection.
  // f is monotone on [a, b], so the bracket holds the only root. Stops when the bracket or the step reaches tol, or
  // f is at rounding level.
  double x = (a * fb - b * fa) / (fb - fa);
  if (!(x > a && x < b))
  {
    x = 0.5 * (a + b);
  }
  double last_step = 2.0 * (b - a);
  for (int it = 0; it < 200; ++it)
  {
    double f, df, magnitude, ddf;
    evaluateWithDerivative(x, &f, &df, &magnitude, &ddf);
    f -= level;
    if (std::fabs(f) <= 4.0 * EPS * (magnitude + std::fabs(level)))
    {
      return x;
    }
    if ((f < 0.0) == (fa < 0.0))
    {
      a = x;
      fa = f;
    }
    else
    {
      b = x;
      fb = f;
    }
    if (b - a <= tol * std::max(std::fabs(a), std::fabs(b)) || b - a <= std::numeric_limits<double>::min())
    {
      return x;
    }
    const double denominator = 2.0 * df * df - f * ddf;
    const double newton = denominator != 0.0 ? x - 2.0 * f * df / denominator : a - 1.0;
    const double step = std::fabs(newton - x);
    if (newton > a && newton < b && step <= 0.5 * last_step)
    {
      if (step <= tol * std::fabs(x))
      {
        return newton;
      }
      x = newton;
      last_step = step;
    }
    else
    {
      x = 0.5 * (a + b);
      last_step = 0.5 * (b - a);
    }
  }
  return x;
}

template class BasicExpPoly<EXP_POLY_MAX_DEGREE>;
template class BasicExpPoly<EXP_POLY_WIDE_DEGREE>;

}  // namespace backlash_servo
