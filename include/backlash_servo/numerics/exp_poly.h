/**
 * @file exp_poly.h
 * @brief Real exponential polynomials f(τ) = Σ_i P_i(τ) e^{r_i τ} and exact root isolation for them.
 *
 * Every mode of the servo with real characteristic exponents has a closed-form solution of this form, so its
 * positions, velocities, gap and mesh torque are ExpPolys in the local time τ [s] of the mode. Roots are isolated
 * exactly by the Pólya–Szegő argument: between two sign changes of f lies a sign change of
 * \f$ \frac{d}{d\tau}(f e^{-r_0 \tau}) \f$, which has one term (or one polynomial degree) fewer; recursing down to a
 * single constant term gives all critical points, and between critical points f is monotone (up to a positive factor),
 * so no root — grazing or not — can be missed. No ROS dependency, no allocation.
 */
#pragma once

#include <array>

namespace backlash_servo
{
/// Highest polynomial degree a term can hold: ω_m² of a frictionless apart mode (θ_m cubic, ω_m quadratic) needs 4.
constexpr int EXP_POLY_MAX_DEGREE = 4;
/// Most distinct exponential rates an ExpPoly can hold: products of two modes have {0, −α, −β} pairwise, 6.
constexpr int EXP_POLY_MAX_TERMS = 6;
/// Highest polynomial degree of the wide form used where slow exponentials are written as their Taylor polynomials
/// (light damping, see modes.h): the gap is of degree ≤ 16 there, and the energy integrals multiply two of them.
constexpr int EXP_POLY_WIDE_DEGREE = 34;
/// Most sign-change roots reported by one call to signChangeRoots().
constexpr int EXP_POLY_MAX_ROOTS = 64;
/// Relative precision of critical points (see refineBracket).
constexpr double CRITICAL_POINT_TOLERANCE = 1e-10;

/// One term P(τ) e^{rate τ}; coef[k] multiplies τ^k.
template <int MaxDegree>
struct BasicExpTerm
{
  double rate = 0.0;  ///< exponential rate r [1/s]
  int degree = 0;     ///< degree of the polynomial P
  std::array<double, MaxDegree + 1> coef{};
};

/// Σ_i P_i(τ) e^{r_i τ} with deg P_i ≤ MaxDegree (ExpPoly: the compact form of every ordinary mode; WideExpPoly:
/// the form with slow exponentials expanded, used at light damping).
template <int MaxDegree>
class BasicExpPoly
{
 public:
  using ExpTerm = BasicExpTerm<MaxDegree>;
  using ExpPoly = BasicExpPoly<MaxDegree>;
  static constexpr int MAX_DEGREE = MaxDegree;

  BasicExpPoly() = default;
  /// A constant function c.
  static ExpPoly constant(double c);
  /// The single term c τ^k e^{rate τ}.
  static ExpPoly monomial(double c, int k, double rate);

  /// Adds coef[0..degree] τ^k e^{rate τ}; terms with exactly equal rates are merged.
  void addTerm(double rate, const double* coef, int degree);
  int termCount() const { return n_; }
  const ExpTerm& term(int i) const { return terms_[i]; }

  /// f(τ).
  double operator()(double tau) const;
  /// f(τ) and f'(τ) in one pass (shared exponentials); optionally Σ|c_k τ^k e^{rτ}| (the rounding scale) and f''.
  void evaluateWithDerivative(double tau, double* value, double* slope, double* magnitude = nullptr,
                              double* curvature = nullptr) const;
  /// f(τ) and a bound on its rounding error (a multiple of ε Σ|c_k τ^k e^{rτ}|).
  double evaluate(double tau, double* rounding_bound) const;

  ExpPoly derivative() const;
  /// Some antiderivative A (A' = f); use A(τ) − A(0) for definite integrals.
  ExpPoly antiderivative() const;
  /// ∫_0^T f(τ) dτ, accurate also when |r T| is small.
  double integral(double upper) const;
  /// f(τ) − f(0), each term as p(τ)·expm1(rτ) + (p(τ) − p(0)): large coefficients that cancel against their own
  /// exponential (a body's position c − c e^{−ατ} with c ≫ the displacement) do not cancel in floating point, so the
  /// increment is exact to the rounding of its own size, not of the coefficients'.
  double increment(double tau) const;

  ExpPoly& operator+=(const ExpPoly& other);
  /// Adds the constant c (to the rate-0 term).
  void addConstant(double c) { addTerm(0.0, &c, 0); }
  ExpPoly operator+(const ExpPoly& other) const;
  ExpPoly operator*(const ExpPoly& other) const;
  ExpPoly operator*(double s) const;

  /**
   * Particular solution y of \f$ y' + s\,y = f \f$ built term by term as Q(τ) e^{rτ} with
   * \f$ Q' + (r + s) Q = P \f$ (degree raised by one where r + s = 0, i.e. resonance).
   */
  ExpPoly solveFirstOrder(double s) const;

  /**
   * All points of (a, b) where f changes sign, ascending, written to out (at most EXP_POLY_MAX_ROOTS).
   * Returns the count. Roots of even multiplicity (touching zero) are not sign changes and are not reported.
   */
  int signChangeRoots(double a, double b, double* out, double rel_tol = 0.0) const;

  /**
   * Root of f − level in [a, b], given fa = f(a) − level and fb = f(b) − level of opposite signs (or a zero) and
   * f monotone on [a, b], to rel_tol relative (0 = full double precision). Critical points only bound monotone pieces —
   * an error δ in one changes the extremum value by O(δ²) — so they are refined to CRITICAL_POINT_TOLERANCE only.
   */
  double refineBracket(double level, double a, double fa, double b, double fb, double rel_tol = 0.0) const;

 private:
  /// signChangeRoots() without the finiteness check (done once at the top of the recursion).
  int isolateRoots(double a, double b, double* out, double rel_tol) const;
  /// d/dτ (f e^{−r_0 τ}) e^{...}: the sign-equivalent derivative with one term or one degree fewer.
  ExpPoly deflatedDerivative() const;
  int complexity() const;

  std::array<ExpTerm, EXP_POLY_MAX_TERMS> terms_{};
  int n_ = 0;
};

using ExpTerm = BasicExpTerm<EXP_POLY_MAX_DEGREE>;
using ExpPoly = BasicExpPoly<EXP_POLY_MAX_DEGREE>;
using WideExpPoly = BasicExpPoly<EXP_POLY_WIDE_DEGREE>;
extern template class BasicExpPoly<EXP_POLY_MAX_DEGREE>;
extern template class BasicExpPoly<EXP_POLY_WIDE_DEGREE>;

}  // namespace backlash_servo
